//! `tomograf.make_item`: one data-set item, made by the same code as `tomograf dataset`
//! (`tomograf_scene::dataset::make_item`), so the same source and settings give the same
//! bytes from Python and from the command line.

use crate::errors;
use pyo3::exceptions::PyFileNotFoundError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use tomograf_datasets::anatomy::Profile;
use tomograf_datasets::preprocess::HuWindow;
use tomograf_scene::Scene;
use tomograf_scene::dataset::{ItemSettings, ItemSource, make_item as make};

/// Makes one training or test item of the TomoGRAF protocol in the folder ``output``
/// (created if missing): ``ct.nii.gz`` (the black-border-cropped CT resampled to
/// ``size``³ and mapped to [0, 1] over ``hu_window``), ``projections.npy`` (float32
/// ``(views + 2, size, size)``: every 360/``views`` degrees, then AP and lateral, rendered
/// with exact Siddon), ``views.json`` (the geometry of each view) and ``item.json``
/// (written last: the item is finished). The same files as item ``index`` of
/// ``tomograf dataset``.
///
/// The source is either ``ct`` (a NIfTI or NRRD file or a DICOM series folder, in HU) or
/// ``phantom_seed`` (a seeded anatomical phantom of ``profile`` ``"lidc"`` or
/// ``"full-chest"``, optionally on a ``table`` and with a ``pacemaker``).
///
/// Without ``physics`` the projections are line integrals of μ at ``energy_kev`` (keV);
/// ``physics`` is a dict of a scene's physics tables (docs/scene.md), e.g.
/// ``{"acquisition": {"preset": "kv-flat-panel-120kvp", "seed": 5}}``, for the detector's
/// signal with noise seeded from the seed and ``index``. Distances in mm, HU for the
/// window and ``crop_hu``. A CT is brought into the patient frame (LPS: ``i`` left, ``j``
/// posterior, ``k`` superior) and everything but its body — couch, padding, stray voxels —
/// is set to air before the crop, unless ``keep_table``. ``heterogeneity_hu`` gives a
/// phantom's soft tissue a correlated texture of that standard deviation (HU), as
/// ``tomograf dataset --heterogeneity``; ``organ_spread`` widens the ranges its heart and
/// diaphragm are drawn from, as ``tomograf dataset --organ-spread``; ``deform_mm`` warps it
/// by a smooth random displacement field, as ``tomograf dataset --deform``.
/// ``augment_seed`` and ``scan_range_seed`` draw the item's shape augmentation and scan
/// range from that seed and ``index``, as ``tomograf dataset --augment`` and
/// ``--scan-range`` (docs/datasets.md). Returns the item folder.
#[pyfunction]
#[pyo3(signature = (output, *, ct=None, phantom_seed=None, profile="lidc", table=false,
    pacemaker=false, index=0, views=72, size=128, hu_window=(-1024.0, 2048.0),
    crop_hu=-900.0, energy_kev=60.0, sad_mm=1000.0, sid_mm=1500.0, split="train",
    physics=None, keep_table=false, heterogeneity_hu=0.0,
    organ_spread=1.0, deform_mm=0.0, augment_seed=None, scan_range_seed=None))]
#[allow(clippy::too_many_arguments)]
pub fn make_item(
    py: Python<'_>,
    output: PathBuf,
    ct: Option<PathBuf>,
    phantom_seed: Option<u64>,
    profile: &str,
    table: bool,
    pacemaker: bool,
    index: usize,
    views: usize,
    size: usize,
    hu_window: (f32, f32),
    crop_hu: f32,
    energy_kev: f64,
    sad_mm: f64,
    sid_mm: f64,
    split: &str,
    physics: Option<&Bound<'_, PyDict>>,
    keep_table: bool,
    heterogeneity_hu: f64,
    organ_spread: f64,
    deform_mm: f64,
    augment_seed: Option<u64>,
    scan_range_seed: Option<u64>,
) -> PyResult<PathBuf> {
    let source = match (ct, phantom_seed) {
        (Some(path), None) => {
            if !path.exists() {
                return Err(PyFileNotFoundError::new_err(format!(
                    "CT {} does not exist",
                    path.display()
                )));
            }
            ItemSource::File { path }
        }
        (None, Some(seed)) => {
            let profile = Profile::parse(profile).map_err(errors::dataset)?;
            ItemSource::phantom(seed, profile, table, pacemaker)
                .with_heterogeneity(heterogeneity_hu)
                .with_organ_spread(organ_spread)
                .with_deformation(deform_mm)
        }
        _ => {
            return Err(errors::value(
                "give exactly one source: ct=PATH or phantom_seed=N",
            ));
        }
    };
    let acquisition = match physics {
        None => None,
        Some(d) => {
            let json: String = py.import("json")?.call_method1("dumps", (d,))?.extract()?;
            let scene: Scene = serde_json::from_str(&json).map_err(|e| {
                errors::value(format!("physics is not a valid set of scene tables: {e}"))
            })?;
            tomograf_scene::physics::acquisition(&scene)
                .map_err(|e| errors::value(format!("{e:#}")))?
        }
    };
    let settings = ItemSettings {
        window: HuWindow::new(hu_window.0, hu_window.1).map_err(errors::dataset)?,
        crop_hu,
        energy_kev,
        views,
        size,
        sad_mm,
        sid_mm,
        split: split.into(),
        acquisition,
        keep_table,
        augment: augment_seed
            .map(|seed| (tomograf_datasets::augment::AugmentRanges::default(), seed)),
        scan_range: scan_range_seed,
        ..ItemSettings::default()
    };
    let dir = output.clone();
    py.detach(move || make(&settings, index, &source, &dir))
        .map_err(|e| errors::value(format!("{e:#}")))?;
    Ok(output)
}
