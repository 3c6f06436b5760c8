//! `tomograf.scatter_matched`: the scatter engine's matched-physics mode (monoenergetic,
//! constant albedo, isotropic or Henyey–Greenstein phase, homogeneous box), for
//! cross-checks with general-purpose volumetric renderers (bridge/tests/test_scatter_mitsuba.py).

use crate::errors;
use glam::DVec3;
use numpy::{IntoPyArray, PyArray2};
use pyo3::prelude::*;
use tomograf_eval::validation::matched::{MatchedMedium, simulate};
use tomograf_sim::geometry::{View, ViewBeam};

type Image<'py> = Bound<'py, PyArray2<f64>>;

/// Per-pixel scatter from a point source through a homogeneous box (mm, mm⁻¹), scored at
/// every pixel centre ``detector_origin + c·u + r·v`` (pixel (0, 0) at
/// ``detector_origin``; ``u``, ``v`` the pixel steps in mm) by forced detection.
///
/// Returns ``(single, multiple, single_se, total_se)``, each ``(rows, cols)`` float64:
/// photons per pixel for a source of intensity 1 photon/sr, and Monte Carlo standard
/// errors of ``single`` and of ``single + multiple``.
#[pyfunction]
#[pyo3(signature = (source, detector_origin, u, v, rows, cols, box_min, box_max, mu_t, albedo, g=0.0, photons=100_000, max_order=1000, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn scatter_matched<'py>(
    py: Python<'py>,
    source: [f64; 3],
    detector_origin: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
    rows: usize,
    cols: usize,
    box_min: [f64; 3],
    box_max: [f64; 3],
    mu_t: f64,
    albedo: f64,
    g: f64,
    photons: u64,
    max_order: u32,
    seed: u64,
) -> PyResult<(Image<'py>, Image<'py>, Image<'py>, Image<'py>)> {
    let view = View {
        beam: ViewBeam::Cone {
            source: DVec3::from(source),
        },
        detector_origin: DVec3::from(detector_origin),
        u: DVec3::from(u),
        v: DVec3::from(v),
        rows,
        cols,
    };
    let medium = MatchedMedium {
        min_mm: DVec3::from(box_min),
        max_mm: DVec3::from(box_max),
        mu_t_per_mm: mu_t,
        albedo,
        g,
    };
    let out = py
        .detach(|| simulate(&medium, &view, photons, max_order, seed))
        .map_err(errors::sim)?;
    let image = |v: Vec<f64>| -> PyResult<Image<'py>> {
        let a = ndarray::Array2::from_shape_vec((rows, cols), v)
            .map_err(|e| errors::value(e.to_string()))?;
        Ok(a.into_pyarray(py))
    };
    Ok((
        image(out.single)?,
        image(out.multiple)?,
        image(out.single_se)?,
        image(out.total_se)?,
    ))
}
