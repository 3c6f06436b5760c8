//! `tomograf.render_scene` and `tomograf.project_scene`: a scene — a TOML file, or a dict of the same tables — rendered
//! (and written) as `tomograf project --scene` renders it (both go through `tomograf_scene::prepare`), so
//! the same scene gives the same bytes from Python and from the command line. Every key:
//! docs/scene.md.

use crate::errors;
use crate::progress::PyProgress;
use numpy::{IntoPyArray, PyArrayDyn};
use pyo3::exceptions::{PyFileNotFoundError, PyUserWarning};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use tomograf_physics::detector::Clipping;
use tomograf_scene::Scene;

/// Renders every view of a scene: ``scene`` is the path of a TOML scene file (relative
/// paths in it are taken from the file's folder) or a dict of the same tables (relative
/// paths from the working directory), e.g. ``{"volume": {"path": "ct.nii.gz"},
/// "views": {"poses": ["ap", "lateral"]}, "acquisition": {"preset":
/// "kv-flat-panel-120kvp", "seed": 7}, "scatter": {"model": "estimate"}}``. Keys and
/// units are those of docs/scene.md (mm, keV, mm⁻¹, HU); the ``[output]`` table's
/// ``quantity`` and ``i0`` apply, its files are not written.
///
/// Returns float32 ``(views, rows, cols)``: the ideal DRR in the scene's output quantity
/// (default line integrals), or with real detector physics the detector's signal; a
/// photon-counting detector adds a channel axis after the views axis. The same array as
/// the ``.npy`` stack `tomograf project` writes for the scene. Geometry that is probably
/// not meant (a source inside the volume, views missing it) and photon-starved or
/// saturated pixels raise a ``UserWarning``.
#[pyfunction]
pub fn render_scene<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let scene = scene_of(py, scene)?;
    let rendered = py.detach(|| -> anyhow::Result<_> {
        let prepared = tomograf_scene::prepare(&scene)?;
        let renderer = prepared.renderer()?;
        let views = &prepared.job.views;
        let mut data = Vec::new();
        let mut channels = 1;
        let mut clipping = Clipping::default();
        for (i, view) in views.iter().enumerate() {
            let frame = renderer.render(i, view)?;
            channels = frame.images.len();
            if let Some(parts) = &frame.parts {
                let pixels = frame.images.iter().map(|p| p.data.len()).sum();
                clipping.add(parts.clipped, parts.saturated, pixels);
            }
            for img in frame.images {
                data.extend(img.data);
            }
        }
        let clip = prepared.acquisition.as_ref().and_then(|(acq, _)| {
            clipping.warning(
                acq.spectrum.mas,
                "[spectrum] mas",
                acq.detector.has_signal_unit(),
            )
        });
        let (rows, cols) = views.first().map_or((0, 0), |v| (v.rows, v.cols));
        let mut shape = vec![views.len(), rows, cols];
        if channels > 1 {
            shape.insert(1, channels);
        }
        Ok((data, shape, prepared.warnings, clip))
    });
    let (data, shape, warnings, clip) = rendered.map_err(|e| errors::value(format!("{e:#}")))?;
    for w in warnings.iter().chain(&clip) {
        PyErr::warn(
            py,
            &py.get_type::<PyUserWarning>(),
            &std::ffi::CString::new(w.as_str())?,
            1,
        )?;
    }
    let arr =
        ndarray::ArrayD::from_shape_vec(shape, data).map_err(|e| errors::value(e.to_string()))?;
    Ok(arr.into_pyarray(py))
}

/// A scene from a TOML path or a dict of the same tables.
fn scene_of(py: Python<'_>, scene: &Bound<'_, PyAny>) -> PyResult<Scene> {
    Ok(if let Ok(d) = scene.cast::<PyDict>() {
        let json: String = py.import("json")?.call_method1("dumps", (d,))?.extract()?;
        serde_json::from_str::<Scene>(&json)
            .map_err(|e| errors::value(format!("the scene dict is not a valid scene: {e}")))?
    } else {
        let path: PathBuf = scene.extract()?;
        if !path.exists() {
            return Err(PyFileNotFoundError::new_err(format!(
                "scene file {} does not exist",
                path.display()
            )));
        }
        Scene::load(&path).map_err(|e| errors::value(format!("{e:#}")))?
    })
}

/// Renders every view of a scene and writes its files, exactly as `tomograf project
/// --scene` does (the same library function, `tomograf_scene::project`): the images in
/// the ``[output]`` table's formats into its ``dir`` (default ``out``, prefix ``drr``), the
/// ``.npy`` stack, the separate scatter images, the dose and the JSON sidecar. ``scene``
/// is a TOML path or a dict, as for :func:`render_scene`.
///
/// ``progress``, if given, is called as ``progress(stage, done, total, message)`` while it
/// runs (stage ``"view"``); an exception it raises is re-raised at the end. Warnings (geometry
/// probably not meant, clipped pixels) are raised as ``UserWarning``; every line the
/// command line would print (dose totals too) is in the returned ``notes``.
///
/// Returns a dict: ``views``, ``rows``, ``cols``, ``render_seconds``, ``load_seconds``,
/// ``files`` (how many were written), ``dir`` and ``notes``.
#[pyfunction]
#[pyo3(signature = (scene, progress=None))]
pub fn project_scene<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let scene = scene_of(py, scene)?;
    let reporter = PyProgress::new(progress);
    let summary = py.detach(|| tomograf_scene::project(&scene, &reporter));
    let notes = reporter.finish(py)?;
    let summary = summary.map_err(|e| errors::value(format!("{e:#}")))?;
    let d = PyDict::new(py);
    d.set_item("views", summary.views)?;
    d.set_item("rows", summary.rows)?;
    d.set_item("cols", summary.cols)?;
    d.set_item("render_seconds", summary.render_seconds)?;
    d.set_item("load_seconds", summary.load_seconds)?;
    d.set_item("files", summary.files)?;
    d.set_item("dir", summary.dir.to_string_lossy().into_owned())?;
    d.set_item("notes", notes)?;
    Ok(d)
}
