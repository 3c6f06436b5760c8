//! HU → tissue: which material each CT voxel is, and how dense (a Schneider-style model).
//!
//! CT numbers are split into HU intervals, each assigned one material — an ICRU tissue or a
//! mixture of two by mass (Schneider, Bortfeld & Schlegel, Phys. Med. Biol. 45 (2000) 459:
//! piecewise tissue compositions over HU, with the bone range as soft-tissue/cortical-bone
//! mixtures). The density follows from the CT number itself: the voxel's linear attenuation
//! at the scanner's effective energy `E_cal` must be the one its HU says,
//!
//! `ρ = μ_water(E_cal) · (1 + HU/1000) / (μ/ρ)_material(E_cal)`,
//!
//! so a monochromatic render at `E_cal` reproduces the projector's HU → mu conversion
//! ([`crate::attenuation`]) whatever the materials, and the materials only change what
//! happens at other energies (beam hardening, detector response). HU ≤ −1000 is vacuum
//! (density 0, as the projector clamps mu at 0). Units: HU, keV, g/cm³.
//!
//! Materials whose interval no voxel falls in are dropped before tracing, so they cost
//! nothing.
//!
//! **Partial volume at boundaries** (`blend_hu`, off by default). A voxel whose CT number
//! lies near the bound between two intervals is most likely part one tissue, part the
//! other. With `blend_hu = W`, CT numbers within ±W/2 of each inner bound are given the
//! 50/50 mass mixture of the two neighbouring materials (one more material per bound: the
//! Schneider model's 7 become 13, within the 16 a composition holds), with the density
//! still calibrated from the HU, so a render at `E_cal` is unchanged and only the energy
//! dependence near boundaries moves between the two tissues'. One mid-mixture per bound
//! rather than fractions varying with HU: each distinct mixture is a material, and a
//! voxel holds one (the tracer's packed format); Schneider's own bone range already steps
//! soft tissue → bone in the same way (bone-30, bone-60).

use crate::attenuation::mu_water_per_mm;
use crate::composition::{Composition, MAX_MATERIALS};
use crate::error::{Result, SimError};
use crate::material::{self, Material};
use crate::volume::Volume;
use serde::{Deserialize, Serialize};

/// One HU interval: every CT number below `below_hu` (and at or above the previous
/// interval's bound) is `material`, or the mass mixture `mix` when given.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct TissueBin {
    /// Upper bound, HU (exclusive); the last bin's is ignored (it takes everything above).
    /// JSON has no infinity: an unbounded last bin is written `null` and read back as +∞.
    #[serde(deserialize_with = "bound_or_infinity")]
    pub below_hu: f64,
    /// A material name ([`material::by_name`]), or the name given to `mix`.
    pub material: String,
    /// Mass fractions of named materials making up this bin's material (sum 1).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mix: Vec<(String, f64)>,
}

/// A piecewise HU → material model with its calibration energy.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct TissueModel {
    /// Effective energy of the CT scan the HU come from (keV): where densities are
    /// calibrated.
    pub calibration_kev: f64,
    /// Intervals in increasing `below_hu`.
    pub bins: Vec<TissueBin>,
    /// Width (HU) of the band about each inner bound whose voxels are the 50/50 mass
    /// mixture of the two neighbouring materials (partial volume); 0 = none.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub blend_hu: f64,
}

/// A bound in HU, `null` (how JSON writes +∞) read as +∞.
fn bound_or_infinity<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn bin(below_hu: f64, material: &str) -> TissueBin {
    TissueBin {
        below_hu,
        material: material.into(),
        mix: vec![],
    }
}

fn bone_mix(below_hu: f64, name: &str, bone: f64) -> TissueBin {
    TissueBin {
        below_hu,
        material: name.into(),
        mix: vec![
            ("soft-tissue".into(), 1.0 - bone),
            ("cortical-bone".into(), bone),
        ],
    }
}

impl TissueModel {
    /// The default chest model at a 70 keV calibration energy (a typical effective energy
    /// of a 120 kVp CT scan): air < −950 ≤ lung < −120 ≤ adipose < −20 ≤ soft tissue < 100
    /// ≤ bone 30 % < 400 ≤ bone 60 % < 900 ≤ cortical bone (bone n %: soft tissue and
    /// cortical bone mixed n % bone by mass).
    pub fn schneider() -> Self {
        Self {
            calibration_kev: 70.0,
            blend_hu: 0.0,
            bins: vec![
                bin(-950.0, "air"),
                bin(-120.0, "lung"),
                bin(-20.0, "adipose"),
                bin(100.0, "soft-tissue"),
                bone_mix(400.0, "bone-30", 0.3),
                bone_mix(900.0, "bone-60", 0.6),
                bin(f64::INFINITY, "cortical-bone"),
            ],
        }
    }

    /// Five tissues (air, lung, adipose, soft tissue, cortical bone), calibrated at 70 keV.
    pub fn five_tissue() -> Self {
        Self {
            calibration_kev: 70.0,
            blend_hu: 0.0,
            bins: vec![
                bin(-950.0, "air"),
                bin(-120.0, "lung"),
                bin(-20.0, "adipose"),
                bin(150.0, "soft-tissue"),
                bin(f64::INFINITY, "cortical-bone"),
            ],
        }
    }

    /// Everything is water of density `1 + HU/1000` (at `calibration_kev` exactly the
    /// projector's own HU → mu): the ideal-DRR assumption, for comparisons.
    pub fn water(calibration_kev: f64) -> Self {
        Self {
            calibration_kev,
            bins: vec![bin(f64::INFINITY, "water")],
            blend_hu: 0.0,
        }
    }

    /// The materials of the intervals, resolved (with `blend_hu`, the boundary mixtures
    /// between their neighbours: see [`TissueModel::intervals`]).
    pub fn materials(&self) -> Result<Vec<Material>> {
        Ok(self.intervals()?.1)
    }

    /// The upper bounds (HU, the last +∞) and materials of the intervals voxels are
    /// classified into: the bins, or with `blend_hu = W` the bins narrowed by W/2 at each
    /// inner bound with the 50/50 mass mixture of the two neighbours between them (named
    /// `A+B`).
    pub fn intervals(&self) -> Result<(Vec<f64>, Vec<Material>)> {
        self.validate()?;
        let base = self
            .bins
            .iter()
            .map(|b| {
                if b.mix.is_empty() {
                    return material::by_name(&b.material);
                }
                let parts = b
                    .mix
                    .iter()
                    .map(|(n, f)| Ok((material::by_name(n)?, *f)))
                    .collect::<Result<Vec<_>>>()?;
                // The nominal density is irrelevant here (densities come from HU).
                material::mixture(&b.material, &parts, 1.0)
            })
            .collect::<Result<Vec<Material>>>()?;
        let bounds: Vec<f64> = self.bins.iter().map(|b| b.below_hu).collect();
        if self.blend_hu == 0.0 || base.len() == 1 {
            return Ok((bounds, base));
        }
        let half = self.blend_hu / 2.0;
        let (mut out_bounds, mut out) = (Vec::new(), Vec::new());
        for (i, m) in base.iter().enumerate() {
            if i + 1 == base.len() {
                out_bounds.push(f64::INFINITY);
                out.push(m.clone());
                break;
            }
            let next = &base[i + 1];
            out_bounds.push(bounds[i] - half);
            out.push(m.clone());
            out_bounds.push(bounds[i] + half);
            out.push(material::mixture(
                &format!("{}+{}", m.name(), next.name()),
                &[(m.clone(), 0.5), (next.clone(), 0.5)],
                1.0,
            )?);
        }
        Ok((out_bounds, out))
    }

    /// Checks the bins (1..=16, increasing bounds, finite calibration energy in the
    /// water table's range).
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(SimError::OutOfRange(format!("tissue model: {m}")));
        if self.bins.is_empty() || self.bins.len() > MAX_MATERIALS {
            return bad(format!(
                "{} HU intervals; give 1 to {MAX_MATERIALS}",
                self.bins.len()
            ));
        }
        if let Some(w) = self
            .bins
            .windows(2)
            .find(|w| w[0].below_hu.partial_cmp(&w[1].below_hu) != Some(std::cmp::Ordering::Less))
        {
            return bad(format!(
                "interval bounds must increase, but '{}' ends at {} HU and '{}' at {} HU",
                w[0].material, w[0].below_hu, w[1].material, w[1].below_hu
            ));
        }
        let blend = self.blend_hu;
        if !(blend.is_finite() && blend >= 0.0) {
            return bad(format!("blend_hu = {blend}; give a width ≥ 0 HU"));
        }
        if blend > 0.0 {
            let n = 2 * self.bins.len() - 1;
            if n > MAX_MATERIALS {
                return bad(format!(
                    "blend_hu needs {n} materials for {} intervals; at most {MAX_MATERIALS} \
                     (use fewer intervals)",
                    self.bins.len()
                ));
            }
            // Each finite interval must be wider than the band taken from it.
            for i in 1..self.bins.len() - 1 {
                let width = self.bins[i].below_hu - self.bins[i - 1].below_hu;
                if width <= blend {
                    return bad(format!(
                        "blend_hu = {blend} HU is not narrower than '{}' ({width} HU wide)",
                        self.bins[i].material
                    ));
                }
            }
        }
        mu_water_per_mm(self.calibration_kev).map(|_| ())
    }

    /// The composition of a CT volume (HU): per voxel its interval's material and the
    /// calibrated density. Only materials that occur are kept (in model order).
    pub fn composition(&self, hu: &Volume) -> Result<(Composition, Vec<Material>)> {
        let (bounds, materials) = self.intervals()?;
        let e = self.calibration_kev;
        let mu_w = mu_water_per_mm(e)?;
        // ρ per (1 + HU/1000), per interval: 10·μ_w[mm⁻¹] / (μ/ρ)[cm²/g].
        let scale = materials
            .iter()
            .map(|m| Ok(10.0 * mu_w / m.mass_attenuation(e)?))
            .collect::<Result<Vec<f64>>>()?;
        let which = |h: f32| {
            let h = f64::from(h);
            bounds[..bounds.len() - 1].partition_point(|&b| b <= h)
        };
        // Which bins occur at all (with a non-zero density).
        let mut used = vec![false; materials.len()];
        for &h in hu.data() {
            if h > -1000.0 {
                used[which(h)] = true;
            }
        }
        if !used.iter().any(|&u| u) {
            used[0] = true; // an empty scene still has one (unused) material
        }
        let index: Vec<usize> = used
            .iter()
            .scan(0, |n, &u| {
                let i = *n;
                *n += usize::from(u);
                Some(i)
            })
            .collect();
        let kept: Vec<Material> = materials
            .into_iter()
            .zip(&used)
            .filter_map(|(m, &u)| u.then_some(m))
            .collect();
        let names = kept.iter().map(|m| m.name().to_string()).collect();
        let comp = Composition::classify(hu, names, |h| {
            let b = which(h);
            let rho = (scale[b] * (1.0 + f64::from(h) / 1000.0)).max(0.0);
            (rho as f32, index[b])
        })?;
        Ok((comp, kept))
    }
}
