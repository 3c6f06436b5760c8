//! Matched-physics mode: the transport a general-purpose volumetric renderer (Mitsuba 3's
//! `volpath`) shares with this engine, for cross-checks — monoenergetic photons, one
//! homogeneous box of extinction μ_t (mm⁻¹) with a constant single-scattering albedo and
//! an isotropic or Henyey–Greenstein phase function, a point source and a flat detector.
//!
//! The same estimator as the X-ray engine ([`super::engine`]): photons from the source,
//! exact free-flight sampling in the box, and at every collision forced detection to the
//! centre of **every** pixel,
//!
//! `W · a · p(cos θ) · A cos γ / d² · exp(−μ_t ℓ_out)`,
//!
//! then implicit capture (W ← a·W), a new direction from the phase function, and Russian
//! roulette below 5 % of the starting weight. Photons leave the source uniformly in the
//! cone subtending the box's bounding sphere, each carrying `Ω_cone / photons`, so the
//! images are in photons per pixel for a source of intensity 1 photon per steradian.
//! A collision of a photon that has not scattered before scores into `single`, later ones
//! into `multiple`. Seeds and batches as in the engine: the bytes do not depend on the
//! thread count.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::f64::consts::PI;
use tomograf_physics::scatter::transport::rotate;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::{View, ViewBeam};
use tomograf_sim::seed::frame_seed;

/// Histories per batch (one random stream each).
const BATCH: u64 = 256;
/// Batches run in parallel before their tallies are summed in order.
const CHUNK: u64 = 64;
/// Russian roulette threshold, as a fraction of the starting weight.
const ROULETTE: f64 = 0.05;

/// A homogeneous box medium with matched (renderer-style) physics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchedMedium {
    /// Lower corner, world mm.
    pub min_mm: DVec3,
    /// Upper corner, world mm.
    pub max_mm: DVec3,
    /// Extinction coefficient μ_t, mm⁻¹.
    pub mu_t_per_mm: f64,
    /// Single-scattering albedo μ_s/μ_t ∈ [0, 1].
    pub albedo: f64,
    /// Henyey–Greenstein asymmetry g ∈ (−1, 1); 0 is isotropic.
    pub g: f64,
}

/// Per-pixel scatter of the matched mode, row-major `rows × cols`, photons per pixel per
/// unit source intensity (photons/sr), with Monte Carlo standard errors from the spread of
/// batch tallies.
#[derive(Debug, Clone)]
pub struct MatchedImages {
    /// Image height.
    pub rows: usize,
    /// Image width.
    pub cols: usize,
    /// Photons scattered once.
    pub single: Vec<f64>,
    /// Photons scattered two or more times.
    pub multiple: Vec<f64>,
    /// Standard error of `single`.
    pub single_se: Vec<f64>,
    /// Standard error of `single + multiple`.
    pub total_se: Vec<f64>,
}

impl MatchedMedium {
    /// Checks the medium, naming the bad value.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(SimError::OutOfRange(format!("matched medium: {m}")));
        if !(self.min_mm.is_finite() && self.max_mm.is_finite())
            || self.min_mm.cmpge(self.max_mm).any()
        {
            return bad(format!(
                "box {:?}–{:?} must be finite with min < max",
                self.min_mm, self.max_mm
            ));
        }
        if !(self.mu_t_per_mm.is_finite() && self.mu_t_per_mm > 0.0) {
            return bad(format!("mu_t = {} mm⁻¹; give > 0", self.mu_t_per_mm));
        }
        if !(0.0..=1.0).contains(&self.albedo) {
            return bad(format!("albedo = {}; give 0–1", self.albedo));
        }
        if !(self.g.is_finite() && self.g.abs() < 1.0) {
            return bad(format!("g = {}; give −1 < g < 1", self.g));
        }
        Ok(())
    }

    /// Entry and exit distances of the ray `p + t·d` (t ≥ 0) through the box.
    fn clip(&self, p: DVec3, d: DVec3) -> Option<(f64, f64)> {
        let inv = d.recip();
        let a = (self.min_mm - p) * inv;
        let b = (self.max_mm - p) * inv;
        let lo = a.min(b);
        let hi = a.max(b);
        // NaN (0·∞ on a face) is ignored by max/min element.
        let t0 = lo.max_element().max(0.0);
        let t1 = hi.min_element();
        (t1 > t0).then_some((t0, t1))
    }

    /// Phase function density (sr⁻¹) at cos θ = `mu`.
    pub fn phase(&self, mu: f64) -> f64 {
        let g = self.g;
        (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
    }

    fn sample_phase<R: Rng>(&self, rng: &mut R) -> f64 {
        let (g, u) = (self.g, rng.random::<f64>());
        if g.abs() < 1e-6 {
            return 1.0 - 2.0 * u;
        }
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    }
}

/// Runs `photons` histories from `view`'s point source through `medium`, scoring every
/// pixel of `view`, at most `max_order` scatters each.
pub fn simulate(
    medium: &MatchedMedium,
    view: &View,
    photons: u64,
    max_order: u32,
    seed: u64,
) -> Result<MatchedImages> {
    medium.validate()?;
    view.validate()?;
    let ViewBeam::Cone { source } = view.beam else {
        return Err(SimError::InvalidGeometry(
            "matched scatter needs a cone beam (a point source)".into(),
        ));
    };
    if photons < 2 * BATCH || max_order == 0 {
        return Err(SimError::OutOfRange(format!(
            "matched scatter: photons = {photons} (give ≥ {}), max_order = {max_order} (≥ 1)",
            2 * BATCH
        )));
    }
    let centre = (medium.min_mm + medium.max_mm) * 0.5;
    let radius = (medium.max_mm - medium.min_mm).length() * 0.5;
    let axis = centre - source;
    let dist = axis.length();
    if dist <= radius {
        return Err(SimError::InvalidGeometry(
            "matched scatter: the source must lie outside the box's bounding sphere".into(),
        ));
    }
    let axis = axis / dist;
    let cos_cone = (1.0 - (radius / dist).powi(2)).sqrt();
    let w0 = 2.0 * PI * (1.0 - cos_cone) / photons as f64;
    let pixels: Vec<DVec3> = (0..view.rows * view.cols)
        .map(|i| view.pixel_centre((i / view.cols) as f64, (i % view.cols) as f64))
        .collect();
    let n = view.u.cross(view.v);
    let (normal, area) = (n.normalize(), n.length());
    let np = pixels.len();

    let history = |rng: &mut ChaCha8Rng, tally: &mut [f64]| {
        let mu = cos_cone + (1.0 - cos_cone) * rng.random::<f64>();
        let mut d = rotate(axis, mu, 2.0 * PI * rng.random::<f64>());
        let mut p = source;
        let mut w = w0;
        for order in 0..max_order {
            let Some((t0, t1)) = medium.clip(p, d) else {
                return;
            };
            let t = t0 - (1.0 - rng.random::<f64>()).ln() / medium.mu_t_per_mm;
            if t >= t1 {
                return;
            }
            p += d * t;
            let base = w * medium.albedo * area;
            let out = &mut tally[if order == 0 { 0 } else { np }..][..np];
            for (s, &q) in out.iter_mut().zip(&pixels) {
                let to = q - p;
                let d2 = to.length_squared();
                let r = d2.sqrt();
                let wq = to / r;
                let exit = medium.clip(p, wq).map_or(0.0, |(_, e)| e.min(r));
                *s += base * medium.phase(d.dot(wq)) * wq.dot(normal).abs() / d2
                    * (-medium.mu_t_per_mm * exit).exp();
            }
            w *= medium.albedo;
            if w < ROULETTE * w0 {
                if rng.random::<f64>() < 0.5 {
                    w *= 2.0;
                } else {
                    return;
                }
            }
            let mu = medium.sample_phase(rng);
            d = rotate(d, mu, 2.0 * PI * rng.random::<f64>());
        }
    };

    let batches = photons.div_ceil(BATCH);
    let (mut sum, mut sq_single, mut sq_total) = (vec![0.0; 2 * np], vec![0.0; np], vec![0.0; np]);
    for chunk in (0..batches).step_by(CHUNK as usize) {
        let tallies: Vec<Vec<f64>> = (chunk..(chunk + CHUNK).min(batches))
            .into_par_iter()
            .map(|b| {
                let mut rng = ChaCha8Rng::seed_from_u64(frame_seed(seed, b));
                let mut tally = vec![0.0; 2 * np];
                for _ in 0..BATCH.min(photons - b * BATCH) {
                    history(&mut rng, &mut tally);
                }
                tally
            })
            .collect();
        for t in &tallies {
            for i in 0..np {
                sum[i] += t[i];
                sum[np + i] += t[np + i];
                sq_single[i] += t[i] * t[i];
                sq_total[i] += (t[i] + t[np + i]).powi(2);
            }
        }
    }
    let nb = batches as f64;
    let se = |sq: f64, s: f64| ((sq - s * s / nb).max(0.0) * nb / (nb - 1.0)).sqrt();
    Ok(MatchedImages {
        rows: view.rows,
        cols: view.cols,
        single_se: (0..np).map(|i| se(sq_single[i], sum[i])).collect(),
        total_se: (0..np)
            .map(|i| se(sq_total[i], sum[i] + sum[np + i]))
            .collect(),
        single: sum[..np].to_vec(),
        multiple: sum[np..].to_vec(),
    })
}
