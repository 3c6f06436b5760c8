//! `tomograf.project` and `tomograf.line_integrals`: rendering, with the GIL released.

use crate::errors;
use crate::geometry::PyView;
use crate::volume::PyVolume;
use glam::DVec3;
use numpy::{AllowTypeChange, IntoPyArray, PyArrayDyn, PyArrayLikeDyn};
use pyo3::prelude::*;
use rayon::prelude::*;
use tomograf_sim::{Projector, Quantity, Ray, Renderer, Tracer, View, Volume};

/// Parses the projector name (the one table: [`Projector::from_name`]).
fn projector(name: &str, step_voxels: f64) -> PyResult<Projector> {
    Projector::from_name(name, step_voxels).map_err(errors::sim)
}

/// Parses the output quantity name (the one table: [`Quantity::from_name`]; checked).
fn quantity(name: &str, i0: f64) -> PyResult<Quantity> {
    Quantity::from_name(name, i0).map_err(errors::sim)
}

/// The projectors integrate mm⁻¹: a negative voxel means HU were passed by mistake.
fn check_mu(mu: &Volume) -> PyResult<()> {
    let (lo, _) = mu.min_max();
    if lo < 0.0 {
        return Err(errors::value(format!(
            "the volume holds negative values (minimum {lo}); projectors integrate linear \
             attenuation in mm⁻¹ — convert HU first with Volume.to_mu()"
        )));
    }
    Ok(())
}

/// The views of a `views` argument (one `View`, or a non-empty sequence of views of one
/// size), and whether it was a single view.
pub(crate) fn view_list(views: &Bound<'_, PyAny>) -> PyResult<(Vec<View>, bool)> {
    let (list, single): (Vec<View>, bool) = match views.cast::<PyView>() {
        Ok(v) => (vec![v.get().inner], true),
        Err(_) => {
            let vs: Vec<PyView> = views.extract().map_err(|_| {
                errors::value("views must be a tomograf.View or a sequence of them")
            })?;
            (vs.into_iter().map(|v| v.inner).collect(), false)
        }
    };
    let Some(first) = list.first() else {
        return Err(errors::value("no views to render"));
    };
    if list
        .iter()
        .any(|v| v.rows != first.rows || v.cols != first.cols)
    {
        return Err(errors::value(
            "all views in one call must have the same rows × cols",
        ));
    }
    Ok((list, single))
}

/// Renders one view or a list of views of an attenuation volume (mm⁻¹).
///
/// ``projector``: ``"siddon"`` (exact, nearest-voxel field) or ``"trilinear"``
/// (midpoint rule through the trilinearly interpolated, cell-centred, edge-clamped field,
/// samples ``step_voxels`` voxels apart). ``quantity``: ``"line-integral"`` (∫mu ds,
/// dimensionless), ``"transmission"`` (exp(−L)) or ``"intensity"`` (``i0``·exp(−L)).
/// ``tracer``: which exact Siddon tracer renders, ``"auto"`` (the measured best),
/// ``"scalar"``, ``"packets"``, ``"sheets"`` or ``"columns"`` (docs/projector.md, "Which
/// tracer"; images agree to rounding).
/// Returns float32 ``(rows, cols)`` for one view, ``(views, rows, cols)`` for a list;
/// row 0 is the top row (beam's-eye view). The GIL is released while rendering;
/// the result does not depend on the thread count.
#[pyfunction]
#[pyo3(signature = (mu, views, projector="siddon", step_voxels=0.5, quantity="line-integral", i0=1.0, tracer="auto"))]
#[allow(clippy::too_many_arguments)]
pub fn project<'py>(
    py: Python<'py>,
    mu: &PyVolume,
    views: &Bound<'py, PyAny>,
    projector: &str,
    step_voxels: f64,
    quantity: &str,
    i0: f64,
    tracer: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let proj = self::projector(projector, step_voxels)?;
    let tracer = Tracer::from_name(tracer).map_err(errors::sim)?;
    let q = self::quantity(quantity, i0)?;
    let (list, single) = view_list(views)?;
    let (rows, cols) = (list[0].rows, list[0].cols);
    let vol = &mu.inner;
    let out = py.detach(|| -> PyResult<Vec<f32>> {
        check_mu(vol)?;
        let renderer = Renderer::new(vol, proj)
            .map_err(errors::sim)?
            .with_tracer(tracer)
            .for_views(&list);
        let mut data = Vec::new();
        for view in &list {
            let img = renderer.render(view).map_err(errors::sim)?;
            data.extend(img.to_quantity(q).data);
        }
        Ok(data)
    })?;
    let shape: Vec<usize> = if single {
        vec![rows, cols]
    } else {
        vec![list.len(), rows, cols]
    };
    let arr =
        ndarray::ArrayD::from_shape_vec(shape, out).map_err(|e| errors::value(e.to_string()))?;
    Ok(arr.into_pyarray(py))
}

/// ∫mu ds (float64) along explicit rays ``origin + t·direction``, t in
/// [``t_min``, ``t_max``] mm (defaults 0 and +∞).
///
/// ``origins`` and ``directions``: arrays of shape ``(..., 3)`` in world LPS mm
/// (directions are normalised here, so t is always mm); ``t_min``/``t_max``: scalars or
/// arrays of shape ``(...)``. Returns shape ``(...)``. Same projectors as
/// :func:`project`.
#[pyfunction]
#[pyo3(signature = (mu, origins, directions, t_min=None, t_max=None, projector="siddon", step_voxels=0.5))]
#[allow(clippy::too_many_arguments)]
pub fn line_integrals<'py>(
    py: Python<'py>,
    mu: &PyVolume,
    origins: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
    directions: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
    t_min: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
    t_max: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
    projector: &str,
    step_voxels: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let proj = self::projector(projector, step_voxels)?;
    let o = origins.as_array();
    let d = directions.as_array();
    if o.shape() != d.shape() || o.shape().last() != Some(&3) {
        return Err(errors::value(format!(
            "origins {:?} and directions {:?} must have the same shape (..., 3)",
            o.shape(),
            d.shape()
        )));
    }
    let lead: Vec<usize> = o.shape()[..o.ndim() - 1].to_vec();
    let n: usize = lead.iter().product();
    let bounds = |t: &Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
                  name: &str,
                  default: f64|
     -> PyResult<Vec<f64>> {
        match t {
            None => Ok(vec![default; n]),
            Some(a) => {
                let a = a.as_array();
                if a.ndim() == 0 {
                    Ok(vec![a.iter().copied().next().unwrap_or(default); n])
                } else if a.shape() == lead.as_slice() {
                    Ok(a.iter().copied().collect())
                } else {
                    Err(errors::value(format!(
                        "{name} has shape {:?}; expected a scalar or {lead:?}",
                        a.shape()
                    )))
                }
            }
        }
    };
    let t0 = bounds(&t_min, "t_min", 0.0)?;
    let t1 = bounds(&t_max, "t_max", f64::INFINITY)?;
    let ov: Vec<f64> = o.iter().copied().collect();
    let dv: Vec<f64> = d.iter().copied().collect();
    let mut rays = Vec::with_capacity(n);
    for r in 0..n {
        let origin = DVec3::from_slice(&ov[3 * r..3 * r + 3]);
        let dir = DVec3::from_slice(&dv[3 * r..3 * r + 3]);
        let len = dir.length();
        if !(origin.is_finite() && dir.is_finite() && len > 0.0) {
            return Err(errors::value(format!(
                "ray #{r}: origin {origin} and direction {dir} must be finite, direction non-zero"
            )));
        }
        if t0[r].is_nan() || t1[r].is_nan() || t0[r] > t1[r] {
            return Err(errors::value(format!(
                "ray #{r}: t_min = {} and t_max = {} must satisfy t_min ≤ t_max",
                t0[r], t1[r]
            )));
        }
        rays.push(Ray {
            origin,
            direction: dir / len,
            t_min: t0[r],
            t_max: t1[r],
        });
    }
    let vol = &mu.inner;
    let out = py.detach(|| -> PyResult<Vec<f64>> {
        check_mu(vol)?;
        let renderer = Renderer::new(vol, proj).map_err(errors::sim)?;
        Ok(rays.par_iter().map(|r| renderer.line_integral(r)).collect())
    })?;
    let arr =
        ndarray::ArrayD::from_shape_vec(lead, out).map_err(|e| errors::value(e.to_string()))?;
    Ok(arr.into_pyarray(py))
}
