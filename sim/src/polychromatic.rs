//! Polychromatic Beer–Lambert: from per-material mass thickness to the expected detector
//! signal, energy bin by energy bin.
//!
//! For a pixel that sees mass thicknesses `t_m` (g/cm², [`MassThickness`]), the photons of
//! energy bin `b` that reach it are `N_b = N0_b · exp(−Σ_m t_m · (μ/ρ)_m(E_b))`, and a
//! detector channel with weight `w_c(E)` (signal per incident photon: absorbed fraction ×
//! energy for an energy-integrating detector, absorbed fraction × threshold window for a
//! photon counter) records on average `Σ_b N_b · w_c(E_b)`, with quantum-noise second
//! moment `Σ_b N_b · w_c(E_b)²` (compound Poisson). Tracing happens once, before this
//! step: many bins cost `bins × materials` multiply-adds and `bins` exponentials per pixel,
//! never another trace.
//!
//! Photons per pixel: the spectrum gives fluence per mAs per mm² at 1 m from the focal
//! spot; a flat-panel pixel of area `A` at distance `d` whose normal makes angle γ with
//! the ray receives `fluence · mAs · A · (1000 mm / d)² · cos γ` (inverse square and
//! obliquity, [`pixel_exposure_factor`]). For a parallel beam the fluence at 1 m applies
//! to every pixel (`A` only).

use crate::detector::{ChannelWeights, ExpectedImage};
use crate::error::{Result, SimError};
use crate::geometry::{View, ViewBeam};
use crate::render::MassThickness;
use rayon::prelude::*;

/// The kernel takes bins in blocks of this many (an AVX-512 register of f64): a partial
/// block would leave a scalar, latency-bound exponential per leftover bin and pixel.
const BIN_BLOCK: usize = 8;

/// One detector channel's response per energy bin.
#[derive(Debug, Clone, PartialEq)]
struct Channel {
    /// `N0_b · w_b` per unit exposure factor.
    first: Vec<f64>,
    /// `N0_b · E[w²]_b` per unit exposure factor.
    second: Vec<f64>,
}

/// A beam (spectrum), the attenuation of each material and a detector's channel weights,
/// ready to integrate pixel by pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectralIntegrator {
    energies_kev: Vec<f64>,
    /// Bins as the kernel sees them: the energies' count rounded up to a multiple of
    /// [`BIN_BLOCK`] with bins of zero attenuation and zero weight, which add exactly 0.
    padded_bins: usize,
    /// Mass attenuation (cm²/g), material-major: `mass_att[m·padded_bins + b]`.
    mass_att: Vec<f64>,
    materials: Vec<String>,
    channels: Vec<Channel>,
    /// Per channel, the mean and second moment with nothing in the beam.
    open: Vec<(f64, f64)>,
}

impl SpectralIntegrator {
    /// Builds the integrator.
    ///
    /// * `energies_kev` — bin energies (keV), and `photons` — photons per bin per mAs per
    ///   mm² at 1 m (a [`crate::spectrum`] spectrum);
    /// * `materials` — names and, per material, the mass attenuation (cm²/g) at each bin
    ///   energy, in the order of the composition's material indices;
    /// * `weights` — per detector channel, the first and second moment of the signal per
    ///   incident photon at each bin energy ([`crate::detector::DetectorModel::channel_weights`]).
    pub fn new(
        energies_kev: Vec<f64>,
        photons: &[f64],
        materials: Vec<(String, Vec<f64>)>,
        weights: &ChannelWeights,
    ) -> Result<Self> {
        let bins = energies_kev.len();
        let bad = |what: String| Err(SimError::OutOfRange(what));
        if bins == 0 || photons.len() != bins {
            return bad(format!(
                "the spectrum has {bins} energies but {} photon counts",
                photons.len()
            ));
        }
        if let Some(p) = photons.iter().find(|p| !(p.is_finite() && **p >= 0.0)) {
            return bad(format!(
                "spectrum photon count {p}; counts must be finite and ≥ 0"
            ));
        }
        if weights.mean.is_empty() || weights.mean.len() != weights.second_moment.len() {
            return bad("the detector has no channels".into());
        }
        let mut mass_att = Vec::with_capacity(materials.len() * bins);
        let mut names = Vec::with_capacity(materials.len());
        for (name, att) in materials {
            if att.len() != bins || att.iter().any(|a| !(a.is_finite() && *a >= 0.0)) {
                return bad(format!(
                    "material '{name}' needs one finite, non-negative mass attenuation per \
                     energy bin ({bins})"
                ));
            }
            mass_att.extend_from_slice(&att);
            names.push(name);
        }
        let mut channels = Vec::with_capacity(weights.mean.len());
        for (c, (w1, w2)) in weights.mean.iter().zip(&weights.second_moment).enumerate() {
            let ok = |w: &Vec<f64>| w.len() == bins && w.iter().all(|x| x.is_finite() && *x >= 0.0);
            if !(ok(w1) && ok(w2)) {
                return bad(format!(
                    "detector channel {c} needs one finite, non-negative weight per energy bin \
                     ({bins})"
                ));
            }
            channels.push(Channel {
                first: photons.iter().zip(w1).map(|(n, w)| n * w).collect(),
                second: photons.iter().zip(w2).map(|(n, w)| n * w).collect(),
            });
        }
        // Bins that add less than 1e-12 of every channel's open-field signal (the far tails
        // of a filtered spectrum, bins outside every counting window) are dropped: they
        // change no result beyond 1e-12 relative and would cost as much as the others.
        let totals: Vec<f64> = channels.iter().map(|c| c.first.iter().sum()).collect();
        let keep: Vec<bool> = (0..bins)
            .map(|b| {
                channels
                    .iter()
                    .zip(&totals)
                    .any(|(c, total)| c.first[b] > 1e-12 * total)
            })
            .collect();
        let kept = keep.iter().filter(|k| **k).count();
        let padded_bins = kept.div_ceil(BIN_BLOCK) * BIN_BLOCK;
        // The kept bins of each `bins`-long block of `v`, padded with zeros.
        let pick = |v: &[f64]| -> Vec<f64> {
            v.chunks(bins)
                .flat_map(|block| {
                    let kept = block
                        .iter()
                        .zip(&keep)
                        .filter(|(_, k)| **k)
                        .map(|(x, _)| *x);
                    kept.chain(std::iter::repeat(0.0)).take(padded_bins)
                })
                .collect()
        };
        let channels: Vec<Channel> = channels
            .iter()
            .map(|c| Channel {
                first: pick(&c.first),
                second: pick(&c.second),
            })
            .collect();
        let open = channels
            .iter()
            .map(|c| (c.first.iter().sum(), c.second.iter().sum()))
            .collect();
        let mut energies_kev = pick(&energies_kev);
        energies_kev.truncate(kept);
        Ok(Self {
            energies_kev,
            padded_bins,
            mass_att: pick(&mass_att),
            materials: names,
            channels,
            open,
        })
    }

    /// Bin energies (keV) of the bins that contribute (see [`SpectralIntegrator::new`]).
    pub fn energies_kev(&self) -> &[f64] {
        &self.energies_kev
    }

    /// Material names, by index.
    pub fn materials(&self) -> &[String] {
        &self.materials
    }

    /// Number of detector channels.
    pub fn channels(&self) -> usize {
        self.channels.len()
    }

    /// Mean signal of each channel with nothing in the beam, per unit exposure factor
    /// (the flat field before exposure and geometry).
    pub fn unattenuated(&self) -> Vec<f64> {
        self.open.iter().map(|o| o.0).collect()
    }

    /// Mean and second moment of each channel, per unit exposure factor, behind mass
    /// thicknesses `t` (g/cm², one per material), into `mean` and `second` (one value
    /// per channel).
    pub fn pixel(&self, t: &[f64], mean: &mut [f64], second: &mut [f64]) {
        self.pixel_with(t, &mut vec![0.0; self.padded_bins], mean, second);
    }

    /// [`SpectralIntegrator::pixel`] with scratch `att` of `padded_bins` values.
    fn pixel_with(&self, t: &[f64], att: &mut [f64], mean: &mut [f64], second: &mut [f64]) {
        if t.iter().all(|&x| x == 0.0) {
            // Nothing in the way (air): the open field.
            for (c, &(m1, m2)) in self.open.iter().enumerate() {
                mean[c] = m1;
                second[c] = m2;
            }
            return;
        }
        pixel_kernel(
            &self.mass_att,
            self.padded_bins,
            t,
            att,
            &self.channels,
            mean,
            second,
        );
    }
    /// The expected signal of a whole view at `mas` (mA·s), from its mass thicknesses.
    pub fn expected(
        &self,
        thickness: &MassThickness,
        view: &View,
        mas: f64,
    ) -> Result<ExpectedImage> {
        if thickness.materials != self.materials {
            return Err(SimError::OutOfRange(format!(
                "the image holds materials [{}] but the spectral model has [{}]",
                thickness.materials.join(", "),
                self.materials.join(", ")
            )));
        }
        if (thickness.rows, thickness.cols) != (view.rows, view.cols) {
            return Err(SimError::InvalidGeometry(format!(
                "the image is {}×{} but the view is {}×{}",
                thickness.rows, thickness.cols, view.rows, view.cols
            )));
        }
        let k = self.materials.len();
        self.image(view, mas, |p, att, mean, second| {
            self.pixel_with(&thickness.data[p * k..(p + 1) * k], att, mean, second)
        })
    }

    /// The expected signal of a view with nothing in the beam (the open field) at `mas`:
    /// [`SpectralIntegrator::unattenuated`] times each pixel's exposure factor.
    pub fn open(&self, view: &View, mas: f64) -> Result<ExpectedImage> {
        let first: Vec<f64> = self.channels.iter().map(|c| c.first.iter().sum()).collect();
        let sec: Vec<f64> = self
            .channels
            .iter()
            .map(|c| c.second.iter().sum())
            .collect();
        self.image(view, mas, |_, _, mean, second| {
            mean.copy_from_slice(&first);
            second.copy_from_slice(&sec);
        })
    }

    /// An image whose pixel `p` (row-major) gets, per unit exposure, the channels' means
    /// and second moments from `fill(p, scratch, mean, second)`.
    fn image(
        &self,
        view: &View,
        mas: f64,
        fill: impl Fn(usize, &mut [f64], &mut [f64], &mut [f64]) + Sync,
    ) -> Result<ExpectedImage> {
        if !(mas.is_finite() && mas > 0.0) {
            return Err(SimError::OutOfRange(format!(
                "exposure {mas} mAs; it must be finite and > 0"
            )));
        }
        view.validate()?;
        let (rows, cols, nc) = (view.rows, view.cols, self.channels.len());
        let bins = self.padded_bins;
        // Pixel-major while computing (each row independent), channel-major at the end.
        let mut pm = vec![0.0; rows * cols * nc * 2];
        pm.par_chunks_mut(cols * nc * 2)
            .enumerate()
            .for_each(|(r, out)| {
                let mut att = vec![0.0; bins];
                for (c, px) in out.chunks_mut(nc * 2).enumerate() {
                    let (mean, second) = px.split_at_mut(nc);
                    fill(r * cols + c, &mut att, mean, second);
                    let f = mas * pixel_exposure_factor(view, r, c);
                    mean.iter_mut()
                        .chain(second.iter_mut())
                        .for_each(|v| *v *= f);
                }
            });
        let n = rows * cols;
        let mut mean = vec![0.0; n * nc];
        let mut second_moment = vec![0.0; n * nc];
        for (p, px) in pm.chunks(nc * 2).enumerate() {
            for ch in 0..nc {
                mean[ch * n + p] = px[ch];
                second_moment[ch * n + p] = px[nc + ch];
            }
        }
        Ok(ExpectedImage {
            rows,
            cols,
            channels: nc,
            pitch_u_mm: view.u.length(),
            pitch_v_mm: view.v.length(),
            mean,
            second_moment,
        })
    }
}

/// Transmission per bin behind thicknesses `t`, then each channel's two dot products; one
/// body compiled for AVX-512, AVX2 and baseline x86-64, chosen at run time (results agree
/// to rounding). Where the CPU has FMA, every multiply-add is fused: half the instructions
/// of the exponential's polynomial, and one rounding instead of two.
#[multiversion::multiversion(targets("x86_64+avx512f+avx2+fma", "x86_64+avx2+fma"))]
fn pixel_kernel(
    mass_att: &[f64],
    bins: usize,
    t: &[f64],
    att: &mut [f64],
    channels: &[Channel],
    mean: &mut [f64],
    second: &mut [f64],
) {
    if multiversion::target::target_cfg_f!(target_feature = "fma") {
        transmission_and_dots::<true>(mass_att, bins, t, att, channels, mean, second);
    } else {
        transmission_and_dots::<false>(mass_att, bins, t, att, channels, mean, second);
    }
}

/// The body of [`pixel_kernel`]; `FMA`: fuse multiply-adds (only where the CPU has FMA,
/// which is otherwise emulated in software).
#[inline(always)]
fn transmission_and_dots<const FMA: bool>(
    mass_att: &[f64],
    bins: usize,
    t: &[f64],
    att: &mut [f64],
    channels: &[Channel],
    mean: &mut [f64],
    second: &mut [f64],
) {
    att.fill(0.0);
    for (m, &tm) in t.iter().enumerate() {
        if tm != 0.0 {
            let mu = &mass_att[m * bins..(m + 1) * bins];
            for (a, &mu) in att.iter_mut().zip(mu) {
                *a = madd::<FMA>(tm, mu, *a);
            }
        }
    }
    att.iter_mut().for_each(|a| *a = exp_neg::<FMA>(*a));
    for (c, ch) in channels.iter().enumerate() {
        mean[c] = dot::<FMA>(&ch.first, att);
        second[c] = dot::<FMA>(&ch.second, att);
    }
}

/// a·b + c, fused when `FMA`.
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// Σ a·b with four partial sums (vectorises; the order is fixed, so results are the same
/// on every run).
#[inline(always)]
fn dot<const FMA: bool>(a: &[f64], b: &[f64]) -> f64 {
    let mut s = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..4 {
            s[l] = madd::<FMA>(x[l], y[l], s[l]);
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// e^(−x) for x ≥ 0, branch-free so that loops over it vectorise: x·log₂e split into the
/// nearest integer k and a remainder in [−½, ½], 2^remainder from its Taylor series to
/// degree 11 (truncation < 1e-14 on [−½ ln 2, ½ ln 2]; the rounding of x·log₂e adds up to
/// ~1e-13 relative near x = 700), k put in the exponent. Results
/// below 2^−1022 (x > 708.4) are flushed to 0, like a transmission that underflows; never
/// NaN. `FMA`: fused multiply-adds (see [`pixel_kernel`]).
#[inline(always)]
fn exp_neg<const FMA: bool>(x: f64) -> f64 {
    let y = -x.clamp(0.0, 1000.0) * std::f64::consts::LOG2_E; // in [−1443, 0]
    let k = y.round_ties_even();
    let r = (y - k) * std::f64::consts::LN_2; // in [−½ ln 2, ½ ln 2]
    // Horner form of Σ rⁿ/n!, n ≤ 11.
    let mut p = 1.0 / 39_916_800.0;
    for d in [
        3_628_800.0,
        362_880.0,
        40_320.0,
        5040.0,
        720.0,
        120.0,
        24.0,
        6.0,
        2.0,
        1.0,
        1.0,
    ] {
        p = madd::<FMA>(p, r, 1.0 / d);
    }
    // 2^k through the exponent field; biased exponents ≤ 0 give +0.0.
    let biased = (k + 1023.0).max(0.0);
    let scale = f64::from_bits((biased + 4_503_599_627_370_496.0).to_bits() << 52);
    p * scale
}

/// Area (mm²) × inverse-square × obliquity factor of pixel `(r, c)`: multiplied by a
/// fluence in photons per mm² at 1 m, it gives the photons the pixel receives
/// (`A · (1000/d)² · cos γ` for a cone beam, `A · cos γ` for a parallel beam).
pub fn pixel_exposure_factor(view: &View, r: usize, c: usize) -> f64 {
    let normal = view.u.cross(view.v);
    let area = normal.length();
    match view.beam {
        ViewBeam::Cone { source } => {
            let d = view.pixel_centre(r as f64, c as f64) - source;
            let dist = d.length();
            let cos = (d.dot(normal) / (dist * area)).abs();
            area * (1000.0 / dist).powi(2) * cos
        }
        ViewBeam::Parallel { direction } => direction.dot(normal).abs() / direction.length(),
    }
}

#[cfg(test)]
mod tests {
    use super::exp_neg;

    #[test]
    fn fast_exp_matches_std_exp() {
        let mut worst = 0.0f64;
        for i in 0..200_000 {
            let x = i as f64 * 0.0035; // 0 … 700
            let (a, b) = (exp_neg::<false>(x), (-x).exp());
            let c = exp_neg::<true>(x);
            worst = worst.max(((c - b) / b).abs());
            worst = worst.max(((a - b) / b).abs());
        }
        assert!(worst < 5e-13, "worst relative error {worst}");
        for e in [exp_neg::<false>, exp_neg::<true>] {
            assert_eq!(e(0.0), 1.0);
            assert_eq!(e(720.0), 0.0);
            assert_eq!(e(f64::INFINITY), 0.0);
            assert!(e(708.0) > 0.0 && e(708.0).is_finite());
        }
    }
}
