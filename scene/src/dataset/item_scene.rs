//! One item: its CT loaded or generated, brought into the patient frame, reduced to the
//! body, augmented and cropped ([`ItemScene`]), then rendered from its views and written
//! ([`make_item`]).

use super::{ItemSettings, ItemSource, sha256_of};
use crate::job::resolve;
use crate::physics::item_seed;
use crate::prepare::{Prepared, prepare_in_memory};
use crate::scene::Scene;
use crate::volume::load_volume_file;
use anyhow::{Context, Result};
use sha2::{Digest, Sha256};
use std::path::Path;
use tomograf_datasets::anatomy;
use tomograf_datasets::augment::Augmentation;
use tomograf_datasets::body::{self, BodySettings};
use tomograf_datasets::frame::{PATIENT_FRAME, to_patient_frame};
use tomograf_datasets::item::{self, AcquisitionRecord, ItemRecord};
use tomograf_datasets::preprocess::{crop_black_border, resample};
use tomograf_datasets::scan_range::ScanRange;
use tomograf_datasets::{image, nifti};
use tomograf_physics::acquisition::Acquisition;
use tomograf_sim::geometry::angles;
use tomograf_sim::{Geometry, Pose, View};

/// What an item is projected from: its CT, cropped, in the patient frame (HU, mm), and the
/// views it is seen from. [`make_item`] renders and writes it; the studies' data-effect
/// table (`tomograf_eval`) renders the same views with other physics.
pub struct ItemScene {
    /// The black-border-cropped CT at full resolution, HU.
    pub hu: tomograf_sim::Volume,
    /// The item as a scene (cone beam, `size²` detector, its poses, exact Siddon) without
    /// its volume and physics, which [`ItemScene::prepare`] gives: every item image is
    /// rendered by [`prepare_in_memory`].
    pub scene: Scene,
    /// The cone beam and the `size²` detector fitted to the volume.
    pub geometry: Geometry,
    /// The poses: every 360/`views` degrees, then AP, then lateral.
    pub poses: Vec<Pose>,
    /// The views of `poses`, in their order.
    pub views: Vec<View>,
    /// The item's estimated peak memory, bytes ([`crate::peak::item_peak_bytes`]), checked
    /// against the memory available once the CT was read.
    pub peak_bytes: u128,
    sha: String,
    reorientation: serde_json::Value,
    outside_body: String,
    augmentation: Option<Augmentation>,
    scan_range: Option<ScanRange>,
}

impl ItemScene {
    /// Item `index` of a set from `source`: loaded or generated, into the patient frame,
    /// reduced to the body, augmented and cropped as `settings` say; its views fitted.
    pub fn new(settings: &ItemSettings, index: usize, source: &ItemSource) -> Result<Self> {
        // The last item's buffers given back first (a data set's items, the study's effects
        // are made one after another): their peaks do not add up.
        tomograf_sim::memory::release_freed();
        settings.validate()?;
        // The CT in HU, and what identifies it.
        let (hu, sha) = match source {
            ItemSource::File { path } => (load_volume_file(path, false)?, sha256_of(path)?),
            ItemSource::Phantom { spec } => {
                let sha = format!(
                    "{:x}",
                    Sha256::digest(serde_json::to_string(spec)?.as_bytes())
                );
                (anatomy::generate(spec)?, sha)
            }
        };
        let from_file = matches!(source, ItemSource::File { .. });
        let prepare_peak = crate::peak::item_prepare_peak_bytes(from_file, hu.len() as u128);
        let phase = if from_file {
            "bringing into the patient frame and finding the body of"
        } else {
            "cropping"
        };
        crate::peak::check_item(index, hu.dims(), phase, prepare_peak)?;
        let (hu, reorientation, outside_body) = match source {
            ItemSource::File { path } => patient_of(hu, path, settings)?,
            // Generated in the frame, holding what its spec asks for (a table only if asked).
            ItemSource::Phantom { .. } => (hu, serde_json::Value::Null, String::new()),
        };
        let augmentation = settings
            .augment
            .as_ref()
            .map(|(ranges, seed)| Augmentation::draw(item_seed(*seed, index), ranges));
        let hu = match &augmentation {
            Some(a) => a.apply(&hu)?,
            None => hu,
        };
        let scan_range = settings
            .scan_range
            .map(|seed| ScanRange::draw(item_seed(seed, index)));
        let hu = match &scan_range {
            Some(r) => r.apply(&hu, settings.crop_hu)?,
            None => hu,
        };
        let hu = crop_black_border(&hu, settings.crop_hu)?;
        let size = settings.size as u128;
        let render_peak = crate::peak::item_render_peak_bytes(
            settings.acquisition.is_some(),
            hu.len() as u128,
            (settings.views as u128 + 2) * size * size,
            size * size * size,
        );
        crate::peak::check_item(index, hu.dims(), "rendering and writing", render_peak)?;
        let peak_bytes = crate::peak::item_peak_bytes(prepare_peak, render_peak);
        let mut poses = angles::arc(0.0, 360.0 / settings.views as f64, settings.views, 0.0)?;
        poses.extend([Pose::AP, Pose::LATERAL]);
        let scene = item_scene(settings, &poses);
        let job = resolve(&scene, &hu)?;
        let geometry = job.geometry.context("an item's views come from poses")?;
        let (poses, views) = (job.poses, job.views);
        Ok(Self {
            hu,
            scene,
            geometry,
            poses,
            views,
            peak_bytes,
            sha,
            reorientation,
            outside_body,
            augmentation,
            scan_range,
        })
    }

    /// The item's scene made ready to render from `hu` (this item's CT or a copy of it):
    /// the ideal DRR at `energy_kev`, or `acquisition` with its noise seed. For real
    /// physics the prepared volume is `hu` itself, handed back in [`Prepared::volume`].
    pub fn prepare(
        &self,
        hu: tomograf_sim::Volume,
        energy_kev: f64,
        acquisition: Option<(Acquisition, u64)>,
    ) -> Result<Prepared> {
        prepare_item(&self.scene, hu, energy_kev, acquisition)
    }

    /// The ideal DRR of the views numbered `which` (of [`ItemScene::views`]): line
    /// integrals of μ at `energy_kev`, exact Siddon, as the item's own are rendered.
    pub fn ideal_drr(
        &self,
        energy_kev: f64,
        which: std::ops::Range<usize>,
    ) -> Result<Vec<Vec<f32>>> {
        let prepared = self.prepare(self.hu.clone(), energy_kev, None)?;
        let renderer = prepared.renderer()?;
        which
            .map(|i| first_channel(renderer.render(i, &prepared.job.views[i])?))
            .collect()
    }
}

/// The scene of an item seen from `poses`: the settings' cone beam, a `size²` detector
/// whose pitch is fitted to the volume, the volume's centre as isocentre, exact Siddon,
/// line integrals. Its volume and physics are given in memory ([`ItemScene::prepare`]).
fn item_scene(settings: &ItemSettings, poses: &[Pose]) -> Scene {
    let mut scene = Scene::default();
    scene.geometry.beam = Some("cone".into());
    scene.geometry.sad_mm = Some(settings.sad_mm);
    scene.geometry.sid_mm = Some(settings.sid_mm);
    scene.detector.rows = Some(settings.size);
    scene.detector.cols = Some(settings.size);
    // `{}` writes the shortest text that reads back as the same f64.
    scene.views.poses = Some(
        poses
            .iter()
            .map(|p| format!("{},{}", p.theta_deg, p.phi_deg))
            .collect(),
    );
    scene.projector.kind = Some("siddon".into());
    scene
}

/// [`ItemScene::prepare`] of the item scene `scene`.
fn prepare_item(
    scene: &Scene,
    hu: tomograf_sim::Volume,
    energy_kev: f64,
    acquisition: Option<(Acquisition, u64)>,
) -> Result<Prepared> {
    let mut scene = scene.clone();
    scene.volume.energy_kev = acquisition.is_none().then_some(energy_kev);
    prepare_in_memory(&scene, hu, acquisition)
}

/// The image of a rendered view: its first (for the ideal DRR, only) channel.
fn first_channel(frame: crate::prepare::Frame) -> Result<Vec<f32>> {
    Ok(frame
        .images
        .into_iter()
        .next()
        .context("a rendered view without an image")?
        .data)
}

/// Makes item `index` of a set from `source` into `dir` (created if missing); returns its
/// estimated peak memory, bytes.
pub fn make_item(
    settings: &ItemSettings,
    index: usize,
    source: &ItemSource,
    dir: &Path,
) -> Result<u128> {
    let item = ItemScene::new(settings, index, source)?;
    let size = settings.size;

    // Projections from the cropped full-resolution volume, through the item's scene: the
    // ideal DRR renders μ made from a copy of the CT; real physics takes the CT itself and
    // hands it back.
    let acquisition = settings
        .acquisition
        .as_ref()
        .map(|(a, s)| (a.clone(), item_seed(*s, index)));
    let quantity = match &settings.acquisition {
        None => "line integral ∫mu ds (mu at the effective energy)".to_string(),
        Some((acq, _)) => format!("detector signal: {:?} (see acquisition)", acq.output),
    };
    let ItemScene {
        hu,
        scene,
        geometry,
        poses,
        views,
        peak_bytes,
        sha,
        reorientation,
        outside_body,
        augmentation,
        scan_range,
    } = item;
    let (hu, kept) = match acquisition {
        None => (hu.clone(), Some(hu)),
        Some(_) => (hu, None),
    };
    let prepared = prepare_item(&scene, hu, settings.energy_kev, acquisition)?;
    let mut stack = Vec::with_capacity(views.len() * size * size);
    {
        let renderer = prepared.renderer()?;
        for (i, v) in prepared.job.views.iter().enumerate() {
            stack.extend(first_channel(renderer.render(i, v)?)?);
        }
    }
    let cropped = match kept {
        Some(hu) => {
            drop(prepared);
            hu
        }
        None => prepared.volume,
    };

    // The CT on the training grid, normalised; how much of it is body, and of what.
    let grid = resample(&cropped, [size; 3])?;
    let (body_fraction, tissue_fractions) = grid_body(&grid);
    let ct = settings.window.normalize(&grid)?;

    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    nifti::write_nifti(&dir.join("ct.nii.gz"), &ct)?;
    image::write_npy(
        &dir.join("projections.npy"),
        &stack,
        &[views.len(), size, size],
    )?;
    item::write_views(dir, &geometry, &poses, &views)?;
    let record = ItemRecord {
        index,
        id: format!("{index:05}"),
        split: settings.split.clone(),
        source: serde_json::to_value(source)?,
        source_sha256: sha,
        hu_window: settings.window,
        energy_kev: settings.energy_kev,
        ct: "ct.nii.gz".into(),
        ct_dims: ct.dims(),
        projections: "projections.npy".into(),
        projection_quantity: quantity,
        acquisition: settings
            .acquisition
            .as_ref()
            .map(|(a, s)| {
                AcquisitionRecord {
                    settings: a.clone(),
                    noise_seed: *s,
                }
                .to_json()
            })
            .unwrap_or(serde_json::Value::Null),
        views: "views.json".into(),
        angles_deg: poses.iter().map(|p| [p.theta_deg, p.phi_deg]).collect(),
        frame: PATIENT_FRAME.into(),
        reorientation,
        outside_body,
        body_fraction,
        tissue_fractions,
        augmentation: augmentation
            .map(serde_json::to_value)
            .transpose()?
            .unwrap_or(serde_json::Value::Null),
        scan_range: scan_range
            .map(serde_json::to_value)
            .transpose()?
            .unwrap_or(serde_json::Value::Null),
    };
    item::write_record(dir, &record)?;
    Ok(peak_bytes)
}

/// A CT (HU, read from `path`) in the patient frame and, unless `settings.keep_table`,
/// with everything but the body set to air; with how it was reoriented and what was done
/// around the body, as `item.json` records them.
fn patient_of(
    hu: tomograf_sim::Volume,
    path: &Path,
    settings: &ItemSettings,
) -> Result<(tomograf_sim::Volume, serde_json::Value, String)> {
    let (framed, how) = to_patient_frame(hu, PADDING_HU)
        .with_context(|| format!("{}: bringing it into the patient frame", path.display()))?;
    let how = serde_json::to_value(how)?;
    if settings.keep_table {
        return Ok((framed, how, "kept".to_string()));
    }
    let mask = body::body_mask(&framed, &settings.body)
        .with_context(|| format!("{}: finding the body", path.display()))?;
    let note = format!(
        "set to air ({} HU): what is not the body (threshold {} HU, opening {} mm)",
        body::AIR_HU,
        settings.body.threshold_hu,
        settings.body.opening_mm
    );
    Ok((body::isolate_body(framed, &mask)?, how, note))
}

/// Value of grid points outside an oblique CT once it is resampled into the patient frame,
/// HU (the scanners' padding; cropped away with the border).
const PADDING_HU: f32 = -1024.0;

/// The fraction of an item's grid (HU) inside the body, and the body's tissue fractions,
/// measured the same way for CTs and phantoms: [`body::body_mask`] without the opening
/// (the grid is coarse, and a CT's surroundings are already air unless kept). `None` when
/// the grid holds no tissue.
fn grid_body(grid: &tomograf_sim::Volume) -> (Option<f64>, Option<body::TissueFractions>) {
    let settings = BodySettings {
        opening_mm: 0.0,
        ..BodySettings::default()
    };
    match body::body_mask(grid, &settings) {
        Ok(b) => (Some(b.fraction()), Some(b.tissue_fractions(grid))),
        Err(_) => (None, None),
    }
}
