//! # `tomograf` — the Python module
//!
//! PyO3 bindings of tomograf: volumes (NIfTI/DICOM in, numpy in and out), HU → mu,
//! geometry (poses, detectors, cone/parallel set-ups, general-form views), exact Siddon
//! and trilinear projections (GIL released), and the phantoms. Built with maturin
//! (`bridge/pyproject.toml`) as `tomograf._native`, re-exported by the package
//! `bridge/python/tomograf/`; type stubs in `bridge/python/tomograf/_native.pyi`; tests in
//! `bridge/tests/` (pytest). Conventions and units: `docs/python.md`.
//!
//! Arrays: volumes are numpy `[k, j, i]` (z, y, x for an axial CT, i fastest), images
//! `(rows, cols)` with row 0 at the top (beam's-eye view). Lengths in mm, attenuation in
//! mm⁻¹, energies in keV, CT values in HU, angles in degrees; world frame DICOM LPS.
//!
//! Errors: Rust messages unchanged, as `ValueError` (bad input) or `OSError` and its
//! subclasses (files); see [`errors`].
//!
//! ## Adding a part (spectra, detector response, scatter, meshes, reconstruction)
//! Write it as its own module here (one concept per module: `spectrum.rs`,
//! `detector_response.rs`, `scatter.rs`, …) with `#[pyclass]`/`#[pyfunction]` items
//! that convert errors through [`errors`] and release the GIL with `py.detach` around
//! the heavy work, register it in [`tomograf_py`] below under the matching comment, and add
//! its signatures to `_native.pyi` and a test to `bridge/tests/`.

mod dataset;
pub mod errors;
pub mod geometry;
mod model;
pub mod phantom;
mod physics;
mod progress;
pub mod render;
pub mod scatter;
mod scene;
pub mod volume;

use pyo3::prelude::*;

/// Simulated X-ray projections (DRRs) of CT volumes: exact Siddon and trilinear ray
/// tracing in cone- and parallel-beam geometry. Units: mm, mm⁻¹, keV, HU, degrees;
/// world frame DICOM LPS. See docs/python.md.
#[pymodule]
#[pyo3(name = "_native")]
fn tomograf_py(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // Volumes and attenuation.
    m.add_class::<volume::PyVolume>()?;
    m.add_function(wrap_pyfunction!(volume::mu_water, m)?)?;
    m.add_function(wrap_pyfunction!(volume::water_energy_range_kev, m)?)?;
    // Geometry.
    m.add_class::<geometry::PyPose>()?;
    m.add_class::<geometry::PyDetector>()?;
    m.add_class::<geometry::PyGeometry>()?;
    m.add_class::<geometry::PyView>()?;
    m.add_function(wrap_pyfunction!(geometry::arc, m)?)?;
    // Rendering.
    m.add_function(wrap_pyfunction!(render::project, m)?)?;
    m.add_function(wrap_pyfunction!(render::line_integrals, m)?)?;
    // Phantoms.
    m.add_function(wrap_pyfunction!(phantom::thorax, m)?)?;
    m.add_function(wrap_pyfunction!(phantom::thorax_line_integrals, m)?)?;
    m.add_function(wrap_pyfunction!(phantom::chest, m)?)?;
    m.add_function(wrap_pyfunction!(phantom::describe_chest, m)?)?;
    // Real detector physics (spectrum, tissues, detector).
    m.add_function(wrap_pyfunction!(physics::acquire, m)?)?;
    m.add_function(wrap_pyfunction!(physics::dose, m)?)?;
    m.add_function(wrap_pyfunction!(physics::presets, m)?)?;
    m.add_function(wrap_pyfunction!(physics::detector_models, m)?)?;
    // Scatter.
    m.add_function(wrap_pyfunction!(scatter::scatter_matched, m)?)?;
    // Scenes (the same files `tomograf project --scene` renders).
    m.add_function(wrap_pyfunction!(scene::render_scene, m)?)?;
    m.add_function(wrap_pyfunction!(scene::project_scene, m)?)?;
    m.add_function(wrap_pyfunction!(model::reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(model::evaluate, m)?)?;
    // Data-set items (the same files `tomograf dataset` writes).
    m.add_function(wrap_pyfunction!(dataset::make_item, m)?)?;
    // Meshes, reconstruction: register here.
    Ok(())
}
