//! Phantoms: the analytic thorax (with its exact line integrals) and the procedural
//! chest patients of `tomograf_datasets::anatomy`.

use crate::errors;
use crate::geometry::PyView;
use crate::volume::{PyVolume, vec3};
use numpy::{IntoPyArray, PyArray2};
use pyo3::prelude::*;
use rayon::prelude::*;
use tomograf_datasets::anatomy::{self, AnatomySpec, Profile};
use tomograf_sim::phantom::Phantom;

fn analytic(seed: Option<u64>) -> Phantom {
    match seed {
        None => Phantom::thorax(),
        Some(s) => Phantom::thorax_variant(s),
    }
}

/// The analytic thorax phantom (HU) sampled at voxel centres of an axis-aligned grid
/// centred on ``centre`` (world LPS mm). ``seed``: a seeded variant (body and lung
/// size, heart position, nodules); ``None``: the reference thorax. About
/// 330 × 230 × 320 mm, centred on the world origin.
#[pyfunction]
#[pyo3(signature = (dims=[256, 256, 133], spacing_mm=[1.4, 1.4, 2.5], centre=[0.0, 0.0, 0.0], seed=None))]
pub fn thorax(
    py: Python<'_>,
    dims: [usize; 3],
    spacing_mm: [f64; 3],
    centre: [f64; 3],
    seed: Option<u64>,
) -> PyResult<PyVolume> {
    let spacing = vec3("spacing", spacing_mm)?;
    let centre = vec3("centre", centre)?;
    let v = py.detach(|| analytic(seed).voxelize(dims, spacing, centre));
    Ok(PyVolume::wrap(v.map_err(errors::sim)?))
}

/// Exact line integrals (float64, ``(rows, cols)``) of the analytic thorax (the same
/// ``seed`` as :func:`thorax`) through every pixel centre of ``view``, for
/// ``mu = mu_water_per_mm · (1 + HU/1000)``: the continuous phantom, no voxels.
#[pyfunction]
#[pyo3(signature = (view, mu_water_per_mm, seed=None))]
pub fn thorax_line_integrals<'py>(
    py: Python<'py>,
    view: &PyView,
    mu_water_per_mm: f64,
    seed: Option<u64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    if !(mu_water_per_mm.is_finite() && mu_water_per_mm > 0.0) {
        return Err(errors::value(format!(
            "mu_water = {mu_water_per_mm} mm⁻¹; it must be finite and > 0"
        )));
    }
    let v = view.inner;
    let (rows, cols) = (v.rows, v.cols);
    let data: Vec<f64> = py.detach(|| {
        let p = analytic(seed);
        (0..rows * cols)
            .into_par_iter()
            .map(|n| {
                p.line_integral(
                    &v.ray((n / cols) as f64, (n % cols) as f64),
                    mu_water_per_mm,
                )
            })
            .collect()
    });
    let a = ndarray::Array2::from_shape_vec((rows, cols), data)
        .map_err(|e| errors::value(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

fn spec(
    seed: u64,
    profile: &str,
    dims: [usize; 3],
    spacing_mm: [f64; 3],
    table: bool,
    pacemaker: bool,
) -> PyResult<AnatomySpec> {
    let profile = Profile::parse(profile).map_err(errors::dataset)?;
    let mut s = AnatomySpec::new(seed, profile, dims, spacing_mm);
    s.table = table;
    s.pacemaker = pacemaker;
    Ok(s)
}

/// A procedural chest patient (HU): lungs with vessel and airway trees, heart and great
/// vessels, spine, ribs, sternum, clavicles, scapulae; ``profile`` ``"lidc"`` (cropped
/// to the thorax) or ``"full-chest"`` (arms, neck, whole chest wall); optional patient
/// ``table`` and ``pacemaker``. Grid centred on the world origin, identity direction;
/// ``spacing_mm`` along (x, y, z). Same arguments, same voxels.
#[pyfunction]
#[pyo3(signature = (seed=0, profile="lidc", dims=[256, 256, 133], spacing_mm=[1.4, 1.4, 2.5], table=false, pacemaker=false))]
pub fn chest(
    py: Python<'_>,
    seed: u64,
    profile: &str,
    dims: [usize; 3],
    spacing_mm: [f64; 3],
    table: bool,
    pacemaker: bool,
) -> PyResult<PyVolume> {
    let s = spec(seed, profile, dims, spacing_mm, table, pacemaker)?;
    let v = py
        .detach(|| anatomy::generate(&s))
        .map_err(errors::dataset)?;
    Ok(PyVolume::wrap(v))
}

/// The patient that :func:`chest` with the same arguments generates (sizes, landmarks,
/// nodules, in world LPS mm) as a dict, without generating voxels.
#[pyfunction]
#[pyo3(signature = (seed=0, profile="lidc", dims=[256, 256, 133], spacing_mm=[1.4, 1.4, 2.5], table=false, pacemaker=false))]
pub fn describe_chest<'py>(
    py: Python<'py>,
    seed: u64,
    profile: &str,
    dims: [usize; 3],
    spacing_mm: [f64; 3],
    table: bool,
    pacemaker: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let s = spec(seed, profile, dims, spacing_mm, table, pacemaker)?;
    let p = anatomy::describe(&s).map_err(errors::dataset)?;
    let text = serde_json::to_string(&p).map_err(|e| errors::value(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}
