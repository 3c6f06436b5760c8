//! Classical reconstruction from projections: the baselines a learned reconstruction is
//! measured against.
//!
//! * [`backproject`] — the exact adjoint of the Siddon projector ([`SiddonOperator`]):
//!   a pixel's value is spread along exactly the path the forward projector integrates.
//! * [`fdk`] — Feldkamp–Davis–Kress filtered backprojection for flat-panel cone beam on a
//!   circular orbit, with ramp-filter windows, full-scan, Parker short-scan and sparse-view
//!   angular weighting.
//! * [`sart`] — SART (ordered subsets) and SIRT on the Siddon operator, with
//!   non-negativity and optional TV steps (ASD-POCS style).
//! * [`tv`] — total variation and its gradient.
//! * [`scatter_correction`] — −log projections corrected by the scatter-to-primary ratio
//!   an estimate of the object gives through the acquisition's own scatter model.
//!
//! Inputs are line-integral images ([`tomograf_sim::render::Projection`], dimensionless ∫mu ds)
//! and the views they were taken in; outputs are volumes of linear attenuation (mm⁻¹) on
//! a *template* grid (its dims, spacing, origin and direction; its values are ignored).
//! [`mu_to_hu`] converts them to HU with [`tomograf_sim::attenuation::mu_water_per_mm`].

pub mod backproject;
pub mod fdk;
pub mod sart;
pub mod scatter_correction;
pub mod tv;

pub use backproject::{SiddonOperator, backproject, forward_project};
pub use fdk::{AngularWeighting, FdkOptions, Window, fdk};
pub use sart::{
    IterationReport, Reconstruction, SartOptions, sart_tv, sart_tv_from, sart_tv_with_progress,
};
pub use tv::TvOptions;

use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::View;
use tomograf_sim::render::Projection;
use tomograf_sim::volume::Volume;

/// Checks that there is at least one view, one image per view, each image the size of its
/// view's detector and every pixel finite.
pub(crate) fn check_projections(projections: &[Projection], views: &[View]) -> Result<()> {
    if views.is_empty() {
        return Err(SimError::InvalidGeometry(
            "no views: reconstruction needs at least one projection".into(),
        ));
    }
    if projections.len() != views.len() {
        return Err(SimError::InvalidProjections(format!(
            "{} projections were given for {} views",
            projections.len(),
            views.len()
        )));
    }
    for (i, (p, v)) in projections.iter().zip(views).enumerate() {
        v.validate()?;
        if p.rows != v.rows || p.cols != v.cols || p.data.len() != p.rows * p.cols {
            return Err(SimError::InvalidProjections(format!(
                "projection {i} is {}×{} ({} values) but its view's detector is {}×{}",
                p.rows,
                p.cols,
                p.data.len(),
                v.rows,
                v.cols
            )));
        }
        if let Some(k) = p.data.iter().position(|x| !x.is_finite()) {
            return Err(SimError::InvalidProjections(format!(
                "projection {i} has a non-finite value ({}) at row {}, column {}",
                p.data[k],
                k / p.cols,
                k % p.cols
            )));
        }
    }
    Ok(())
}

/// A volume with `template`'s grid holding `data`.
pub(crate) fn on_grid(template: &Volume, data: Vec<f32>) -> Result<Volume> {
    Volume::new(
        template.dims(),
        template.spacing(),
        template.origin(),
        template.direction(),
        data,
    )
}

/// Converts linear attenuation (mm⁻¹) to HU: `HU = 1000·(mu/mu_water − 1)`, the inverse of
/// [`tomograf_sim::attenuation::hu_to_mu`] above −1000 HU (negative mu, which reconstructions can
/// produce, maps below −1000 HU and is kept, not clamped).
pub fn mu_to_hu(volume: &Volume, mu_water_per_mm: f64) -> Result<Volume> {
    if !(mu_water_per_mm.is_finite() && mu_water_per_mm > 0.0) {
        return Err(SimError::OutOfRange(format!(
            "mu_water = {mu_water_per_mm} mm⁻¹; it must be finite and > 0"
        )));
    }
    volume.map(|mu| (1000.0 * (f64::from(mu) / mu_water_per_mm - 1.0)) as f32)
}

/// [`mu_to_hu`] with `mu_water` at an effective energy (keV) from the shipped water table.
pub fn mu_to_hu_at_kev(volume: &Volume, energy_kev: f64) -> Result<Volume> {
    mu_to_hu(
        volume,
        tomograf_sim::attenuation::mu_water_per_mm(energy_kev)?,
    )
}
