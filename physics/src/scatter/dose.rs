//! Absorbed dose of an acquisition: the energy-imparted tally
//! ([`super::energy_imparted`]) run for every view, with the view's point source collimated
//! to its detector panel (the primary field is the panel, as for the scatter images), the
//! spectrum's photons per mAs through that solid angle, summed over the views.
//!
//! Units: dose Gy, energy eV and J, fluence photons per mAs per mm² at 1 m.

use super::energy_imparted::{BeamSpectrum, Estimate, TallySettings, dose_gy, simulate};
use super::field::FieldSource;
use super::transport::Medium;
use crate::spectrum::Spectrum;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::{View, ViewBeam};
use tomograf_sim::seed::frame_seed;
use tomograf_sim::volume::Volume;

/// Photon histories per view when a scene asks for dose without saying how many.
pub const DEFAULT_DOSE_PHOTONS: u64 = 1_000_000;

/// Seed salt of the dose streams (distinct from the noise and scatter streams).
const DOSE_SALT: u64 = 0xD05E_D05E_D05E_D05E;

/// The dose of an acquisition.
#[derive(Debug, Clone)]
pub struct Dose {
    /// Absorbed dose per voxel over all views, Gy, on the CT's grid.
    pub gray: Volume,
    /// Per view: energy imparted to the volume, eV per source photon, with its standard
    /// error.
    pub per_view: Vec<Estimate>,
    /// Per view: source photons emitted into the detector's solid angle.
    pub source_photons: Vec<f64>,
    /// Energy imparted over all views, J.
    pub energy_joule: f64,
}

/// The field of a cone-beam view: the source collimated to the detector panel.
pub fn view_field(view: &View) -> Result<FieldSource> {
    let ViewBeam::Cone { source } = view.beam else {
        return Err(SimError::InvalidGeometry(
            "dose needs a cone beam (a point source); this view is parallel".into(),
        ));
    };
    let centre = view.pixel_centre(
        (view.rows as f64 - 1.0) * 0.5,
        (view.cols as f64 - 1.0) * 0.5,
    );
    FieldSource::new(
        source,
        centre,
        view.u * (view.cols as f64 * 0.5),
        view.v * (view.rows as f64 * 0.5),
    )
}

/// The dose `views` deliver to `medium` with `spectrum` at `mas` per view, `photons`
/// histories per view; the dose volume is on the medium's grid.
pub fn acquisition_dose(
    medium: &Medium,
    spectrum: &Spectrum,
    mas: f64,
    views: &[View],
    photons: u64,
    seed: u64,
) -> Result<Dose> {
    if views.is_empty() {
        return Err(SimError::InvalidGeometry("dose: no views".into()));
    }
    if !(mas.is_finite() && mas > 0.0) {
        return Err(SimError::OutOfRange(format!(
            "dose: {mas} mAs; give a finite exposure > 0"
        )));
    }
    // Photons per bin per mm² at 1 m for this exposure.
    let per_mm2 = spectrum.photons_per_mm2(mas, 1000.0)?;
    let beam = BeamSpectrum::new(spectrum.energies_kev().to_vec(), &per_mm2)?;
    let per_mm2_total: f64 = per_mm2.iter().sum();
    let grid = medium.composition().packed();
    let mut total_ev = vec![0.0; grid.len()];
    let (mut per_view, mut source_photons) = (Vec::new(), Vec::new());
    for (i, view) in views.iter().enumerate() {
        view.validate()?;
        let field = view_field(view)?;
        // Photons into the field: fluence at 1 m times the field's area on a 1 m sphere.
        let n = per_mm2_total * field.solid_angle() * 1.0e6;
        let r = simulate(
            medium,
            &field,
            &beam,
            &[],
            TallySettings {
                photons,
                max_collisions: 1000,
                voxel_map: true,
                ..TallySettings::default()
            },
            frame_seed(seed ^ DOSE_SALT, i as u64),
        )?;
        for (t, e) in total_ev.iter_mut().zip(&r.voxel_ev) {
            *t += e * n;
        }
        per_view.push(r.deposited);
        source_photons.push(n);
    }
    let energy_joule = total_ev.iter().sum::<f64>() * super::energy_imparted::JOULE_PER_EV;
    let gy = dose_gy(medium, &total_ev, 1.0)?;
    let gray = Volume::new(
        grid.dims(),
        grid.spacing(),
        grid.origin(),
        grid.direction(),
        gy,
    )?;
    Ok(Dose {
        gray,
        per_view,
        source_photons,
        energy_joule,
    })
}
