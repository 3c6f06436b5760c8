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
use rayon::prelude::*;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::{View, ViewBeam};
use tomograf_sim::render::MassThickness;

#[cfg(target_arch = "x86_64")]
mod avx512;
mod exp2;
mod kernel;
use kernel::{RowOut, row_kernel};

/// The kernel takes bins in blocks of this many (an AVX-512 register of f32): a partial
/// block would leave a scalar, latency-bound exponential per leftover bin and pixel.
const BIN_BLOCK: usize = 16;

/// One detector channel's response per energy bin, in the kernel's precision (f32: see
/// [`row_kernel`]), each moment divided by its largest bin so that any units of the
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
    /// per channel). Relative precision: that of f32 transmissions (see [`row_kernel`]).
    ///
    /// # Panics
    /// If `t` does not hold one thickness per material, or `mean` or `second` one value
    /// per channel.
    pub fn pixel(&self, t: &[f64], mean: &mut [f64], second: &mut [f64]) {
        let (k, nc) = (self.materials.len(), self.channels.len());
        assert!(
            t.len() == k && mean.len() == nc && second.len() == nc,
            "pixel: {} thicknesses for {k} materials, {} and {} moments for {nc} channels",
            t.len(),
            mean.len(),
            second.len()
        );
        let mut out = RowOut {
            mean: mean.chunks_mut(1).collect(),
            second: second.chunks_mut(1).collect(),
        };
        row_kernel(self, t, &[1.0], &mut vec![0.0; self.padded_bins], &mut out);
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
        let cols = view.cols;
        if thickness.data.len() != view.rows * cols * k {
            return Err(SimError::OutOfRange(format!(
                "the image holds {} mass thicknesses; {}×{} pixels of {k} materials need {}",
                thickness.data.len(),
                view.rows,
                cols,
                view.rows * cols * k
            )));
        }
        self.image(view, mas, |r, factors, out| {
            let t = &thickness.data[r * cols * k..(r + 1) * cols * k];
            row_kernel(self, t, factors, &mut vec![0.0; self.padded_bins], out);
        })
    }

    /// The expected signal of a view with nothing in the beam (the open field) at `mas`:
    /// [`SpectralIntegrator::unattenuated`] times each pixel's exposure factor.
    pub fn open(&self, view: &View, mas: f64) -> Result<ExpectedImage> {
        self.image(view, mas, |_, factors, out| {
            for (c, &f) in factors.iter().enumerate() {
                out.set_open(c, &self.open, f);
            }
        })
    }

    /// An image whose row `r` is filled by `fill(r, factors, out)`: `factors` are the row's
    /// exposure factors times `mas`, `out` the row of each channel's mean and second moment.
    fn image(
        &self,
        view: &View,
        mas: f64,
        fill: impl Fn(usize, &[f64], &mut RowOut) + Sync,
    ) -> Result<ExpectedImage> {
        if !(mas.is_finite() && mas > 0.0) {
            return Err(SimError::OutOfRange(format!(
                "exposure {mas} mAs; it must be finite and > 0"
            )));
        }
        view.validate()?;
        let (rows, cols, nc) = (view.rows, view.cols, self.channels.len());
        let exposure = ExposureFactors::new(view);
        let n = rows * cols;
        let mut mean = vec![0.0; n * nc];
        let mut second_moment = vec![0.0; n * nc];
        // Channel-major images, handed out row by row: row r gets every channel's row r.
        let mut out: Vec<RowOut> = (0..rows)
            .map(|_| RowOut {
                mean: Vec::with_capacity(nc),
                second: Vec::with_capacity(nc),
            })
            .collect();
        for (m, s) in mean.chunks_mut(n).zip(second_moment.chunks_mut(n)) {
            for ((o, m), s) in out
                .iter_mut()
                .zip(m.chunks_mut(cols))
                .zip(s.chunks_mut(cols))
            {
                o.mean.push(m);
                o.second.push(s);
            }
        }
        out.par_iter_mut().enumerate().for_each(|(r, o)| {
            let mut factors = vec![0.0; cols];
            exposure.row(r, &mut factors);
            factors.iter_mut().for_each(|f| *f *= mas);
            fill(r, &factors, o);
        });
        drop(out);
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
            ViewBeam::Cone { source } => cone_factor(
                self.view.pixel_centre(r as f64, c as f64) - source,
                self.normal,
            ),
            ViewBeam::Parallel { direction } => {
                direction.dot(self.normal).abs() / direction.length()
            }
        }
    }

    /// The factors of row `r`, one per column, into `out` (as [`ExposureFactors::at`], with
    /// the choice of beam made once: a loop over the columns that vectorises).
    fn row(&self, r: usize, out: &mut [f64]) {
        match self.view.beam {
            ViewBeam::Cone { source } => {
                for (c, f) in out.iter_mut().enumerate() {
                    let d = self.view.pixel_centre(r as f64, c as f64) - source;
                    *f = cone_factor(d, self.normal);
                }
            }
            ViewBeam::Parallel { .. } => out.fill(self.at(r, 0)),
        }
    }
}

/// `10⁶ · |d⃗ · n⃗| / d³`: the cone-beam exposure factor of a pixel at `d` (mm) from the
/// source, `n` its normal scaled to its area ([`ExposureFactors::at`]).
#[inline(always)]
fn cone_factor(d: glam::DVec3, n: glam::DVec3) -> f64 {
    let d2 = d.length_squared();
    1e6 * d.dot(n).abs() / (d2 * d2.sqrt())
}
