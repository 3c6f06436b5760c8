//! Materials: photon attenuation of elements and mixtures, 1–500 keV.
//!
//! A [`Material`] is a named mixture of elements given as (Z, mass fraction) with a nominal
//! density in g/cm³. Its mass attenuation follows the mixture rule
//! `μ/ρ = Σ wᵢ (μ/ρ)ᵢ` over the per-element tables in [`element`](mod@element) (Elam, Ravel & Sieber 2002,
//! via xraydb; log–log interpolation that never crosses an absorption edge). Named materials
//! (ICRU-44 tissues, NIST compounds, filters, scintillators) come from [`by_name`].
//!
//! Units: energies in keV, mass attenuation in cm²/g, density in g/cm³, linear attenuation in
//! mm⁻¹ (`μ[mm⁻¹] = μ/ρ[cm²/g] · ρ[g/cm³] / 10`).

pub mod element;
mod library;

pub use element::{Edge, Element, Interactions, element, element_by_name, elements};
pub use library::{IODINE_CONTRAST_MG_PER_ML, NAMES, by_name, iodine_contrast};

use crate::error::{Result, SimError};

/// How far a composition's mass fractions may sum away from 1 before it is rejected; within
/// this they are renormalised (published compositions are rounded to 3–6 digits).
pub const FRACTION_SUM_TOLERANCE: f64 = 1e-3;

/// A named mixture of elements with a nominal density.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    name: String,
    /// (Z, mass fraction); fractions sum to 1, one entry per element, sorted by Z.
    composition: Vec<(u8, f64)>,
    density_g_cm3: f64,
}

impl Material {
    /// A material from (Z, mass fraction) pairs and a nominal density (g/cm³).
    ///
    /// Errors on an empty name, Z outside 1..=92, a negative or non-finite fraction, fractions
    /// that do not sum to 1 within [`FRACTION_SUM_TOLERANCE`], or a density that is not a
    /// positive finite number. Repeated elements are merged; fractions are renormalised.
    pub fn new(name: &str, composition: &[(u8, f64)], density_g_cm3: f64) -> Result<Self> {
        let bad = |msg: String| SimError::InvalidMaterial(format!("'{name}': {msg}"));
        if name.trim().is_empty() {
            return Err(SimError::InvalidMaterial("material name is empty".into()));
        }
        check_density(name, density_g_cm3)?;
        let mut merged: Vec<(u8, f64)> = Vec::new();
        for &(z, w) in composition {
            element(z).map_err(|e| bad(e.to_string()))?;
            if !(w.is_finite() && w >= 0.0) {
                return Err(bad(format!(
                    "mass fraction {w} of Z={z} must be a finite number ≥ 0"
                )));
            }
            match merged.iter_mut().find(|(zz, _)| *zz == z) {
                Some(entry) => entry.1 += w,
                None => merged.push((z, w)),
            }
        }
        merged.retain(|&(_, w)| w > 0.0);
        let sum: f64 = merged.iter().map(|&(_, w)| w).sum();
        if merged.is_empty() || (sum - 1.0).abs() > FRACTION_SUM_TOLERANCE {
            return Err(bad(format!(
                "mass fractions sum to {sum}, expected 1 (±{FRACTION_SUM_TOLERANCE})"
            )));
        }
        merged.iter_mut().for_each(|(_, w)| *w /= sum);
        merged.sort_by_key(|&(z, _)| z);
        Ok(Self {
            name: name.trim().to_string(),
            composition: merged,
            density_g_cm3,
        })
    }

    /// A pure element at its natural density (see [`Element::density_g_cm3`]), named by its
    /// English name (e.g. "tungsten").
    pub fn element(z: u8) -> Result<Self> {
        let el = element(z)?;
        Self::new(&el.name, &[(z, 1.0)], el.density_g_cm3)
    }

    /// The same composition at another nominal density (g/cm³).
    pub fn with_density(mut self, density_g_cm3: f64) -> Result<Self> {
        check_density(&self.name, density_g_cm3)?;
        self.density_g_cm3 = density_g_cm3;
        Ok(self)
    }

    /// The same material under another name.
    pub fn renamed(mut self, name: &str) -> Result<Self> {
        if name.trim().is_empty() {
            return Err(SimError::InvalidMaterial("material name is empty".into()));
        }
        self.name = name.trim().to_string();
        Ok(self)
    }

    /// The material's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Nominal density, g/cm³.
    pub fn density(&self) -> f64 {
        self.density_g_cm3
    }

    /// (Z, mass fraction) pairs, sorted by Z, fractions summing to 1.
    pub fn composition(&self) -> &[(u8, f64)] {
        &self.composition
    }

    /// Mass attenuation split by interaction at `e_kev` (1–500 keV), cm²/g.
    pub fn interactions(&self, e_kev: f64) -> Result<Interactions> {
        element::check_energy(e_kev, &self.name)?;
        let mut acc = Interactions::default();
        for &(z, w) in &self.composition {
            acc = acc.plus(&element(z)?.interactions(e_kev)?.scaled(w));
        }
        Ok(acc)
    }

    /// Total mass attenuation coefficient μ/ρ (with coherent) at `e_kev`, cm²/g.
    pub fn mass_attenuation(&self, e_kev: f64) -> Result<f64> {
        Ok(self.interactions(e_kev)?.total())
    }

    /// Linear attenuation coefficient in mm⁻¹ at `e_kev` for a density in g/cm³ (pass
    /// [`Material::density`] for the nominal one).
    pub fn mu_per_mm(&self, e_kev: f64, density_g_cm3: f64) -> Result<f64> {
        if !(density_g_cm3.is_finite() && density_g_cm3 >= 0.0) {
            return Err(SimError::InvalidMaterial(format!(
                "'{}': density {density_g_cm3} g/cm³ must be a finite number ≥ 0",
                self.name
            )));
        }
        Ok(self.mass_attenuation(e_kev)? * density_g_cm3 / 10.0)
    }

    /// Absorption edges (keV) of the constituent elements inside 1–500 keV, sorted. Energy
    /// grids that straddle these resolve the jump in attenuation.
    pub fn edges_kev(&self) -> Result<Vec<f64>> {
        let mut out = Vec::new();
        for &(z, _) in &self.composition {
            out.extend(element(z)?.edges().iter().map(|e| e.energy_kev));
        }
        out.sort_by(f64::total_cmp);
        out.dedup();
        Ok(out)
    }
}

fn check_density(name: &str, d: f64) -> Result<()> {
    if d.is_finite() && d > 0.0 {
        Ok(())
    } else {
        Err(SimError::InvalidMaterial(format!(
            "'{name}': density {d} g/cm³ must be a positive finite number"
        )))
    }
}

/// A mixture of materials by mass fraction: the result's composition is
/// `Σ fraction · composition(part)` and its density is the given one (g/cm³). Fractions must
/// be ≥ 0 and sum to 1 within [`FRACTION_SUM_TOLERANCE`].
pub fn mixture(name: &str, parts: &[(Material, f64)], density_g_cm3: f64) -> Result<Material> {
    if parts.is_empty() {
        return Err(SimError::InvalidMaterial(format!(
            "'{name}': a mixture needs at least one part"
        )));
    }
    let mut comp = Vec::new();
    for (m, f) in parts {
        if !(f.is_finite() && *f >= 0.0) {
            return Err(SimError::InvalidMaterial(format!(
                "'{name}': mass fraction {f} of '{}' must be a finite number ≥ 0",
                m.name()
            )));
        }
        comp.extend(m.composition().iter().map(|&(z, w)| (z, w * f)));
    }
    Material::new(name, &comp, density_g_cm3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mixture_rule_is_the_weighted_sum() {
        let h = Material::element(1).unwrap();
        let o = Material::element(8).unwrap();
        let m = mixture("hydrox", &[(h.clone(), 0.25), (o.clone(), 0.75)], 1.0).unwrap();
        for e in [5.0, 30.0, 120.0] {
            let expect =
                0.25 * h.mass_attenuation(e).unwrap() + 0.75 * o.mass_attenuation(e).unwrap();
            assert!((m.mass_attenuation(e).unwrap() / expect - 1.0).abs() < 1e-12);
        }
        let mu = m.mu_per_mm(60.0, 2.0).unwrap();
        assert!((mu - m.mass_attenuation(60.0).unwrap() * 0.2).abs() < 1e-15);
    }

    #[test]
    fn bad_definitions_are_errors_naming_the_problem() {
        let e = Material::new("x", &[(1, 0.5), (8, 0.4)], 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sum to 0.9"), "{e}");
        let e = Material::new("x", &[(1, -0.1), (8, 1.1)], 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("-0.1"), "{e}");
        let e = Material::new("x", &[(95, 1.0)], 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("95"), "{e}");
        let e = Material::new("x", &[(1, 1.0)], 0.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("density"), "{e}");
        let e = Material::new("x", &[(1, f64::NAN)], 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("NaN"), "{e}");
        assert!(Material::new(" ", &[(1, 1.0)], 1.0).is_err());
        assert!(mixture("m", &[], 1.0).is_err());
        let w = by_name("water").unwrap();
        assert!(w.mu_per_mm(60.0, -1.0).is_err());
        assert!(
            w.mass_attenuation(0.9)
                .unwrap_err()
                .to_string()
                .contains("water")
        );
    }

    #[test]
    fn repeated_elements_merge_and_fractions_renormalise() {
        let m = Material::new("x", &[(8, 0.4), (1, 0.2), (8, 0.4004)], 1.0).unwrap();
        assert_eq!(m.composition().len(), 2);
        assert_eq!(m.composition()[0].0, 1);
        let sum: f64 = m.composition().iter().map(|c| c.1).sum();
        assert!((sum - 1.0).abs() < 1e-15);
    }
}
