//! X-ray spectra: photon fluence per energy bin.
//!
//! A [`Spectrum`] is a list of bins, each an energy (keV) and a photon fluence in **photons per
//! mAs per mm² at 1 m from the focal spot** (scale by mAs and by (1 m / distance)² for a
//! detector elsewhere). Shipped tungsten spectra ([`Spectrum::tungsten`], 40–150 kVp, 1 keV
//! bins) come from SpekPy v2; filters attenuate each bin by `exp(−μ(E)·t)` with the material
//! data of [`tomograf_sim::material`], evaluated at the bin energy.

mod air_kerma;
mod file;
mod tungsten;

pub use air_kerma::{air_kerma_ugy, air_mu_en_cm2_g};
pub use file::FluenceUnit;
pub use tungsten::{ANODE_ANGLE_DEG, INHERENT_AL_MM, KVP_MAX, KVP_MIN};

use std::path::Path;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::material::{Material, by_name};

/// A slab of material in the beam, at the material's nominal density.
#[derive(Debug, Clone, PartialEq)]
pub struct Filter {
    /// The filter material (its nominal density is used).
    pub material: Material,
    /// Thickness along the beam, mm.
    pub thickness_mm: f64,
}

impl Filter {
    /// A filter of `material` (nominal density), `thickness_mm` ≥ 0 thick.
    pub fn new(material: Material, thickness_mm: f64) -> Result<Self> {
        if !(thickness_mm.is_finite() && thickness_mm >= 0.0) {
            return Err(SimError::InvalidSpectrum(format!(
                "filter thickness {thickness_mm} mm of '{}' must be a finite number ≥ 0",
                material.name()
            )));
        }
        Ok(Self {
            material,
            thickness_mm,
        })
    }

    /// A filter of a named material ([`tomograf_sim::material::by_name`]), e.g. `("cu", 0.2)`.
    pub fn named(name: &str, thickness_mm: f64) -> Result<Self> {
        Self::new(by_name(name)?, thickness_mm)
    }

    /// Transmission `exp(−μ(E)·t)` at `e_kev`.
    pub fn transmission(&self, e_kev: f64) -> Result<f64> {
        let mu = self.material.mu_per_mm(e_kev, self.material.density())?;
        Ok((-mu * self.thickness_mm).exp())
    }
}

/// Photon fluence per energy bin, photons per mAs per mm² at 1 m from the focal spot.
#[derive(Debug, Clone, PartialEq)]
pub struct Spectrum {
    energies_kev: Vec<f64>,
    fluence: Vec<f64>,
    kvp: f64,
}

impl Spectrum {
    /// Tungsten-anode tube spectrum at a whole `kvp` in 40..=150 (non-integer kV is rejected:
    /// the tables are per 1 kV), 1 keV bins centred at 1.5, 2.5, … kvp − 0.5 keV, with the
    /// tables' inherent filtration ([`INHERENT_AL_MM`] mm Al, anode angle [`ANODE_ANGLE_DEG`]°,
    /// no air) followed by `filtration` in order.
    pub fn tungsten(kvp: f64, filtration: &[Filter]) -> Result<Self> {
        let (energies_kev, fluence) = tungsten::table(kvp)?;
        let mut s = Self {
            energies_kev,
            fluence,
            kvp,
        };
        for f in filtration {
            s = s.filtered(f)?;
        }
        Ok(s)
    }

    /// A single line at `e_kev` (1–500 keV) with `fluence` > 0 photons/mAs/mm² at 1 m.
    /// Its [`Spectrum::kvp`] is `e_kev`.
    pub fn monoenergetic(e_kev: f64, fluence: f64) -> Result<Self> {
        Self::from_bins(vec![e_kev], vec![fluence])
    }

    /// A spectrum from bin energies (keV, strictly increasing, 1–500) and photons per
    /// mAs per mm² at 1 m (finite, ≥ 0, positive total). [`Spectrum::kvp`] is the highest
    /// bin energy.
    pub fn from_bins(energies_kev: Vec<f64>, fluence: Vec<f64>) -> Result<Self> {
        if energies_kev.len() != fluence.len() {
            return Err(SimError::InvalidSpectrum(format!(
                "{} energies but {} fluence values",
                energies_kev.len(),
                fluence.len()
            )));
        }
        for i in 0..energies_kev.len() {
            let prev = i.checked_sub(1).map(|p| energies_kev[p]);
            file::check_bin(energies_kev[i], fluence[i], prev)
                .map_err(|m| SimError::InvalidSpectrum(format!("spectrum bin {i}: {m}")))?;
        }
        file::check_total(&fluence, "spectrum")?;
        let kvp = *energies_kev.last().unwrap_or(&0.0);
        Ok(Self {
            energies_kev,
            fluence,
            kvp,
        })
    }

    /// Reads a user spectrum in tomograf's unit (photons per mAs per mm² at 1 m, per bin):
    /// [`Spectrum::from_file_in`] with [`FluenceUnit::PerMm2`].
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        Self::from_file_in(path, FluenceUnit::PerMm2)
    }

    /// Reads a user spectrum file as other tools write them: keV and fluence columns
    /// (comma, tab, semicolon or space separated; `#`/`%` comments; header lines; an
    /// optional leading bin-count row; zero rows outside 1–500 keV dropped), the fluence in
    /// `unit`. Errors name the file and line of a bad row, a negative or non-finite value,
    /// unsorted energies, or a bin count that does not match.
    pub fn from_file_in(path: impl AsRef<Path>, unit: FluenceUnit) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| {
            SimError::InvalidSpectrum(format!("cannot read spectrum file {}: {e}", path.display()))
        })?;
        let (energies_kev, values) = file::parse(&text, &path.display().to_string())?;
        let fluence = unit.to_per_mm2_per_bin(&energies_kev, &values);
        let kvp = *energies_kev.last().unwrap_or(&0.0);
        Ok(Self {
            energies_kev,
            fluence,
            kvp,
        })
    }

    /// This spectrum after `filter`: each bin times `exp(−μ(E)·t)` at its energy. Errors if
    /// the filter removes every photon (underflow), naming the filter.
    pub fn filtered(&self, filter: &Filter) -> Result<Self> {
        let mut fluence = Vec::with_capacity(self.fluence.len());
        for (&e, &f) in self.energies_kev.iter().zip(&self.fluence) {
            fluence.push(f * filter.transmission(e)?);
        }
        if fluence.iter().sum::<f64>() <= 0.0 {
            return Err(SimError::InvalidSpectrum(format!(
                "{} mm of '{}' stops every photon of the spectrum",
                filter.thickness_mm,
                filter.material.name()
            )));
        }
        Ok(Self {
            energies_kev: self.energies_kev.clone(),
            fluence,
            kvp: self.kvp,
        })
    }

    /// At most `n_bins` wider bins (`n_bins` = 0 is taken as 1). Rule: the energy range from
    /// the first to the last bin with non-zero fluence is cut into `n_bins` equal-width
    /// intervals; each source bin goes to the interval holding its energy; a new bin carries
    /// the summed photons at their fluence-weighted mean energy. So total photons and total
    /// energy (Σ fluence·E) are preserved exactly, in each new bin and overall. Intervals that
    /// receive no photons are dropped, so fewer than `n_bins` bins may result. A spectrum with
    /// at most `n_bins` bins is returned unchanged.
    pub fn rebinned(&self, n_bins: usize) -> Spectrum {
        let n = n_bins.max(1);
        if self.energies_kev.len() <= n {
            return self.clone();
        }
        let nz: Vec<usize> = (0..self.fluence.len())
            .filter(|&i| self.fluence[i] > 0.0)
            .collect();
        let (lo, hi) = match (nz.first(), nz.last()) {
            (Some(&a), Some(&b)) => (self.energies_kev[a], self.energies_kev[b]),
            _ => return self.clone(),
        };
        let width = (hi - lo) / n as f64;
        let (mut photons, mut energy) = (vec![0.0; n], vec![0.0; n]);
        for &i in &nz {
            let (e, f) = (self.energies_kev[i], self.fluence[i]);
            let k = if width > 0.0 {
                (((e - lo) / width) as usize).min(n - 1)
            } else {
                0
            };
            photons[k] += f;
            energy[k] += f * e;
        }
        let (mut energies_kev, mut fluence) = (Vec::new(), Vec::new());
        for k in 0..n {
            if photons[k] > 0.0 {
                energies_kev.push(energy[k] / photons[k]);
                fluence.push(photons[k]);
            }
        }
        Spectrum {
            energies_kev,
            fluence,
            kvp: self.kvp,
        }
    }

    /// Bin energies, keV, increasing.
    pub fn energies_kev(&self) -> &[f64] {
        &self.energies_kev
    }

    /// Photons per mAs per mm² at 1 m from the focal spot, per bin.
    pub fn fluence(&self) -> &[f64] {
        &self.fluence
    }

    /// Tube potential in kV for tube spectra; for monoenergetic, user or binned spectra made
    /// by [`Spectrum::from_bins`]/[`Spectrum::from_file`], the highest bin energy in keV.
    pub fn kvp(&self) -> f64 {
        self.kvp
    }

    /// Photons per mm² per bin for an exposure of `mas` mAs at `distance_mm` from the focal
    /// spot (inverse-square law from the 1 m reference): `fluence · mas · (1000 / d)²`.
    pub fn photons_per_mm2(&self, mas: f64, distance_mm: f64) -> Result<Vec<f64>> {
        if !(mas.is_finite() && mas >= 0.0) {
            return Err(SimError::InvalidSpectrum(format!(
                "exposure {mas} mAs must be a finite number ≥ 0"
            )));
        }
        if !(distance_mm.is_finite() && distance_mm > 0.0) {
            return Err(SimError::InvalidSpectrum(format!(
                "distance from the focal spot {distance_mm} mm must be positive"
            )));
        }
        let k = mas * (1000.0 / distance_mm).powi(2);
        Ok(self.fluence.iter().map(|f| f * k).collect())
    }

    /// Total photons per mAs per mm² at 1 m.
    pub fn total_fluence(&self) -> f64 {
        self.fluence.iter().sum()
    }

    /// Fluence-weighted mean photon energy, keV.
    pub fn mean_energy_kev(&self) -> f64 {
        let e: f64 = self
            .energies_kev
            .iter()
            .zip(&self.fluence)
            .map(|(e, f)| e * f)
            .sum();
        e / self.total_fluence()
    }

    /// Air kerma at 1 m per mAs, µGy (`Σ Φ E (μ_en/ρ)_air`, NIST air table).
    pub fn air_kerma_ugy_per_mas(&self) -> Result<f64> {
        air_kerma_ugy(&self.energies_kev, &self.fluence)
    }

    /// Thickness (mm, at the material's nominal density) that reduces the air kerma to
    /// `fraction` (0 < fraction < 1) of its unfiltered value; narrow-beam geometry.
    pub fn attenuating_thickness_mm(&self, material: &Material, fraction: f64) -> Result<f64> {
        if !(fraction > 0.0 && fraction < 1.0) {
            return Err(SimError::InvalidSpectrum(format!(
                "kerma fraction {fraction} must be in (0, 1)"
            )));
        }
        let mut w = Vec::with_capacity(self.fluence.len());
        let mut mu = Vec::with_capacity(self.fluence.len());
        for (&e, &f) in self.energies_kev.iter().zip(&self.fluence) {
            if f > 0.0 {
                w.push(f * e * air_mu_en_cm2_g(e)?);
                mu.push(material.mu_per_mm(e, material.density())?);
            }
        }
        let k0: f64 = w.iter().sum();
        let kerma = |t: f64| -> f64 {
            w.iter()
                .zip(&mu)
                .map(|(w, m)| w * (-m * t).exp())
                .sum::<f64>()
                / k0
        };
        // Every term decays at least at the smallest and at most at the largest μ, which
        // brackets the root: ln(1/f)/μ_max ≤ t ≤ ln(1/f)/μ_min.
        let target = (1.0 / fraction).ln();
        let (mut a, mut b) = (
            target / mu.iter().cloned().fold(f64::MIN, f64::max),
            target / mu.iter().cloned().fold(f64::MAX, f64::min),
        );
        for _ in 0..200 {
            let m = 0.5 * (a + b);
            if kerma(m) > fraction {
                a = m;
            } else {
                b = m;
            }
            if b - a <= 1e-12 * b {
                break;
            }
        }
        Ok(0.5 * (a + b))
    }

    /// First half-value layer in `material` (e.g. aluminium), mm: the thickness halving the
    /// air kerma.
    pub fn half_value_layer_mm(&self, material: &Material) -> Result<f64> {
        self.attenuating_thickness_mm(material, 0.5)
    }

    /// Thickness (mm) of `filter_material` to add so that the first HVL in `hvl_material`
    /// reaches `target_hvl_mm` — how standard beam qualities (e.g. IEC 61267 RQR) are set up.
    /// Errors if the beam is already harder than the target, or if 100 mm of filter do not
    /// get there.
    pub fn filtration_for_hvl_mm(
        &self,
        filter_material: &Material,
        hvl_material: &Material,
        target_hvl_mm: f64,
    ) -> Result<f64> {
        let hvl_with = |t: f64| -> Result<f64> {
            self.filtered(&Filter::new(filter_material.clone(), t)?)?
                .half_value_layer_mm(hvl_material)
        };
        let h0 = self.half_value_layer_mm(hvl_material)?;
        if !(target_hvl_mm.is_finite() && target_hvl_mm >= h0) {
            return Err(SimError::InvalidSpectrum(format!(
                "target HVL {target_hvl_mm} mm of '{}' is below the unfiltered beam's {h0:.4} mm",
                hvl_material.name()
            )));
        }
        let (mut a, mut b) = (0.0, 100.0);
        if hvl_with(b)? < target_hvl_mm {
            return Err(SimError::InvalidSpectrum(format!(
                "100 mm of '{}' do not harden the beam to an HVL of {target_hvl_mm} mm",
                filter_material.name()
            )));
        }
        // The HVL grows monotonically with added filtration: bisect.
        while b - a > 1e-7 * b.max(1e-3) {
            let m = 0.5 * (a + b);
            if hvl_with(m)? < target_hvl_mm {
                a = m;
            } else {
                b = m;
            }
        }
        Ok(0.5 * (a + b))
    }

    /// Second half-value layer, mm: from half to a quarter of the air kerma.
    pub fn second_half_value_layer_mm(&self, material: &Material) -> Result<f64> {
        Ok(self.attenuating_thickness_mm(material, 0.25)? - self.half_value_layer_mm(material)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tungsten_tables_load_for_every_kvp_and_reject_others() {
        for kvp in KVP_MIN..=KVP_MAX {
            let s = Spectrum::tungsten(f64::from(kvp), &[]).unwrap();
            assert_eq!(s.energies_kev().len(), kvp as usize - 1);
            assert!(s.total_fluence() > 0.0);
            assert!(s.mean_energy_kev() < f64::from(kvp));
        }
        for bad in [39.0, 151.0, 70.5, f64::NAN] {
            let e = Spectrum::tungsten(bad, &[]).unwrap_err().to_string();
            assert!(e.contains("whole kV from 40 to 150"), "{e}");
        }
    }

    #[test]
    fn filter_is_beer_lambert_per_bin() {
        let s = Spectrum::tungsten(80.0, &[]).unwrap();
        let cu = Filter::named("cu", 0.1).unwrap();
        let f = s.filtered(&cu).unwrap();
        let m = by_name("cu").unwrap();
        for i in 0..s.fluence().len() {
            let e = s.energies_kev()[i];
            let expect =
                s.fluence()[i] * (-m.mass_attenuation(e).unwrap() * m.density() / 10.0 * 0.1).exp();
            assert!((f.fluence()[i] - expect).abs() <= 1e-12 * expect.max(1e-300));
        }
        assert!(f.mean_energy_kev() > s.mean_energy_kev());
        assert!(Filter::named("cu", -1.0).is_err());
        let e = s
            .filtered(&Filter::named("w", 1000.0).unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("stops every photon"), "{e}");
    }

    #[test]
    fn photons_follow_mas_and_the_inverse_square_law() {
        let s = Spectrum::monoenergetic(60.0, 1000.0).unwrap();
        assert_eq!(s.photons_per_mm2(2.0, 1000.0).unwrap(), vec![2000.0]);
        assert_eq!(s.photons_per_mm2(1.0, 2000.0).unwrap(), vec![250.0]);
        assert!(s.photons_per_mm2(-1.0, 1000.0).is_err());
        assert!(s.photons_per_mm2(1.0, 0.0).is_err());
    }

    #[test]
    fn monoenergetic_hvl_is_ln2_over_mu() {
        let al = by_name("al").unwrap();
        for e in [20.0, 60.0, 100.0] {
            let s = Spectrum::monoenergetic(e, 1e6).unwrap();
            let hvl = s.half_value_layer_mm(&al).unwrap();
            let expect = std::f64::consts::LN_2 / al.mu_per_mm(e, al.density()).unwrap();
            assert!((hvl / expect - 1.0).abs() < 1e-9, "{e}: {hvl} vs {expect}");
            let hvl2 = s.second_half_value_layer_mm(&al).unwrap();
            assert!((hvl2 / expect - 1.0).abs() < 1e-9);
        }
        assert!(Spectrum::monoenergetic(0.5, 1.0).is_err());
        assert!(Spectrum::monoenergetic(60.0, 0.0).is_err());
    }

    #[test]
    fn rebinning_preserves_photons_and_energy() {
        let s = Spectrum::tungsten(120.0, &[Filter::named("cu", 0.2).unwrap()]).unwrap();
        let e_tot: f64 = s
            .energies_kev()
            .iter()
            .zip(s.fluence())
            .map(|(e, f)| e * f)
            .sum();
        for n in [1, 5, 10, 20, 50, 100, 500] {
            let r = s.rebinned(n);
            assert!(r.fluence().len() <= n.max(1));
            let re: f64 = r
                .energies_kev()
                .iter()
                .zip(r.fluence())
                .map(|(e, f)| e * f)
                .sum();
            assert!(
                (r.total_fluence() / s.total_fluence() - 1.0).abs() < 1e-12,
                "{n}"
            );
            assert!((re / e_tot - 1.0).abs() < 1e-12, "{n}");
            assert!(r.energies_kev().windows(2).all(|w| w[0] < w[1]));
        }
        assert_eq!(s.rebinned(1).energies_kev().len(), 1);
        assert!((s.rebinned(1).energies_kev()[0] - s.mean_energy_kev()).abs() < 1e-9);
        assert_eq!(s.rebinned(0), s.rebinned(1));
    }
}
