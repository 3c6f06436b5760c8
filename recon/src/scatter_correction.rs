//! Scatter correction of measured −log projections from an estimate of the object.
//!
//! A flat-field-corrected −log image of a detector that records primary `P` and scatter
//! `S` is `p = −ln((P + S)/O)`, O the open field: scatter lowers every line integral behind
//! the patient, and a reconstruction from `p` has too little attenuation. Given an
//! estimate of the object (a prior such as the mean training volume, or a first
//! reconstruction), the acquisition's own spectrum, tissue model and scatter model give
//! the expected primary `P̂` and scatter `Ŝ` of each view, and the corrected line integral
//! is
//!
//! ```text
//! p_c = p + ln(1 + Ŝ/P̂)
//! ```
//!
//! This is the multiplicative (scatter-to-primary ratio) form of Monte Carlo scatter
//! correction used in cone-beam CT: it is exact when the estimate is the object (then
//! `(P + S)/O · P/(P + S) = P/O`), and unlike subtracting `Ŝ/O` from the transmission it
//! can never produce a negative transmission, however wrong `Ŝ` is. Scatter is smooth, so
//! an estimate that has the patient's outline and gross densities right gives most of the
//! correction (docs/studies.md measures how much).
//!
//! The ratio is taken between expected signals before the detector records them (the
//! detector's blur acts on both alike and its noise has zero mean); the primary is traced
//! with exact Siddon.

use tomograf_physics::acquisition::Prepared;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::View;
use tomograf_sim::render::Projector;

/// Largest scatter-to-primary ratio a pixel is corrected by: where the estimate's primary
/// is starved (P̂ → 0) the ratio is meaningless, and the correction is capped at
/// ln(1 + 100) ≈ 4.6.
pub const MAX_SCATTER_TO_PRIMARY: f64 = 100.0;

/// The expected scatter-to-primary ratio `Ŝ/P̂` of view number `index` through the
/// prepared estimate, one value per pixel (row-major, one channel), capped at
/// [`MAX_SCATTER_TO_PRIMARY`]. `index` seeds the scatter's random streams
/// ([`Prepared::scatter`]). Errors when the acquisition models no scatter or records more
/// than one channel.
pub fn scatter_to_primary(estimate: &Prepared, view: &View, index: usize) -> Result<Vec<f64>> {
    let primary = estimate.primary(Projector::Siddon, view)?;
    if primary.channels != 1 {
        return Err(SimError::OutOfRange(format!(
            "scatter correction needs a one-channel detector; this one records {} channels",
            primary.channels
        )));
    }
    let Some(scatter) = estimate.scatter(view, index)? else {
        return Err(SimError::OutOfRange(
            "scatter correction needs an acquisition that models scatter ([scatter] model = \
             \"estimate\" or \"monte-carlo\")"
                .into(),
        ));
    };
    let scatter = scatter.total();
    Ok(primary
        .mean
        .iter()
        .zip(&scatter.mean)
        .map(|(&p, &s)| {
            if s <= 0.0 {
                0.0
            } else if p > 0.0 {
                (s / p).min(MAX_SCATTER_TO_PRIMARY)
            } else {
                MAX_SCATTER_TO_PRIMARY
            }
        })
        .collect())
}

/// Corrects one −log image in place by a per-pixel scatter-to-primary ratio:
/// `p ← p + ln(1 + spr)`. Errors when the sizes differ or a ratio is negative or not
/// finite.
pub fn correct_log(image: &mut [f32], spr: &[f64]) -> Result<()> {
    if image.len() != spr.len() {
        return Err(SimError::InvalidProjections(format!(
            "scatter correction: the image has {} pixels but the ratio {}",
            image.len(),
            spr.len()
        )));
    }
    if let Some(k) = spr.iter().position(|r| !(r.is_finite() && *r >= 0.0)) {
        return Err(SimError::InvalidProjections(format!(
            "scatter correction: ratio {} at pixel {k} (it must be finite and ≥ 0)",
            spr[k]
        )));
    }
    image
        .iter_mut()
        .zip(spr)
        .for_each(|(p, r)| *p = (f64::from(*p) + r.ln_1p()) as f32);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_correction_undoes_a_known_ratio() {
        // p = −ln((P+S)/O) with P/O = 0.2, S = 0.5 P: p_c must be −ln 0.2.
        let (t_primary, spr) = (0.2_f64, 0.5_f64);
        let mut image = [(-(t_primary * (1.0 + spr)).ln()) as f32];
        correct_log(&mut image, &[spr]).unwrap();
        assert!((f64::from(image[0]) - (-t_primary.ln())).abs() < 1e-6);
    }

    #[test]
    fn bad_ratios_are_named() {
        let mut image = [1.0_f32, 2.0];
        assert!(correct_log(&mut image, &[0.1]).is_err());
        let e = correct_log(&mut image, &[0.1, f64::NAN]).unwrap_err();
        assert!(e.to_string().contains("pixel 1"), "{e}");
        assert_eq!(image, [1.0, 2.0], "nothing is changed on error");
    }
}
