//! `tomograf.render_scene`: a scene — a TOML file, or a dict of the same tables — rendered
//! as `tomograf project --scene` renders it (both go through `tomograf_scene::prepare`), so
//! the same scene gives the same bytes from Python and from the command line. Every key:
//! docs/scene.md.

use crate::errors;
use numpy::{IntoPyArray, PyArrayDyn};
use pyo3::exceptions::{PyFileNotFoundError, PyUserWarning};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use tomograf_scene::Scene;
use tomograf_sim::detector::Clipping;

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
    let scene = if let Ok(d) = scene.cast::<PyDict>() {
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
    };
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
        let clip = prepared
            .acquisition
            .as_ref()
            .and_then(|(acq, _)| clipping.warning(acq.spectrum.mas, "[spectrum] mas"));
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
