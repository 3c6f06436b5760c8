//! Scintillator blur and pixel aperture: the light from each absorbed photon spreads
//! (point-spread function, PSF) before the photodiodes collect it.
//!
//! **PSF.** A Gaussian core of standard deviation σ (mm) plus an optional long-range tail
//! carrying a fraction t of the light (the low-frequency drop of CsI and Gd2O2S screens):
//! PSF = (1 − t)·g_σ(x)·g_σ(y) + t·e_L(x)·e_L(y), with e_L(x) = exp(−|x|/L)/(2L). The tail
//! is separable (a product of 1-D exponentials), so its MTF is exactly
//! 1/(1 + (2πL·f_x)²) · 1/(1 + (2πL·f_y)²); the core's is exp(−2π²σ²f²).
//!
//! **Aperture.** The expected image is sampled at pixel centres (one ray per pixel), so the
//! photons of pixel n are taken to be absorbed at its centre. Their light is collected by
//! the square aperture of each pixel (100 % fill factor): the discrete kernel is
//! k[m] = ∫ over pixel m of the PSF centred on pixel 0. Its transfer function is the PSF's
//! MTF times sinc(p·f) (the aperture), sampled at the pitch p, i.e. aliased:
//! K(f) = Σ_j MTF(f + j/p)·sinc(p·(f + j/p)). A slanted-edge measurement on the recorded
//! image therefore sees K (checked in `tests/detector_mtf.rs`). Without a PSF the kernel is
//! the identity (the aliased sinc sums to 1): the aperture's own sinc on the scene needs
//! rays inside the pixel, i.e. the caller supersampling the expected image.
//!
//! **Implementation.** Separable: the Gaussian as a finite kernel to ±5σ (renormalised
//! to sum 1; the mass cut is < 6·10⁻⁷), the tail exactly (untruncated) by a first-order
//! recursive filter, since the pixel integrals of an exponential are A·r^|m| for m ≠ 0.
//! Image borders replicate the edge pixels, so flat images stay flat and light is
//! conserved. The noise variance of white input is multiplied by Σk²
//! ([`Blur::noise_power_gain`]) away from the borders.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};

/// The light-spread PSF (see the module docs). All zero: no blur.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct Blur {
    /// Standard deviation of the Gaussian core, mm; ≥ 0 (0: no core spread).
    #[serde(default)]
    pub sigma_mm: f64,
    /// Fraction of the light in the exponential tail, in [0, 1].
    #[serde(default)]
    pub tail_fraction: f64,
    /// Decay length L of the tail, mm; > 0 when `tail_fraction` > 0.
    #[serde(default)]
    pub tail_length_mm: f64,
}

/// A 1-D pixel kernel along one image axis.
#[derive(Debug, Clone)]
enum Kernel {
    /// Symmetric finite kernel, `taps[j]` at offset j − radius.
    Fir { taps: Vec<f64>, radius: usize },
    /// k[0] = c0, k[m] = a1·r^(|m|−1) for m ≠ 0 (infinite).
    Exp { c0: f64, a1: f64, r: f64 },
}

impl Blur {
    /// No blur.
    pub fn none() -> Self {
        Self::default()
    }

    /// A Gaussian core only.
    pub fn gaussian(sigma_mm: f64) -> Self {
        Self {
            sigma_mm,
            ..Self::default()
        }
    }

    /// True when the blur leaves images unchanged.
    pub fn is_identity(&self) -> bool {
        self.sigma_mm == 0.0 && self.tail_fraction == 0.0
    }

    /// The widest PSF accepted, mm (σ and L): scintillators spread light over tenths of a
    /// millimetre; a wider kernel is a mistake, and its size (±5σ in pixels) would grow
    /// without bound.
    pub const MAX_MM: f64 = 100.0;

    /// Checks 0 ≤ σ ≤ [`Self::MAX_MM`], t ∈ [0, 1], 0 < L ≤ [`Self::MAX_MM`] where t > 0.
    pub fn validate(&self) -> Result<()> {
        if !(self.sigma_mm.is_finite() && (0.0..=Self::MAX_MM).contains(&self.sigma_mm)) {
            return Err(bad(format!(
                "blur sigma is {} mm; it must lie in 0–{} mm",
                self.sigma_mm,
                Self::MAX_MM
            )));
        }
        if self.tail_length_mm > Self::MAX_MM {
            return Err(bad(format!(
                "blur tail length is {} mm; at most {} mm",
                self.tail_length_mm,
                Self::MAX_MM
            )));
        }
        if !(self.tail_fraction.is_finite() && (0.0..=1.0).contains(&self.tail_fraction)) {
            return Err(bad(format!(
                "blur tail fraction is {}; it must be in [0, 1]",
                self.tail_fraction
            )));
        }
        if !(self.tail_length_mm.is_finite() && self.tail_length_mm >= 0.0)
            || (self.tail_fraction > 0.0 && self.tail_length_mm == 0.0)
        {
            return Err(bad(format!(
                "blur tail length is {} mm; it must be finite, and > 0 when the tail \
                 fraction is > 0",
                self.tail_length_mm
            )));
        }
        Ok(())
    }

    /// Σk² of the 2-D pixel kernel for pitches `pitch_u_mm` (along a row) and
    /// `pitch_v_mm` (down a column): the factor by which the blur multiplies the variance
    /// of uncorrelated pixel noise (away from the image borders).
    pub fn noise_power_gain(&self, pitch_u_mm: f64, pitch_v_mm: f64) -> Result<f64> {
        self.validate()?;
        check_pitch(pitch_u_mm, pitch_v_mm)?;
        let t = self.tail_fraction;
        let dense = |p: f64| {
            let g = dense_taps(&self.core_kernel(p));
            let e = if t > 0.0 {
                dense_taps(&self.tail_kernel(p))
            } else {
                vec![0.0]
            };
            let dot = |a: &[f64], b: &[f64]| -> f64 {
                let (ra, rb) = (a.len() / 2, b.len() / 2);
                let r = ra.min(rb);
                (0..=2 * r).map(|j| a[ra - r + j] * b[rb - r + j]).sum()
            };
            (dot(&g, &g), dot(&g, &e), dot(&e, &e))
        };
        let (gg_u, ge_u, ee_u) = dense(pitch_u_mm);
        let (gg_v, ge_v, ee_v) = dense(pitch_v_mm);
        Ok((1.0 - t).powi(2) * gg_u * gg_v
            + 2.0 * t * (1.0 - t) * ge_u * ge_v
            + t * t * ee_u * ee_v)
    }

    /// Blurs a `rows × cols` row-major image in place (pitches in mm).
    pub fn apply(
        &self,
        image: &mut [f64],
        rows: usize,
        cols: usize,
        pitch_u_mm: f64,
        pitch_v_mm: f64,
    ) -> Result<()> {
        self.validate()?;
        check_pitch(pitch_u_mm, pitch_v_mm)?;
        if image.len() != rows * cols {
            return Err(bad(format!(
                "image of {} values is not {rows} × {cols}",
                image.len()
            )));
        }
        if self.is_identity() || image.is_empty() {
            return Ok(());
        }
        // image ← (1 − t)·Gv(Gu(image)) + t·Ev(Eu(image)): rows first, then columns
        // straight into the image.
        let t = self.tail_fraction;
        let rows_through = |k: &Kernel| {
            let mut a = vec![0.0; image.len()];
            a.par_chunks_mut(cols)
                .zip(image.par_chunks(cols))
                .for_each(|(dst, src)| filter_line(src, dst, k));
            a
        };
        let core = (t < 1.0).then(|| rows_through(&self.core_kernel(pitch_u_mm)));
        let tail = (t > 0.0).then(|| rows_through(&self.tail_kernel(pitch_u_mm)));
        if let Some(a) = &core {
            filter_columns(
                a,
                image,
                rows,
                cols,
                &self.core_kernel(pitch_v_mm),
                1.0 - t,
                false,
            );
        }
        if let Some(b) = &tail {
            let k = self.tail_kernel(pitch_v_mm);
            filter_columns(b, image, rows, cols, &k, t, core.is_some());
        }
        Ok(())
    }

    /// Pixel integrals of the 1-D Gaussian core at pitch `p`.
    fn core_kernel(&self, p: f64) -> Kernel {
        let s = self.sigma_mm;
        if s == 0.0 {
            return Kernel::Fir {
                taps: vec![1.0],
                radius: 0,
            };
        }
        let radius = (5.0 * s / p).ceil() as usize;
        let z = |x: f64| x / (s * std::f64::consts::SQRT_2);
        let mut taps: Vec<f64> = (0..=2 * radius)
            .map(|j| {
                let m = j.abs_diff(radius) as f64;
                if m == 0.0 {
                    libm::erf(z(0.5 * p))
                } else {
                    // Upper-tail differences keep precision far from the centre.
                    0.5 * (libm::erfc(z((m - 0.5) * p)) - libm::erfc(z((m + 0.5) * p)))
                }
            })
            .collect();
        let sum: f64 = taps.iter().sum();
        taps.iter_mut().for_each(|k| *k /= sum);
        Kernel::Fir { taps, radius }
    }

    /// Pixel integrals of the 1-D exponential tail at pitch `p` (exact, sum 1).
    fn tail_kernel(&self, p: f64) -> Kernel {
        let h = 0.5 * p / self.tail_length_mm;
        // ∫ over pixel m ≥ 1 of exp(−|x|/L)/(2L) = sinh(h)·e^(−2hm) = a1·r^(m−1).
        Kernel::Exp {
            c0: -(-h).exp_m1(),
            a1: 0.5 * ((-h).exp() - (-3.0 * h).exp()),
            r: (-2.0 * h).exp(),
        }
    }
}

fn check_pitch(pu: f64, pv: f64) -> Result<()> {
    if !(pu.is_finite() && pu > 0.0 && pv.is_finite() && pv > 0.0) {
        return Err(bad(format!(
            "pixel pitch {pu} × {pv} mm; it must be finite and > 0"
        )));
    }
    Ok(())
}

/// The kernel's taps as a dense symmetric array (the exponential cut where its taps fall
/// below 1e-17 of the centre).
fn dense_taps(k: &Kernel) -> Vec<f64> {
    match k {
        Kernel::Fir { taps, .. } => taps.clone(),
        &Kernel::Exp { c0, a1, r } => {
            let mut side = Vec::new();
            let mut v = a1;
            while v > 1e-17 * c0 && side.len() < 1 << 20 {
                side.push(v);
                v *= r;
            }
            side.iter()
                .rev()
                .copied()
                .chain(std::iter::once(c0))
                .chain(side.iter().copied())
                .collect()
        }
    }
}

/// Filters every column of a row-major image with `k` scaled by `scale`, writing (or with
/// `add`, adding) to `dst`. Works on whole rows at a time, so the inner loops run along
/// memory; edges replicated.
fn filter_columns(
    src: &[f64],
    dst: &mut [f64],
    rows: usize,
    cols: usize,
    k: &Kernel,
    scale: f64,
    add: bool,
) {
    let row = |r: usize| &src[r * cols..(r + 1) * cols];
    match k {
        Kernel::Fir { taps, radius } => {
            dst.par_chunks_mut(cols).enumerate().for_each(|(r, out)| {
                if !add {
                    out.fill(0.0);
                }
                for (j, &kj) in taps.iter().enumerate() {
                    let rr = (r + j).saturating_sub(*radius).min(rows - 1);
                    let kj = scale * kj;
                    for (o, &x) in out.iter_mut().zip(row(rr)) {
                        *o += kj * x;
                    }
                }
            });
        }
        &Kernel::Exp { c0, a1, r } => {
            // The recursion of `filter_line`, one state per column, rows in sequence.
            let (c0, a1) = (scale * c0, scale * a1);
            let mut u: Vec<f64> = row(0).iter().map(|&x| x / (1.0 - r)).collect();
            for i in 0..rows {
                if i > 0 {
                    for (u, &x) in u.iter_mut().zip(row(i - 1)) {
                        *u = x + r * *u;
                    }
                }
                let out = &mut dst[i * cols..(i + 1) * cols];
                for ((o, &x), &u) in out.iter_mut().zip(row(i)).zip(&u) {
                    let v = c0 * x + a1 * u;
                    *o = if add { *o + v } else { v };
                }
            }
            u.iter_mut()
                .zip(row(rows - 1))
                .for_each(|(u, &x)| *u = x / (1.0 - r));
            for i in (0..rows).rev() {
                if i + 1 < rows {
                    for (u, &x) in u.iter_mut().zip(row(i + 1)) {
                        *u = x + r * *u;
                    }
                }
                let out = &mut dst[i * cols..(i + 1) * cols];
                for (o, &u) in out.iter_mut().zip(&u) {
                    *o += a1 * u;
                }
            }
        }
    }
}

/// One line through a 1-D kernel, edges replicated.
fn filter_line(src: &[f64], dst: &mut [f64], k: &Kernel) {
    let n = src.len();
    match k {
        Kernel::Fir { taps, radius } => {
            let r = *radius;
            // Taps in order for every pixel (same sums whatever the path): edge pixels
            // with replicated neighbours, the interior as shifted slices (vectorises).
            let edge = |i: usize| -> f64 {
                taps.iter()
                    .enumerate()
                    .map(|(j, k)| k * src[(i + j).saturating_sub(r).min(n - 1)])
                    .sum()
            };
            if n <= 2 * r {
                for (i, d) in dst.iter_mut().enumerate() {
                    *d = edge(i);
                }
                return;
            }
            let inner = &mut dst[r..n - r];
            inner.fill(0.0);
            for (j, &k) in taps.iter().enumerate() {
                for (d, &x) in inner.iter_mut().zip(&src[j..j + n - 2 * r]) {
                    *d += k * x;
                }
            }
            for i in (0..r).chain(n - r..n) {
                dst[i] = edge(i);
            }
        }
        &Kernel::Exp { c0, a1, r } => {
            // u[i] = Σ_{m≥1} r^(m−1)·x[i−m], with x[<0] = x[0] (so u[0] = x0/(1−r)).
            let mut u = src[0] / (1.0 - r);
            for (i, d) in dst.iter_mut().enumerate() {
                if i > 0 {
                    u = src[i - 1] + r * u;
                }
                *d = c0 * src[i] + a1 * u;
            }
            let mut u = src[n - 1] / (1.0 - r);
            for i in (0..n).rev() {
                if i + 1 < n {
                    u = src[i + 1] + r * u;
                }
                dst[i] += a1 * u;
            }
        }
    }
}

fn bad(msg: String) -> SimError {
    SimError::OutOfRange(msg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_images_stay_flat_and_light_is_conserved() {
        let b = Blur {
            sigma_mm: 0.3,
            tail_fraction: 0.2,
            tail_length_mm: 1.5,
        };
        let mut flat = vec![7.0; 40 * 30];
        b.apply(&mut flat, 40, 30, 0.2, 0.25).unwrap();
        assert!(flat.iter().all(|&x| (x - 7.0).abs() < 1e-12));
        // A point well inside: total signal conserved.
        let mut p = vec![0.0; 201 * 201];
        p[100 * 201 + 100] = 1.0;
        b.apply(&mut p, 201, 201, 0.2, 0.2).unwrap();
        let sum: f64 = p.iter().sum();
        assert!((sum - 1.0).abs() < 1e-4, "{sum}"); // tail beyond ±20 mm: e^(−13)
    }

    #[test]
    fn exponential_taps_are_the_pixel_integrals() {
        // Independent: midpoint-rule integral of exp(−|x|/L)/(2L) over each pixel.
        let b = Blur {
            sigma_mm: 0.0,
            tail_fraction: 1.0,
            tail_length_mm: 0.7,
        };
        let p = 0.4;
        let mut img = vec![0.0; 61];
        img[30] = 1.0;
        b.apply(&mut img, 1, 61, p, 1e6).unwrap(); // huge row pitch: no vertical spread
        for m in -5i32..=5 {
            let n = 20_000;
            let lo = (f64::from(m) - 0.5) * p;
            let want: f64 = (0..n)
                .map(|i| {
                    let x = lo + (i as f64 + 0.5) * p / n as f64;
                    (-x.abs() / 0.7).exp() / 1.4 * p / n as f64
                })
                .sum();
            let got = img[(30 + m) as usize];
            assert!((got - want).abs() < 1e-8, "m={m}: {got} vs {want}");
        }
    }

    #[test]
    fn bad_blur_is_refused() {
        for b in [
            Blur::gaussian(-1.0),
            Blur::gaussian(f64::NAN),
            Blur {
                sigma_mm: 0.1,
                tail_fraction: 0.1,
                tail_length_mm: 0.0,
            },
            Blur {
                sigma_mm: 0.1,
                tail_fraction: 1.5,
                tail_length_mm: 1.0,
            },
        ] {
            assert!(b.validate().is_err(), "{b:?}");
        }
    }
}
