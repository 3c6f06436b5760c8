//! The AAPM TG-195 cases as scenes for the energy-imparted tally
//! ([`tomograf_physics::scatter::energy_imparted`]), each run and set beside the four codes' results.
//!
//! Geometry follows the open-source XRayMClib build of each case (the CSV headers in
//! `eval/data/tg195/`), in mm, world filled with TG-195 dry air:
//!
//! * **Case 1** — point source, beam along +z collimated to a 10 mm disc at 1000 mm; an
//!   aluminium filter (a 40 × 40 mm slab standing in for the r = 20 mm disc; the beam is
//!   0.5 mm wide there) with its upstream face at 100 mm; air kerma at 1000 mm from the
//!   photons crossing a 5 mm-radius disc, Σ w·E·(μen/ρ)_air/(A·|cos θ|), with TG-195's own
//!   air μen/ρ table (part of the case's definition; with the NIST-based table of
//!   `tomograf_physics::spectrum` as it was before this validation, 4 % low at 25 keV, the 100 kVp
//!   ratios were +0.8 and +1.2 % off: docs/validation.md). Compared as the HVL and QVL
//!   ratios (unit-free) and as absolute kerma in the transcription's convention
//!   (Σ E[keV]·μen/ρ[cm²/g]·Φ[cm⁻²] / 100).
//! * **Case 2** — a 390 × 390 × 200 mm ICRU soft-tissue box at 1550–1750 mm, field
//!   390 × 390 mm at 1800 mm; tomosynthesis: source moved to y = −1800·tan 15°. Whole box
//!   and nine 30 mm VOIs. Voxels of 5 mm hold the box exactly (its faces lie on voxel
//!   faces); the VOIs are scored analytically.
//! * **Case 3** — mammography and breast tomosynthesis ([`super::tg195_case3`]).
//! * **Case 4.2** — a PMMA cylinder of radius 160 mm along z (1000 mm long: "very long";
//!   scatter from beyond ±500 mm back into the ±50 mm scoring cylinders is negligible),
//!   source 600 mm from the axis, fan 320 mm wide and 10 or 80 mm thick at the axis.
//!   Scoring cylinders r = 5 mm, 100 mm long, on the axis and 150 mm from it. The phantom
//!   is symmetric under rotation, so instead of turning the source, one run scores the 36
//!   peripheral cylinders at the 36 angles at once; it is also mirror-symmetric about the
//!   source's plane, so θ and 360° − θ are averaged. The cylinder is voxelised on a
//!   2 × 2 × 20 mm grid with partial-volume densities (4 × 4 sub-samples per voxel), so its
//!   surface is right on average; the scoring cylinders are exact and scored with the
//!   track-length estimator.
//!
//! Physics as [`tomograf_physics::scatter::energy_imparted`] states (no electron transport, no
//! fluorescence, Compton with S, Rayleigh with F², Elam/xraydb cross sections).

use super::reference::{self, CODES, Reference};
use glam::{DMat3, DVec3};
use std::sync::Arc;
use tomograf_physics::scatter::energy_imparted::{
    BeamSpectrum, EnergyImparted, FluenceDisc, RegionEstimator, TallySettings,
    simulate_with_fluence,
};
use tomograf_physics::scatter::field::FieldSource;
use tomograf_physics::scatter::region::Region;
use tomograf_physics::scatter::transport::Medium;
use tomograf_sim::composition::Composition;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::material::Material;
use tomograf_sim::volume::Volume;

/// One of our figures beside the codes' results for the same quantity.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// The case and its variant, e.g. `"2 radiography 56.4 keV"`.
    pub case: String,
    /// The quantity, e.g. `"VOI 3"`.
    pub quantity: String,
    /// Our value, in the reference's unit.
    pub ours: f64,
    /// Our standard error, same unit.
    pub ours_se: f64,
    /// The four codes' results.
    pub reference: Reference,
}

impl Comparison {
    /// Our deviation from the codes' mean, %.
    pub fn deviation_percent(&self) -> f64 {
        (self.ours / self.reference.mean() - 1.0) * 100.0
    }

    /// Our deviation from the codes' mean in our standard errors.
    pub fn deviation_se(&self) -> f64 {
        (self.ours - self.reference.mean()) / self.ours_se
    }

    /// Whether our value lies within `tolerance_percent` of the codes' mean or inside
    /// their range.
    pub fn agrees(&self, tolerance_percent: f64) -> bool {
        let (lo, hi) = self.reference.range();
        self.deviation_percent().abs() <= tolerance_percent || (lo..=hi).contains(&self.ours)
    }
}

/// A TG-195 beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Beam {
    /// Monoenergetic, keV.
    Mono(f64),
    /// A TG-195 spectrum by kVp: 30 (Mo/Mo RQR-M3), 100 (W/Al RQR-8), 120 (W/Al RQR-9).
    Kvp(u32),
}

impl Beam {
    /// The label the reference tables use ("56.4 keV", "120 kVp").
    pub fn label(&self) -> String {
        match self {
            Beam::Mono(e) => format!("{e} keV"),
            Beam::Kvp(k) => format!("{k} kVp"),
        }
    }

    pub(super) fn spectrum(&self) -> Result<BeamSpectrum> {
        match *self {
            Beam::Mono(e) => BeamSpectrum::monoenergetic(e),
            Beam::Kvp(k) => {
                let name = match k {
                    30 => "30kVp_MoMo_RQR-M3",
                    100 => "100kVp_WAl_RQR-8",
                    120 => "120kVp_WAl_RQR-9",
                    _ => {
                        return Err(SimError::OutOfRange(format!(
                            "TG-195 has spectra for 30, 100 and 120 kVp, not {k}"
                        )));
                    }
                };
                let (e, w) = reference::spectrum(name)?;
                BeamSpectrum::new(e, &w)
            }
        }
    }
}

/// TG-195 dry air (0.001205 g/cm³).
pub fn air() -> Result<Material> {
    Material::new(
        "tg195-air",
        &[(6, 0.000124), (7, 0.755268), (8, 0.231781), (18, 0.012827)],
        0.001205,
    )
}

/// TG-195 (ICRU) soft tissue, 1.03 g/cm³.
pub fn soft_tissue() -> Result<Material> {
    Material::new(
        "tg195-soft-tissue",
        &[
            (1, 0.105),
            (6, 0.256),
            (7, 0.027),
            (8, 0.602),
            (11, 0.001),
            (15, 0.002),
            (16, 0.003),
            (17, 0.002),
            (19, 0.002),
        ],
        1.03,
    )
}

/// TG-195 PMMA, 1.19 g/cm³.
pub fn pmma() -> Result<Material> {
    Material::new(
        "tg195-pmma",
        &[(1, 0.080541), (6, 0.599846), (8, 0.319613)],
        1.19,
    )
}

/// A grid from `min` (outer corner, mm) with `dims` voxels of `spacing`, filled by
/// `fill(voxel centre)` → (density g/cm³, material index), as a medium of `materials`.
pub(super) fn medium(
    min: DVec3,
    dims: [usize; 3],
    spacing: DVec3,
    materials: Vec<Material>,
    e_max_kev: f64,
    fill: impl Fn(DVec3) -> (f32, usize) + Sync,
) -> Result<Medium> {
    use rayon::prelude::*;
    let n = dims[0] * dims[1] * dims[2];
    // The case's peak: this medium's density and label grids (8 bytes a voxel) and the
    // composition and transport medium made from them, `25 MiB + 12.5 B` a voxel, fitted
    // to `/usr/bin/time -v` peaks of `validate tg195 --cases 2 | 3 | 4.2` (docs/reliability.md,
    // "Memory budget"); checked before any of it is allocated.
    tomograf_sim::memory::check(
        25 * (1 << 20) + n as u128 * 25 / 2,
        &format!(
            "the TG-195 case's voxel medium of {}×{}×{} voxels",
            dims[0], dims[1], dims[2]
        ),
    )?;
    let (rho, label): (Vec<f32>, Vec<f32>) = (0..n)
        .into_par_iter()
        .map(|v| {
            let (i, j, k) = (
                v % dims[0],
                (v / dims[0]) % dims[1],
                v / (dims[0] * dims[1]),
            );
            let c = min + (DVec3::new(i as f64, j as f64, k as f64) + 0.5) * spacing;
            let (r, m) = fill(c);
            (r, m as f32)
        })
        .unzip();
    let grid = |data| Volume::new(dims, spacing, min + spacing * 0.5, DMat3::IDENTITY, data);
    let names = materials.iter().map(|m| m.name().to_string()).collect();
    let composition = Composition::from_labels(&grid(label)?, &grid(rho)?, names)?;
    Medium::new(&composition, &materials, e_max_kev)
}

pub(super) fn run(
    medium: &Medium,
    source: &FieldSource,
    beam: &BeamSpectrum,
    regions: &[Region],
    discs: &[FluenceDisc],
    (estimator, photons): (RegionEstimator, u64),
    seed: u64,
) -> Result<EnergyImparted> {
    simulate_with_fluence(
        medium,
        source,
        beam,
        regions,
        discs,
        TallySettings {
            photons,
            max_collisions: 1000,
            voxel_map: false,
            regions: estimator,
        },
        seed,
    )
}

/// Case 1: air kerma at 1000 mm without a filter and behind the HVL and QVL aluminium
/// filters; `photons` per run (three runs).
pub fn case1(beam: Beam, photons: u64, seed: u64) -> Result<Vec<Comparison>> {
    let label = beam.label();
    let (hvl, qvl) = match beam {
        Beam::Mono(30.0) => (2.273, 4.546),
        Beam::Mono(100.0) => (15.11, 30.22),
        Beam::Kvp(30) => (0.3431, 0.7663),
        Beam::Kvp(100) => (3.950, 9.840),
        _ => {
            return Err(SimError::OutOfRange(format!(
                "TG-195 case 1 has 30 keV, 100 keV, 30 kVp and 100 kVp beams, not {label}"
            )));
        }
    };
    let spectrum = beam.spectrum()?;
    let source = FieldSource::disc(DVec3::ZERO, DVec3::Z * 1000.0, DVec3::Z, 5.0)?;
    let response: Arc<dyn Fn(f64) -> f64 + Send + Sync> =
        Arc::new(|e| e * reference::air_mu_en(e).unwrap_or(f64::NAN));
    let disc = FluenceDisc {
        name: "kerma".into(),
        centre: DVec3::Z * 1000.0,
        normal: DVec3::Z,
        radius: 5.0,
        response,
    };
    let mut kerma = Vec::new();
    for (k, t) in [0.0f64, hvl, qvl].into_iter().enumerate() {
        // z voxels of t/n (≤ 2 mm) starting so that the filter's faces are voxel faces.
        let dz = if t > 0.0 { t / (t / 2.0).ceil() } else { 2.0 };
        let z0 = 100.0 - (100.0 / dz).floor() * dz;
        let nz = ((1010.0 - z0) / dz).ceil() as usize;
        let m = medium(
            DVec3::new(-20.0, -20.0, z0),
            [1, 1, nz],
            DVec3::new(40.0, 40.0, dz),
            vec![air()?, Material::element(13)?],
            spectrum.max_kev() + 1.0,
            |c| {
                if c.z > 100.0 && c.z < 100.0 + t {
                    (2.699, 1)
                } else {
                    (0.001205, 0)
                }
            },
        )?;
        let r = run(
            &m,
            &source,
            &spectrum,
            &[],
            std::slice::from_ref(&disc),
            (RegionEstimator::Collision, photons),
            seed + k as u64,
        )?;
        let e = r.discs[0].1;
        if !e.ev_per_photon.is_finite() {
            return Err(SimError::OutOfRange(
                "case 1: air μen/ρ is not tabulated at a scored energy".into(),
            ));
        }
        kerma.push((e.ev_per_photon / 100.0, e.standard_error / 100.0));
    }
    let refs = reference::case1()?;
    let find = |filter: &str| {
        refs.iter()
            .find(|r| r.key[0] == filter && r.key[1] == label)
            .cloned()
            .ok_or_else(|| SimError::OutOfRange(format!("no case 1 reference for {label}")))
    };
    let case = format!("1 {label}");
    let mut out = Vec::new();
    let none = find("NoneFilter")?;
    for (k, name) in ["NoneFilter", "HVLFilter", "QVLFilter"]
        .into_iter()
        .enumerate()
    {
        out.push(Comparison {
            case: case.clone(),
            quantity: format!("air kerma, {name}"),
            ours: kerma[k].0,
            ours_se: kerma[k].1,
            reference: find(name)?,
        });
    }
    for (k, name) in [(1, "HVL/none"), (2, "QVL/none")] {
        let filtered = find(if k == 1 { "HVLFilter" } else { "QVLFilter" })?;
        let ratio = kerma[k].0 / kerma[0].0;
        let se =
            ratio * ((kerma[k].1 / kerma[k].0).powi(2) + (kerma[0].1 / kerma[0].0).powi(2)).sqrt();
        let mut codes = [None; 4];
        for (c, slot) in codes.iter_mut().enumerate() {
            *slot = filtered.codes[c].zip(none.codes[c]).map(|(f, n)| f / n);
        }
        out.push(Comparison {
            case: case.clone(),
            quantity: format!("ratio {name}"),
            ours: ratio,
            ours_se: se,
            reference: Reference {
                key: vec![name.into(), label.clone()],
                codes,
            },
        });
    }
    Ok(out)
}

/// Case 2 VOI centres (cm from the box centre), by VOI number 1–9.
const CASE2_VOIS: [[f64; 3]; 9] = [
    [0.0, -15.0, 0.0],
    [-15.0, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [15.0, 0.0, 0.0],
    [0.0, 15.0, 0.0],
    [0.0, 0.0, -6.0],
    [0.0, 0.0, -3.0],
    [0.0, 0.0, 3.0],
    [0.0, 0.0, 6.0],
];

/// Case 2: energy imparted in the whole box and the nine VOIs (radiography, or
/// tomosynthesis at 15°); `vois` limits the VOIs scored (all: 1..=9).
pub fn case2(
    beam: Beam,
    tomo: bool,
    vois: &[usize],
    photons: u64,
    seed: u64,
) -> Result<Vec<Comparison>> {
    let label = beam.label();
    if !matches!(beam, Beam::Kvp(120)) && beam != Beam::Mono(56.4) {
        return Err(SimError::OutOfRange(format!(
            "TG-195 case 2 has 56.4 keV and 120 kVp beams, not {label}"
        )));
    }
    let spectrum = beam.spectrum()?;
    let mode = if tomo { "tomosynthesis" } else { "radiography" };
    let shift = if tomo {
        1800.0 * 15f64.to_radians().tan()
    } else {
        0.0
    };
    let source = FieldSource::new(
        DVec3::new(0.0, -shift, 0.0),
        DVec3::Z * 1800.0,
        DVec3::X * 195.0,
        DVec3::Y * 195.0,
    )?;
    // Air from the source to the field plane, laterally wherever the primary beam goes.
    let s = 5.0;
    let y_min = -195.0 - (shift / s).ceil() * s;
    let dims = [78, ((195.0 - y_min) / s) as usize, 360];
    let body = |c: DVec3| c.x.abs() < 195.0 && c.y.abs() < 195.0 && c.z > 1550.0 && c.z < 1750.0;
    let m = medium(
        DVec3::new(-195.0, y_min, 0.0),
        dims,
        DVec3::splat(s),
        vec![air()?, soft_tissue()?],
        spectrum.max_kev() + 1.0,
        |c| if body(c) { (1.03, 1) } else { (0.001205, 0) },
    )?;
    let centre = DVec3::new(0.0, 0.0, 1650.0);
    let mut regions = vec![Region::cube(
        "Total body",
        centre,
        DVec3::new(390.0, 390.0, 200.0),
    )];
    for &v in vois {
        let o = CASE2_VOIS
            .get(v.wrapping_sub(1))
            .ok_or_else(|| SimError::OutOfRange(format!("case 2 has VOIs 1 to 9, not {v}")))?;
        regions.push(Region::cube(
            &format!("VOI {v}"),
            centre + DVec3::from(*o) * 10.0,
            DVec3::splat(30.0),
        ));
    }
    // Scored at the interaction points: the box and its 3 cm VOIs see enough collisions.
    let r = run(
        &m,
        &source,
        &spectrum,
        &regions,
        &[],
        (RegionEstimator::Collision, photons),
        seed,
    )?;
    regions_against(&r, &reference::case2()?, "2", &label, mode)
}

/// Each scored region of `r` beside its reference row (key: [volume, VOI centre, beam,
/// mode]) from `refs`, as rows of case `case` ("2 radiography 56.4 keV", …).
pub(super) fn regions_against(
    r: &EnergyImparted,
    refs: &[Reference],
    case: &str,
    label: &str,
    mode: &str,
) -> Result<Vec<Comparison>> {
    r.regions
        .iter()
        .map(|(name, e)| {
            let reference = refs
                .iter()
                .find(|x| x.key[0] == *name && x.key[2] == label && x.key[3] == mode)
                .cloned()
                .ok_or_else(|| {
                    SimError::OutOfRange(format!("no case {case} reference for {name}"))
                })?;
            Ok(Comparison {
                case: format!("{case} {mode} {label}"),
                quantity: name.clone(),
                ours: e.ev_per_photon,
                ours_se: e.standard_error,
                reference,
            })
        })
        .collect()
}

/// Case 4.2: energy imparted in the centre and peripheral scoring cylinders for source
/// angles 0–350° (10° steps) and for a continuous rotation (their mean); `wide`: 80 mm
/// collimation, else 10 mm.
pub fn case42(beam: Beam, wide: bool, photons: u64, seed: u64) -> Result<Vec<Comparison>> {
    let label = beam.label();
    if !matches!(beam, Beam::Kvp(120)) && beam != Beam::Mono(56.4) {
        return Err(SimError::OutOfRange(format!(
            "TG-195 case 4.2 has 56.4 keV and 120 kVp beams, not {label}"
        )));
    }
    let spectrum = beam.spectrum()?;
    let half_z = if wide { 40.0 } else { 5.0 };
    let source = FieldSource::new(
        DVec3::new(-600.0, 0.0, 0.0),
        DVec3::ZERO,
        DVec3::Y * 160.0,
        DVec3::Z * half_z,
    )?;
    let (r0, sub) = (160.0, 4);
    let spacing = DVec3::new(2.0, 2.0, 20.0);
    let min = DVec3::new(-600.0, -164.0, -500.0);
    let dims = [382, 164, 50];
    let m = medium(
        min,
        dims,
        spacing,
        vec![air()?, pmma()?],
        spectrum.max_kev() + 1.0,
        |c| {
            // Fraction of the voxel's cross-section inside the cylinder, 4 × 4 sub-samples.
            let mut inside = 0;
            for a in 0..sub {
                for b in 0..sub {
                    let x = c.x + ((a as f64 + 0.5) / sub as f64 - 0.5) * spacing.x;
                    let y = c.y + ((b as f64 + 0.5) / sub as f64 - 0.5) * spacing.y;
                    inside += usize::from(x * x + y * y < r0 * r0);
                }
            }
            let f = inside as f64 / (sub * sub) as f64;
            if f == 0.0 {
                (0.001205, 0)
            } else {
                ((1.19 * f + 0.001205 * (1.0 - f)) as f32, 1)
            }
        },
    )?;
    let mut regions = vec![Region::cylinder(
        "Center",
        DVec3::ZERO,
        DVec3::Z,
        5.0,
        100.0,
    )];
    for a in 0..36 {
        // The source at angle θ (about +z, from −x) ≡ the phantom turned by −θ.
        let th = -(a as f64 * 10.0).to_radians();
        let at = DVec3::new(-150.0 * th.cos(), -150.0 * th.sin(), 0.0);
        regions.push(Region::cylinder(
            &format!("{}", a * 10),
            at,
            DVec3::Z,
            5.0,
            100.0,
        ));
    }
    // Track length: the peripheral cylinders behind the phantom get few interactions, and
    // every photon crossing them scores (docs/validation.md).
    let r = run(
        &m,
        &source,
        &spectrum,
        &regions,
        &[],
        (RegionEstimator::TrackLength, photons),
        seed,
    )?;
    let refs = reference::case42()?;
    let coll = if wide { "80mm" } else { "10mm" };
    let find = |angle: &str, volume: &str| {
        refs.iter()
            .find(|x| {
                x.key[0] == angle
                    && x.key[1] == label
                    && x.key[2] == format!("{volume} {coll} collimation")
            })
            .cloned()
            .ok_or_else(|| {
                SimError::OutOfRange(format!("no case 4.2 reference for {angle} {volume}"))
            })
    };
    let case = format!("4.2 {coll} {label}");
    let mut out = Vec::new();
    // The centre cylinder sees every angle alike: compare with each code's mean over the
    // 36 angles.
    let mut codes = [None; 4];
    for (c, slot) in codes.iter_mut().enumerate() {
        let v: Option<Vec<f64>> = (0..36)
            .map(|a| find(&(a * 10).to_string(), "Center").map(|x| x.codes[c]))
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .collect();
        *slot = v.map(|v| v.iter().sum::<f64>() / v.len() as f64);
    }
    let centre = r.regions[0].1;
    out.push(Comparison {
        case: case.clone(),
        quantity: "Center (mean over angles)".into(),
        ours: centre.ev_per_photon,
        ours_se: centre.standard_error,
        reference: Reference {
            key: vec!["Center".into()],
            codes,
        },
    });
    // The phantom, its voxels and the fan are mirror-symmetric about the plane of the
    // source's path (y = 0), so the cylinders at θ and 360° − θ have the same expectation:
    // each angle's row is their mean (regions 1 + a and 1 + (36 − a) mod 36), its
    // standard error from their covariance.
    for a in 0..36 {
        let b = (36 - a) % 36;
        let e = r.combine(&[(1 + a, 0.5), (1 + b, 0.5)])?;
        let name = format!("{}", a * 10);
        out.push(Comparison {
            case: case.clone(),
            quantity: format!("Periphery {name}°"),
            ours: e.ev_per_photon,
            ours_se: e.standard_error,
            reference: find(&name, "Pherifery")?,
        });
    }
    let all: Vec<(usize, f64)> = (1..=36).map(|k| (k, 1.0 / 36.0)).collect();
    let continuous = r.combine(&all)?;
    if let Ok(cont) = find("Continuous", "Center") {
        out.push(Comparison {
            case: case.clone(),
            quantity: "Center, continuous rotation".into(),
            ours: centre.ev_per_photon,
            ours_se: centre.standard_error,
            reference: cont,
        });
    }
    if let Ok(cont) = find("Continuous", "Pherifery") {
        out.push(Comparison {
            case: case.clone(),
            quantity: "Periphery, continuous rotation".into(),
            ours: continuous.ev_per_photon,
            ours_se: continuous.standard_error,
            reference: cont,
        });
    }
    Ok(out)
}

/// The codes' names, for table headers.
pub fn codes() -> [&'static str; 4] {
    CODES
}
