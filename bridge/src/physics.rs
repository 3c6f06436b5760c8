//! `tomograf.acquire`: what a real detector records (polychromatic beam, tissues, detector
//! noise and blur, flat-field correction), with the GIL released. See docs/physics.md.

use crate::errors;
use crate::volume::PyVolume;
use numpy::{IntoPyArray, PyArrayDyn};
use pyo3::prelude::*;
use tomograf_physics::acquisition::{Acquisition, PRESETS};
use tomograf_physics::detector::{Clipping, DetectorModel, Output};
use tomograf_sim::Projector;

/// Names of the acquisition presets (``"ideal-drr"`` is :func:`project` itself).
#[pyfunction]
pub fn presets() -> Vec<&'static str> {
    PRESETS.to_vec()
}

/// Names of the detector models (``detector=`` of :func:`acquire`): ``"perfect-absorber"``
/// (alias ``"ideal"``: η = 1), ``"noiseless-csi"`` (0.6 mm CsI response, no noise),
/// ``"kv-flat-panel"``, ``"cbct"``, ``"photon-counting"`` (docs/detector.md).
#[pyfunction]
pub fn detector_models() -> Vec<&'static str> {
    DetectorModel::NAMES.to_vec()
}

/// Acquires one view or a list of views of a CT volume in **HU** with real detector
/// physics: a preset (``"kv-flat-panel-120kvp"`` or ``"cbct-100kvp"``), optionally with
/// another tube voltage ``kvp`` (kVp, whole numbers 40–150), exposure ``mas`` (mA·s per
/// view), ``energy_bins`` (rebinned spectrum; default 1 keV bins) and ``signal``
/// (``"raw"`` ADU/counts, ``"flat-field"`` transmission, or ``"log-line-integral"``, the
/// default); ``detector`` replaces the preset's detector by name (:func:`detector_models`,
/// e.g. ``"noiseless-csi"``). Noise is seeded by ``seed``: view ``i`` of the list has its own stream, so the
/// result depends only on the inputs, never on the thread count. Photon-starved or
/// saturated pixels raise a ``UserWarning`` that counts them and names ``mas``.
///
/// Returns float32 ``(rows, cols)`` for one view, ``(views, rows, cols)`` for a list; a
/// photon-counting detector adds a channel axis after the views axis.
#[pyfunction]
#[pyo3(signature = (hu, views, preset="kv-flat-panel-120kvp", kvp=None, mas=None, energy_bins=None, signal=None, seed=0, projector="siddon", detector=None))]
#[allow(clippy::too_many_arguments)]
pub fn acquire<'py>(
    py: Python<'py>,
    hu: &PyVolume,
    views: &Bound<'py, PyAny>,
    preset: &str,
    kvp: Option<f64>,
    mas: Option<f64>,
    energy_bins: Option<usize>,
    signal: Option<&str>,
    seed: u64,
    projector: &str,
    detector: Option<&str>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let proj = Projector::from_name(projector, 0.5).map_err(errors::sim)?;
    let mut acq = acquisition(preset, kvp, mas)?;
    if energy_bins.is_some() {
        acq.spectrum.bins = energy_bins;
    }
    if let Some(d) = detector {
        acq.detector = DetectorModel::by_name(d, None).map_err(errors::sim)?;
    }
    if let Some(s) = signal {
        acq.output = Output::from_name(s).map_err(errors::sim)?;
    }
    let (list, single) = crate::render::view_list(views)?;
    let (rows, cols) = (list[0].rows, list[0].cols);
    let vol = &hu.inner;
    let channels = acq.detector.channels();
    let (out, clipping) = py.detach(|| -> PyResult<(Vec<f32>, Clipping)> {
        let prepared = acq
            .prepare(vol, seed)
            .and_then(|p| p.for_views(proj, &list))
            .map_err(errors::sim)?;
        let mut data = Vec::with_capacity(list.len() * channels * rows * cols);
        let mut clipping = Clipping::default();
        for (i, view) in list.iter().enumerate() {
            let parts = prepared
                .acquire_with_parts(proj, view, i)
                .map_err(errors::sim)?;
            let pixels = parts.images.iter().map(|p| p.data.len()).sum();
            clipping.add(parts.clipped, parts.saturated, pixels);
            for img in parts.images {
                data.extend(img.data);
            }
        }
        Ok((data, clipping))
    })?;
    // Starved or saturated pixels: the same warning as the command line, as a Python
    // UserWarning (silence it with the warnings module).
    if let Some(w) = clipping.warning(acq.spectrum.mas, "mas=", acq.detector.has_signal_unit()) {
        let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
        PyErr::warn(
            py,
            &category,
            &std::ffi::CString::new(w).unwrap_or_default(),
            1,
        )?;
    }
    let mut shape = Vec::new();
    if !single {
        shape.push(list.len());
    }
    if channels > 1 {
        shape.push(channels);
    }
    shape.extend([rows, cols]);
    let arr =
        ndarray::ArrayD::from_shape_vec(shape, out).map_err(|e| errors::value(e.to_string()))?;
    Ok(arr.into_pyarray(py))
}

/// A preset with another tube voltage or exposure.
fn acquisition(preset: &str, kvp: Option<f64>, mas: Option<f64>) -> PyResult<Acquisition> {
    let mut acq = Acquisition::preset(preset).map_err(errors::sim)?;
    if let Some(k) = kvp {
        acq.spectrum.kvp = Some(k);
    }
    if let Some(m) = mas {
        acq.spectrum.mas = m;
    }
    Ok(acq)
}

/// Absorbed dose (**Gy**, a :class:`Volume` on the CT's grid) that ``views`` deliver to a
/// CT in **HU** with a preset's spectrum and tissues, optionally another ``kvp`` or ``mas``
/// (mA·s per view): a Monte Carlo of ``photons`` histories per view, each view's source
/// collimated to its detector panel, electron energy deposited where the photon
/// interacts (no electron transport). Seeded; GIL released; the result does not depend
/// on the thread count. See docs/scatter.md, "Dose".
#[pyfunction]
#[pyo3(signature = (hu, views, preset="kv-flat-panel-120kvp", kvp=None, mas=None, photons=1_000_000, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn dose(
    py: Python<'_>,
    hu: &PyVolume,
    views: &Bound<'_, PyAny>,
    preset: &str,
    kvp: Option<f64>,
    mas: Option<f64>,
    photons: u64,
    seed: u64,
) -> PyResult<PyVolume> {
    let acq = acquisition(preset, kvp, mas)?;
    let (list, _) = crate::render::view_list(views)?;
    let vol = &hu.inner;
    let d = py
        .detach(|| acq.dose(vol, &list, photons, seed))
        .map_err(errors::sim)?;
    Ok(PyVolume::wrap(d.gray))
}
