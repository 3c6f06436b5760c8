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

/// The kernel takes bins in blocks of this many (an AVX-512 register of f32): a partial
/// block would leave a scalar, latency-bound exponential per leftover bin and pixel.
const BIN_BLOCK: usize = 16;

/// One detector channel's response per energy bin, in the kernel's precision (f32: see
/// [`pixel_kernel`]), each moment divided by its largest bin so that any units of the
/// spectrum and weights fit f32's range.
#[derive(Debug, Clone, PartialEq)]
struct Channel {
    /// `N0_b · w_b` per unit exposure factor, divided by `scale.0`.
    first: Vec<f32>,
    /// `N0_b · E[w²]_b` per unit exposure factor, divided by `scale.1`.
    second: Vec<f32>,
    /// The largest bin of each moment (1 where all are 0).
    scale: (f64, f64),
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
    mass_att: Vec<f32>,
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
            // (first, second) moments per bin, in f64 until the bins are chosen.
            let times_photons =
                |w: &[f64]| -> Vec<f64> { photons.iter().zip(w).map(|(n, w)| n * w).collect() };
            channels.push((times_photons(w1), times_photons(w2)));
        }
        // Bins that add less than 1e-12 of every channel's open-field signal (the far tails
        // of a filtered spectrum, bins outside every counting window) are dropped: they
        // change no result beyond 1e-12 relative and would cost as much as the others.
        let totals: Vec<f64> = channels.iter().map(|c| c.0.iter().sum()).collect();
        let keep: Vec<bool> = (0..bins)
            .map(|b| {
                channels
                    .iter()
                    .zip(&totals)
                    .any(|(c, total)| c.0[b] > 1e-12 * total)
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
        let narrow = |v: Vec<f64>| -> Vec<f32> { v.into_iter().map(|x| x as f32).collect() };
        // A moment over its largest bin, in f32, and that largest bin.
        let normalised = |v: Vec<f64>| -> (Vec<f32>, f64) {
            let top = v.iter().copied().fold(0.0, f64::max);
            let scale = if top > 0.0 { top } else { 1.0 };
            (v.into_iter().map(|x| (x / scale) as f32).collect(), scale)
        };
        // The open field in f64, from the kept bins (what the kernel's sums tend to as the
        // thicknesses go to 0).
        let open = channels
            .iter()
            .map(|c| (pick(&c.0).iter().sum(), pick(&c.1).iter().sum()))
            .collect();
        let channels: Vec<Channel> = channels
            .iter()
            .map(|c| {
                let (first, s1) = normalised(pick(&c.0));
                let (second, s2) = normalised(pick(&c.1));
                Channel {
                    first,
                    second,
                    scale: (s1, s2),
                }
            })
            .collect();
        let mut energies_kev = pick(&energies_kev);
        energies_kev.truncate(kept);
        Ok(Self {
            energies_kev,
            padded_bins,
            mass_att: narrow(pick(&mass_att)),
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
    /// per channel). Relative precision: that of f32 transmissions (see [`pixel_kernel`]).
    pub fn pixel(&self, t: &[f64], mean: &mut [f64], second: &mut [f64]) {
        self.pixel_with(t, &mut vec![0.0; self.padded_bins], mean, second);
    }

    /// [`SpectralIntegrator::pixel`] with scratch `att` of `padded_bins` values.
    fn pixel_with(&self, t: &[f64], att: &mut [f32], mean: &mut [f64], second: &mut [f64]) {
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
        let first: Vec<f64> = self.open.iter().map(|o| o.0).collect();
        let sec: Vec<f64> = self.open.iter().map(|o| o.1).collect();
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
        fill: impl Fn(usize, &mut [f32], &mut [f64], &mut [f64]) + Sync,
    ) -> Result<ExpectedImage> {
        if !(mas.is_finite() && mas > 0.0) {
            return Err(SimError::OutOfRange(format!(
                "exposure {mas} mAs; it must be finite and > 0"
            )));
        }
        view.validate()?;
        let (rows, cols, nc) = (view.rows, view.cols, self.channels.len());
        let bins = self.padded_bins;
        let exposure = ExposureFactors::new(view);
        // Pixel-major while computing (each row independent), channel-major at the end.
        let mut pm = vec![0.0; rows * cols * nc * 2];
        pm.par_chunks_mut(cols * nc * 2)
            .enumerate()
            .for_each(|(r, out)| {
                let mut att = vec![0.0; bins];
                for (c, px) in out.chunks_mut(nc * 2).enumerate() {
                    let (mean, second) = px.split_at_mut(nc);
                    fill(r * cols + c, &mut att, mean, second);
                    let f = mas * exposure.at(r, c);
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
/// to rounding). Where the CPU has FMA, every multiply-add is fused.
///
/// Precision: optical depths, exponentials and per-lane partial sums are f32 (16 bins per
/// AVX-512 register, twice the f64 rate), the lanes' sums are added in f64. An optical
/// depth τ is then known to ≈ τ·2⁻²⁴ and its transmission to ≈ (τ + 1)·2⁻²³ relative:
/// ≈ 1e-6 at τ = 10 (transmission 5e-5), far below the quantum noise of any exposure the
/// detector models (1/√N ≥ 1e-4 for N ≤ 10⁸ photons) and the tabulated attenuation's own
/// uncertainty (~1 %). The monochromatic projector stays f64 throughout.
#[multiversion::multiversion(targets("x86_64+avx512f+avx2+fma", "x86_64+avx2+fma"))]
fn pixel_kernel(
    mass_att: &[f32],
    bins: usize,
    t: &[f64],
    att: &mut [f32],
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
    mass_att: &[f32],
    bins: usize,
    t: &[f64],
    att: &mut [f32],
    channels: &[Channel],
    mean: &mut [f64],
    second: &mut [f64],
) {
    // Block by block of BIN_BLOCK bins: fixed-size loops compile to straight-line vector
    // code, where loops over all bins would run their few blocks through remainder loops.
    for (i, a) in att.chunks_exact_mut(BIN_BLOCK).enumerate() {
        let mut tau = [0.0f32; BIN_BLOCK];
        for (m, &tm) in t.iter().enumerate() {
            if tm != 0.0 {
                let start = m * bins + i * BIN_BLOCK;
                let mu = &mass_att[start..start + BIN_BLOCK];
                for l in 0..BIN_BLOCK {
                    tau[l] = madd::<FMA>(tm as f32, mu[l], tau[l]);
                }
            }
        }
        for l in 0..BIN_BLOCK {
            a[l] = exp_neg::<FMA>(tau[l]);
        }
    }
    for (c, ch) in channels.iter().enumerate() {
        mean[c] = dot::<FMA>(&ch.first, att) * ch.scale.0;
        second[c] = dot::<FMA>(&ch.second, att) * ch.scale.1;
    }
}

/// a·b + c, fused when `FMA`.
#[inline(always)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// Σ a·b over whole blocks of [`BIN_BLOCK`] (the padded bins): one f32 partial sum per
/// lane (each adds at most a few dozen positive terms), the lanes added in f64 as a tree
/// (a chain of 16 dependent adds would cost more than the bins themselves at few bins).
/// The order is fixed, so results are the same on every run.
#[inline(always)]
fn dot<const FMA: bool>(a: &[f32], b: &[f32]) -> f64 {
    let mut s = [0.0f32; BIN_BLOCK];
    for (x, y) in a.chunks_exact(BIN_BLOCK).zip(b.chunks_exact(BIN_BLOCK)) {
        for l in 0..BIN_BLOCK {
            s[l] = madd::<FMA>(x[l], y[l], s[l]);
        }
    }
    let mut h: [f64; BIN_BLOCK / 2] =
        std::array::from_fn(|l| f64::from(s[l]) + f64::from(s[l + BIN_BLOCK / 2]));
    let mut n = BIN_BLOCK / 2;
    while n > 1 {
        n /= 2;
        for l in 0..n {
            h[l] += h[l + n];
        }
    }
    h[0]
}

/// e^(−x) for x ≥ 0 in f32, branch-free so that loops over it vectorise: x·log₂e split
/// into the nearest integer k and a remainder in [−½, ½], 2^remainder from its Taylor
/// series to degree 7 (truncation < 6e-9 on [−½ ln 2, ½ ln 2], below f32 rounding), k put
/// in the exponent. The rounding of x·log₂e adds ≈ x·2⁻²⁴ relative. Results below 2^−126
/// (x > 87.3) are flushed to 0, like a transmission that underflows; never NaN. `FMA`:
/// fused multiply-adds (see [`pixel_kernel`]).
#[inline(always)]
fn exp_neg<const FMA: bool>(x: f32) -> f32 {
    let y = -x.clamp(0.0, 200.0) * std::f32::consts::LOG2_E; // in [−289, 0]
    let k = y.round_ties_even();
    let r = (y - k) * std::f32::consts::LN_2; // in [−½ ln 2, ½ ln 2]
    // Horner form of Σ rⁿ/n!, n ≤ 7.
    let mut p = 1.0 / 5040.0;
    for d in [720.0, 120.0, 24.0, 6.0, 2.0, 1.0, 1.0] {
        p = madd::<FMA>(p, r, 1.0 / d);
    }
    // 2^k through the exponent field; biased exponents ≤ 0 give +0.0.
    let biased = (k + 127.0).max(0.0);
    let scale = f32::from_bits((biased + 8_388_608.0).to_bits() << 23);
    p * scale
}

/// Area (mm²) × inverse-square × obliquity factor of pixel `(r, c)`: multiplied by a
/// fluence in photons per mm² at 1 m, it gives the photons the pixel receives
/// (`A · (1000/d)² · cos γ` for a cone beam, `A · cos γ` for a parallel beam).
pub fn pixel_exposure_factor(view: &View, r: usize, c: usize) -> f64 {
    ExposureFactors::new(view).at(r, c)
}

/// [`pixel_exposure_factor`] for every pixel of one view, with what the pixels share
/// computed once.
struct ExposureFactors<'a> {
    view: &'a View,
    /// u × v: the pixel's normal, with length its area (mm²).
    normal: glam::DVec3,
}

impl<'a> ExposureFactors<'a> {
    fn new(view: &'a View) -> Self {
        Self {
            view,
            normal: view.u.cross(view.v),
        }
    }

    /// The factor of pixel `(r, c)`. Cone beam: `A · (1000/d)² · cos γ` with
    /// `A · cos γ = |d⃗ · n⃗| / d` (|n⃗| = A), i.e. `10⁶ · |d⃗ · n⃗| / d³`.
    fn at(&self, r: usize, c: usize) -> f64 {
        match self.view.beam {
            ViewBeam::Cone { source } => {
                let d = self.view.pixel_centre(r as f64, c as f64) - source;
                let d2 = d.length_squared();
                1e6 * d.dot(self.normal).abs() / (d2 * d2.sqrt())
            }
            ViewBeam::Parallel { direction } => {
                direction.dot(self.normal).abs() / direction.length()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::exp_neg;

    /// Against f64's exp on [0, 87] (where f32 holds the result as a normal number): the
    /// relative error stays within (x + 2)·2⁻²³, the bound [`exp_neg`] states (input
    /// rounding x·2⁻²⁴ twice over, plus the polynomial's and the product's rounding).
    #[test]
    fn fast_exp_matches_std_exp() {
        let mut worst = 0.0f64;
        for i in 0..200_000 {
            let x = i as f32 * 0.000_435; // 0 … 87
            let b = (-f64::from(x)).exp();
            for e in [exp_neg::<false>, exp_neg::<true>] {
                let rel = ((f64::from(e(x)) - b) / b).abs();
                worst = worst.max(rel / ((f64::from(x) + 2.0) * 2f64.powi(-23)));
            }
        }
        assert!(worst < 1.0, "worst error {worst} × the stated bound");
        for e in [exp_neg::<false>, exp_neg::<true>] {
            assert_eq!(e(0.0), 1.0);
            assert_eq!(e(100.0), 0.0);
            assert_eq!(e(f32::INFINITY), 0.0);
            assert!(e(87.0) > 0.0 && e(87.0).is_finite());
        }
    }
}
