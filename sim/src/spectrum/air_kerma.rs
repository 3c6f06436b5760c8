//! Air kerma from photon fluence: `K = Σ Φᵢ · Eᵢ · (μ_en/ρ)_air(Eᵢ)`.
//!
//! `(μ_en/ρ)_air` is NIST's table for dry air (Hubbell & Seltzer, NISTIR 5632, Table 4), shipped
//! as `data/air_muen_nist.csv`. That grid is coarse (10 keV steps where the photo-effect hands
//! over to Compton scattering), and log–log interpolation of μ_en/ρ itself overestimates it by
//! up to a few per cent between points. So the smooth ratio `(μ_en/ρ) / (μ/ρ)` is interpolated
//! log–log instead and multiplied by the dense total `μ/ρ` of `air` from [`crate::material`];
//! at the NIST energies this reproduces the table exactly. The argon K edge is kept as two
//! rows. Used for half-value layers, which are defined on air kerma, and for tube output.

use crate::error::{Result, SimError};
use crate::material::{Material, by_name};
use std::sync::OnceLock;

const AIR_MUEN_CSV: &str = include_str!("../../data/air_muen_nist.csv");

/// keV → joules.
const KEV_TO_J: f64 = 1.602_176_634e-16;

fn air() -> Result<&'static Material> {
    static AIR: OnceLock<std::result::Result<Material, String>> = OnceLock::new();
    AIR.get_or_init(|| by_name("air").map_err(|e| e.to_string()))
        .as_ref()
        .map_err(|e| SimError::DataTable(e.clone()))
}

/// (energy keV, (μ_en/ρ)/(μ/ρ) of air) at the NIST energies.
fn table() -> Result<&'static [(f64, f64)]> {
    static T: OnceLock<std::result::Result<Vec<(f64, f64)>, String>> = OnceLock::new();
    T.get_or_init(|| {
        let mut out: Vec<(f64, f64)> = Vec::new();
        for (i, l) in AIR_MUEN_CSV.lines().enumerate() {
            if l.starts_with('#') || l.trim().is_empty() {
                continue;
            }
            let (e, m) = l
                .split_once(',')
                .ok_or_else(|| format!("air_muen_nist.csv line {}: two columns", i + 1))?;
            let (e, m): (f64, f64) = match (e.trim().parse(), m.trim().parse()) {
                (Ok(e), Ok(m)) if e > 0.0 && m > 0.0 => (e, m),
                _ => return Err(format!("air_muen_nist.csv line {}: bad numbers", i + 1)),
            };
            if out.last().is_some_and(|&(pe, _)| e < pe) {
                return Err(format!(
                    "air_muen_nist.csv line {}: energies not sorted",
                    i + 1
                ));
            }
            // Below / above the argon K edge: evaluate μ/ρ on the matching side.
            let above = out.last().is_some_and(|&(pe, _)| pe == e);
            let e_mu = if above || e <= 1.0 {
                e
            } else {
                e * (1.0 - 1e-9)
            };
            let mu = air()
                .and_then(|a| a.mass_attenuation(e_mu))
                .map_err(|err| err.to_string())?;
            out.push((e, m / mu));
        }
        Ok(out)
    })
    .as_deref()
    .map_err(|e| SimError::DataTable(e.clone()))
}

/// Mass energy-absorption coefficient of dry air at `e_kev` (1–500 keV), cm²/g. At exactly the
/// argon K edge the value above the edge is returned.
pub fn air_mu_en_cm2_g(e_kev: f64) -> Result<f64> {
    let t = table()?;
    let (lo, hi) = (t[0].0, t[t.len() - 1].0);
    if !(e_kev.is_finite() && e_kev >= lo && e_kev <= hi) {
        return Err(SimError::OutOfRange(format!(
            "photon energy {e_kev} keV is outside the air energy-absorption table ({lo}–{hi} keV)"
        )));
    }
    let k = t
        .partition_point(|&(e, _)| e <= e_kev)
        .clamp(1, t.len() - 1);
    let ((e0, r0), (e1, r1)) = (t[k - 1], t[k]);
    let ratio = if e1 == e0 {
        r1
    } else {
        let w = (e_kev / e0).ln() / (e1 / e0).ln();
        (r0.ln() + w * (r1 / r0).ln()).exp()
    };
    Ok(ratio * air()?.mass_attenuation(e_kev)?)
}

/// Air kerma in µGy for fluences in photons/mm² at energies in keV.
pub fn air_kerma_ugy(energies_kev: &[f64], fluence_per_mm2: &[f64]) -> Result<f64> {
    let mut k = 0.0; // J/g, with fluence converted to cm⁻²
    for (&e, &f) in energies_kev.iter().zip(fluence_per_mm2) {
        if f > 0.0 {
            k += f * 100.0 * e * KEV_TO_J * air_mu_en_cm2_g(e)?;
        }
    }
    Ok(k * 1000.0 * 1e6) // J/g → Gy → µGy
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_points_are_reproduced_and_edge_respected() {
        assert!((air_mu_en_cm2_g(60.0).unwrap() / 0.03041 - 1.0).abs() < 1e-9);
        assert!((air_mu_en_cm2_g(3.2029).unwrap() / 146.0 - 1.0).abs() < 1e-9);
        assert!(air_mu_en_cm2_g(3.2028).unwrap() < 134.0);
        assert!(air_mu_en_cm2_g(0.5).is_err());
        assert!(air_mu_en_cm2_g(f64::NAN).is_err());
    }

    #[test]
    fn kerma_of_a_monoenergetic_fluence_is_the_closed_form() {
        // 1e6 photons/mm² at 60 keV: K = Φ E μen/ρ.
        let k = air_kerma_ugy(&[60.0], &[1e6]).unwrap();
        let expect = 1e6 * 100.0 * 60.0 * 1.602_176_634e-16 * air_mu_en_cm2_g(60.0).unwrap() * 1e9;
        assert!((k / expect - 1.0).abs() < 1e-12);
    }
}
