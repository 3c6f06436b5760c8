//! The X-ray detector: from the expected photons per pixel to what a real panel records,
//! and the flat/dark correction and −log a clinical chain applies.
//!
//! Not to be confused with [`tomograf_sim::geometry::Detector`], the pixel grid (rows, columns,
//! pitch); this is the physics of the panel, [`DetectorModel`].
//!
//! **Stage order** of [`DetectorModel::record`], per channel:
//! 1. expected signal per pixel, mean m and second moment M₂ ([`ExpectedImage`], built by
//!    the caller from the photons per energy bin and [`DetectorModel::channel_weights`]);
//! 2. quantum noise ([`noise`]): g·Poisson(λ), λ = m²/M₂, g = M₂/m (mean m, variance M₂);
//! 3. scintillator blur and pixel aperture ([`blur`]), applied to the noisy signal so the
//!    noise is correlated as the light spread makes it;
//! 4. readout ([`readout`]): gain map, offset map, electronic noise, saturation, ADC.
//!
//! Signal units: ADU for energy integration (the conversion gain sets ADU per keV
//! absorbed), counts for photon counting. Noise is seeded per (seed, stage, channel, row),
//! so images are identical for any number of threads.

pub mod blur;
pub mod clipping;
pub mod correction;
pub mod noise;
pub mod readout;
pub mod response;

pub use blur::Blur;
pub use clipping::Clipping;
pub use correction::{
    Calibration, FlatField, Output, flat_field_correct, log_line_integral,
    log_line_integral_clamped,
};
pub use readout::Readout;
pub use response::{ChannelWeights, Mode, Scintillator, absorption_efficiency, channel_weights};

use noise::Stage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::Detector;
use tomograf_sim::render::Projection;

/// The noiseless expectation per pixel that the energy integration produces: per channel
/// (channel-major), a row-major `rows × cols` image, pixel (0, 0) top-left as in
/// [`Projection`].
#[derive(Debug, Clone, PartialEq)]
pub struct ExpectedImage {
    /// Image height.
    pub rows: usize,
    /// Image width.
    pub cols: usize,
    /// Output channels (1 for energy integration, one per threshold for counting).
    pub channels: usize,
    /// Pixel pitch along a row (between columns), mm.
    pub pitch_u_mm: f64,
    /// Pixel pitch down a column (between rows), mm.
    pub pitch_v_mm: f64,
    /// Mean signal, signal units; `channels · rows · cols` values, pixel (c, r, k) at
    /// `(c·rows + r)·cols + k`.
    pub mean: Vec<f64>,
    /// Second moment of the signal (its quantum-noise variance), signal units², same layout.
    pub second_moment: Vec<f64>,
}

impl ExpectedImage {
    /// An all-zero image on `detector`'s grid.
    pub fn zeros(detector: &Detector, channels: usize) -> Self {
        let n = channels * detector.rows * detector.cols;
        Self {
            rows: detector.rows,
            cols: detector.cols,
            channels,
            pitch_u_mm: detector.pitch_u_mm,
            pitch_v_mm: detector.pitch_v_mm,
            mean: vec![0.0; n],
            second_moment: vec![0.0; n],
        }
    }

    /// Adds one energy bin: `photons[p]` expected photons reaching pixel p (row-major, one
    /// per pixel) of bin `bin` of `weights`.
    pub fn accumulate_bin(
        &mut self,
        photons: &[f64],
        weights: &ChannelWeights,
        bin: usize,
    ) -> Result<()> {
        let n = self.rows * self.cols;
        if photons.len() != n {
            return Err(bad(format!(
                "{} photon values for a {} × {} image",
                photons.len(),
                self.rows,
                self.cols
            )));
        }
        if weights.mean.len() != self.channels
            || weights.mean.iter().any(|w| bin >= w.len())
            || weights.second_moment.iter().any(|w| bin >= w.len())
        {
            return Err(bad(format!(
                "energy bin {bin} or channel count {} does not match the weights",
                self.channels
            )));
        }
        for c in 0..self.channels {
            let (w1, w2) = (weights.mean[c][bin], weights.second_moment[c][bin]);
            let range = c * n..(c + 1) * n;
            for ((m, m2), &q) in self.mean[range.clone()]
                .iter_mut()
                .zip(&mut self.second_moment[range])
                .zip(photons)
            {
                *m += q * w1;
                *m2 += q * w2;
            }
        }
        Ok(())
    }

    /// Channel `c`'s mean signal, row-major.
    pub fn channel_mean(&self, c: usize) -> &[f64] {
        let n = self.rows * self.cols;
        &self.mean[c * n..(c + 1) * n]
    }

    /// Checks sizes, pitches and values (finite, ≥ 0, M₂ > 0 where the mean is > 0).
    pub fn validate(&self) -> Result<()> {
        if self.rows == 0 || self.cols == 0 || self.channels == 0 {
            return Err(bad(format!(
                "empty expected image: {} channels of {} × {} pixels",
                self.channels, self.rows, self.cols
            )));
        }
        let n = self.channels * self.rows * self.cols;
        if self.mean.len() != n || self.second_moment.len() != n {
            return Err(bad(format!(
                "expected image holds {} means and {} second moments; {} channels of {} × {} \
                 need {n}",
                self.mean.len(),
                self.second_moment.len(),
                self.channels,
                self.rows,
                self.cols
            )));
        }
        Detector {
            rows: self.rows,
            cols: self.cols,
            pitch_u_mm: self.pitch_u_mm,
            pitch_v_mm: self.pitch_v_mm,
            offset_u_mm: 0.0,
            offset_v_mm: 0.0,
        }
        .validate()?;
        for (i, (&m, &m2)) in self.mean.iter().zip(&self.second_moment).enumerate() {
            if !(m.is_finite() && m2.is_finite() && m >= 0.0 && m2 >= 0.0 && (m2 > 0.0 || m == 0.0))
            {
                let p = i % (self.rows * self.cols);
                return Err(bad(format!(
                    "expected image channel {}, pixel (row {}, col {}): mean {m}, second \
                     moment {m2}; both must be finite and ≥ 0, the second moment > 0 where \
                     the mean is",
                    i / (self.rows * self.cols),
                    p / self.cols,
                    p % self.cols
                )));
            }
        }
        Ok(())
    }
}

/// The detector physics, configurable from a scene's `[detector]` table (snake_case keys, kebab-case values).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct DetectorModel {
    /// Energy response.
    #[serde(default = "default_mode")]
    pub mode: Mode,
    /// The converter layer (informative: the caller turns its μ(E) into η(E)).
    #[serde(default)]
    pub scintillator: Option<Scintillator>,
    /// Whether quantum (Poisson) noise is sampled.
    #[serde(default)]
    pub quantum_noise: bool,
    /// Light spread and pixel aperture.
    #[serde(default)]
    pub blur: Blur,
    /// Gain, offset, electronic noise, saturation, ADC.
    #[serde(default)]
    pub readout: Readout,
    /// How flat and dark fields are acquired.
    #[serde(default)]
    pub calibration: Calibration,
}

fn default_mode() -> Mode {
    Mode::energy_integrating(1.0)
}

impl DetectorModel {
    /// No noise, no blur, unit gain, 1 ADU per keV: [`Self::record`] returns the mean.
    pub fn ideal() -> Self {
        Self {
            mode: default_mode(),
            scintillator: None,
            quantum_noise: false,
            blur: Blur::none(),
            readout: Readout::ideal(),
            calibration: Calibration::default(),
        }
    }

    /// Every detector name [`Self::by_name`] knows, as scenes and `--detector-model` write
    /// them.
    pub const NAMES: &[&str] = &[
        "perfect-absorber",
        "ideal",
        "noiseless-csi",
        "kv-flat-panel",
        "cbct",
        "photon-counting",
    ];

    /// The detector called `name` (one of [`Self::NAMES`]); `thresholds_kev` are the
    /// photon-counting thresholds (default `[20]`) and an error for any other model.
    /// * `perfect-absorber` (alias `ideal`): η = 1, every photon absorbed and its energy
    ///   counted; no noise, blur or readout ([`Self::ideal`]);
    /// * `noiseless-csi`: the `kv-flat-panel`'s 0.6 mm CsI energy response without noise,
    ///   blur or readout ([`Self::noiseless_csi`]);
    /// * `kv-flat-panel`, `cbct`, `photon-counting`: the presets below.
    pub fn by_name(name: &str, thresholds_kev: Option<Vec<f64>>) -> Result<Self> {
        if thresholds_kev.is_some() && name != "photon-counting" {
            return Err(bad(format!(
                "thresholds_kev applies to the photon-counting detector model only, not '{name}'"
            )));
        }
        Ok(match name {
            "perfect-absorber" | "ideal" => Self::ideal(),
            "noiseless-csi" => Self::noiseless_csi(),
            "kv-flat-panel" => Self::kv_flat_panel(),
            "cbct" => Self::cbct(),
            "photon-counting" => {
                Self::photon_counting(thresholds_kev.unwrap_or_else(|| vec![20.0]))
            }
            other => {
                return Err(bad(format!(
                    "unknown detector model '{other}': use one of {}",
                    Self::NAMES.join(", ")
                )));
            }
        })
    }

    /// The `kv-flat-panel`'s converter (0.6 mm CsI: η(E) = 1 − exp(−μ_CsI(E)·0.6 mm), energy
    /// weighted, Swank factor irrelevant without noise) with no quantum or electronic noise,
    /// no blur, no gain or offset maps and no ADC: the line integral a real scintillator
    /// reports, free of noise. It differs from the perfect absorber through η(E) alone
    /// (docs/detector.md gives the size of the difference).
    pub fn noiseless_csi() -> Self {
        let panel = Self::kv_flat_panel();
        Self {
            mode: panel.mode,
            scintillator: panel.scintillator,
            ..Self::ideal()
        }
    }

    /// Whether the signal comes in units (quantum noise, electronic noise or an ADC): then
    /// the −log floor is half a unit; otherwise the expected signal is exact.
    pub fn has_signal_unit(&self) -> bool {
        self.quantum_noise || self.readout.electronic_noise_adu > 0.0 || self.readout.bits.is_some()
    }

    /// Pixels of the recorded `raw` channels at the readout's ceiling (analogue saturation
    /// or the ADC's largest code; none without either) for simulated pixels of `pitch_u_mm`
    /// × `pitch_v_mm`: their signal, and any line integral from it, is clipped.
    pub fn saturated(&self, raw: &[Projection], pitch_u_mm: f64, pitch_v_mm: f64) -> usize {
        let ceiling = self
            .readout
            .ceiling(self.readout.binning(pitch_u_mm, pitch_v_mm));
        if !ceiling.is_finite() {
            return 0;
        }
        // Compared as stored: a clipped pixel holds the ceiling rounded to float32, which
        // may lie below the f64 ceiling (large binned pixels: 2¹⁶ × 59 037 native pixels).
        let ceiling = ceiling as f32;
        raw.iter()
            .map(|p| p.data.iter().filter(|&&v| v >= ceiling).count())
            .sum()
    }

    /// An indirect kV flat panel for radiography (CsI:Tl 0.6 mm on a-Si:H, ~0.14–0.15 mm
    /// pixels, 16-bit ADC). Numbers are typical, not one product's: see docs/detector.md
    /// for their sources.
    pub fn kv_flat_panel() -> Self {
        // CsI:Tl ≈ 54 optical photons/keV; ×~0.5 escape/coupling ×~0.8 photodiode QE
        // ≈ 20 e⁻/keV; 1000 e⁻ per ADU (a radiography gain mode) puts ≈ 90 µGy at ~60 keV
        // at 2¹⁶, above the open field of the acquisition presets (see docs/detector.md).
        Self {
            mode: Mode::EnergyIntegrating {
                conversion_gain_adu_per_kev: 20.0 / 1000.0,
                swank_factor: 0.9,
            },
            scintillator: Some(Scintillator {
                material: "CsI".into(),
                thickness_mm: 0.6,
            }),
            quantum_noise: true,
            blur: Blur {
                sigma_mm: 0.14,
                tail_fraction: 0.05,
                tail_length_mm: 1.0,
            },
            readout: Readout {
                gain_nonuniformity: 0.05,
                offset_adu: 1000.0,
                offset_nonuniformity_adu: 100.0,
                // ~1500 e⁻ rms additive noise (Siewerdsen et al. 1997) at 1000 e⁻/ADU.
                electronic_noise_adu: 1500.0 / 1000.0,
                map_seed: 0x5eed_f1a7,
                saturation_adu: None,
                bits: Some(16),
                native_pitch_mm: Some(0.15),
            },
            calibration: Calibration {
                flat_frames: 16,
                dark_frames: 16,
            },
        }
    }

    /// A cone-beam CT panel as on a linac or C-arm (CsI:Tl 0.6 mm, 2×2-binned ~0.4 mm
    /// pixels read at high frame rate: more blur in the tail, more electronic noise per
    /// ADU, 16-bit ADC). Typical numbers, see docs/detector.md.
    pub fn cbct() -> Self {
        let mut d = Self::kv_flat_panel();
        d.blur = Blur {
            sigma_mm: 0.2,
            tail_fraction: 0.08,
            tail_length_mm: 1.5,
        };
        d.readout.electronic_noise_adu = 2500.0 / 1000.0;
        d.readout.gain_nonuniformity = 0.08;
        d.readout.map_seed = 0xcbc7_0001;
        d.readout.native_pitch_mm = Some(0.4);
        d.calibration = Calibration {
            flat_frames: 32,
            dark_frames: 32,
        };
        d
    }

    /// An ideal-ish CdTe photon-counting detector with `thresholds_kev`: Poisson counts, no
    /// electronic noise (the thresholds reject it), a 12-bit counter, no blur.
    pub fn photon_counting(thresholds_kev: Vec<f64>) -> Self {
        Self {
            mode: Mode::PhotonCounting { thresholds_kev },
            scintillator: Some(Scintillator {
                material: "CdTe".into(),
                thickness_mm: 2.0,
            }),
            quantum_noise: true,
            blur: Blur::none(),
            readout: Readout {
                bits: Some(12),
                ..Readout::ideal()
            },
            calibration: Calibration::default(),
        }
    }

    /// Number of output channels.
    pub fn channels(&self) -> usize {
        self.mode.channels()
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<()> {
        self.mode.validate()?;
        if let Some(s) = &self.scintillator {
            s.validate()?;
        }
        self.blur.validate()?;
        self.calibration.validate()?;
        self.readout.validate()
    }

    /// The weights per channel and energy bin (see [`response`]): `absorption` is η(E) of
    /// the converter at `energies_kev`, e.g. from [`Scintillator::absorption`].
    pub fn channel_weights(
        &self,
        energies_kev: &[f64],
        absorption: &[f64],
    ) -> Result<ChannelWeights> {
        channel_weights(&self.mode, energies_kev, absorption)
    }

    /// One recorded frame: the raw signal per channel (ADU or counts), seeded by `seed`.
    pub fn record(&self, expected: &ExpectedImage, seed: u64) -> Result<Vec<Projection>> {
        self.check(expected)?;
        (0..expected.channels)
            .map(|c| {
                Ok(to_projection(
                    expected,
                    self.signal(expected, c, Some(seed))?,
                ))
            })
            .collect()
    }

    /// The noiseless expectation of the raw signal (no quantum or electronic noise, no
    /// rounding; blur, gain, offset and clipping applied).
    pub fn expectation(&self, expected: &ExpectedImage) -> Result<Vec<Projection>> {
        self.check(expected)?;
        (0..expected.channels)
            .map(|c| Ok(to_projection(expected, self.signal(expected, c, None)?)))
            .collect()
    }

    /// Flat (open beam `open`) and dark (no beam) fields as [`Self::calibration`] says:
    /// noiseless expectations, or averages of recorded frames seeded from `seed`.
    pub fn calibrate(&self, open: &ExpectedImage, seed: u64) -> Result<FlatField> {
        self.check(open)?;
        let mut dark_scene = open.clone();
        dark_scene.mean.fill(0.0);
        dark_scene.second_moment.fill(0.0);
        let c = self.calibration;
        let flat = self.average(open, c.flat_frames, noise::frame_seed(seed, 1 << 32))?;
        let dark = self.average(&dark_scene, c.dark_frames, noise::frame_seed(seed, 2 << 32))?;
        let floor = if self.has_signal_unit() {
            FlatField::HALF_UNIT
        } else {
            FlatField::NOISELESS
        };
        self.check_open_beam(&flat, &dark, open)?;
        FlatField::new(flat, dark)?.with_floor(floor)
    }

    /// Names what makes a calibration unusable at the top of the detector's range, which
    /// [`FlatField::new`] (knowing no ceiling) would blame on too few photons: an open beam
    /// whose signal overflows float32, or a dark field already at the readout's ceiling
    /// (the ADC's top code or the saturation), which no exposure can get above.
    fn check_open_beam(
        &self,
        flat: &[Projection],
        dark: &[Projection],
        open: &ExpectedImage,
    ) -> Result<()> {
        let ceiling = self
            .readout
            .ceiling(self.readout.binning(open.pitch_u_mm, open.pitch_v_mm));
        for (ch, (f, d)) in flat.iter().zip(dark).enumerate() {
            for (i, (&fv, &dv)) in f.data.iter().zip(&d.data).enumerate() {
                let (row, col) = (i / f.cols.max(1), i % f.cols.max(1));
                if !fv.is_finite() {
                    return Err(SimError::OutOfRange(format!(
                        "channel {ch}, pixel (row {row}, col {col}): the open beam's signal is \
                         {fv}: it overflows float32; lower the exposure (mas)"
                    )));
                }
                // fv ≤ dv at the ceiling: the dark field is there too.
                if fv <= dv && ceiling.is_finite() && fv >= ceiling as f32 {
                    return Err(SimError::OutOfRange(format!(
                        "channel {ch}, pixel (row {row}, col {col}): the dark field is already \
                         at the detector's ceiling ({dv} of {ceiling} ADU: the ADC's top code or \
                         the saturation, for pixels of {:.3} × {:.3} mm), so the beam adds \
                         nothing: the offset (offset_adu) fills the readout's range; lower \
                         offset_adu or raise bits / saturation_adu",
                        open.pitch_u_mm, open.pitch_v_mm
                    )));
                }
            }
        }
        Ok(())
    }

    /// The full chain: records `object`, calibrates with `open` (the same exposure without
    /// the object) and returns `output`. Calibration frames use seeds derived from `seed`.
    pub fn acquire(
        &self,
        object: &ExpectedImage,
        open: &ExpectedImage,
        output: Output,
        seed: u64,
    ) -> Result<Vec<Projection>> {
        let raw = self.record(object, seed)?;
        if output == Output::Raw {
            return Ok(raw);
        }
        if (open.rows, open.cols, open.channels) != (object.rows, object.cols, object.channels) {
            return Err(bad(
                "the open-beam image must match the object image's size".into(),
            ));
        }
        self.calibrate(open, noise::frame_seed(seed, 3 << 32))?
            .apply(&raw, output)
    }

    fn check(&self, expected: &ExpectedImage) -> Result<()> {
        self.validate()?;
        expected.validate()?;
        if expected.channels != self.channels() {
            return Err(bad(format!(
                "expected image has {} channels; the detector mode has {}",
                expected.channels,
                self.channels()
            )));
        }
        Ok(())
    }

    /// Mean of `frames` recorded frames (0: the noiseless expectation).
    fn average(&self, scene: &ExpectedImage, frames: u32, seed: u64) -> Result<Vec<Projection>> {
        (0..scene.channels)
            .map(|c| {
                if frames == 0 {
                    return Ok(to_projection(scene, self.signal(scene, c, None)?));
                }
                let mut sum = vec![0.0; scene.rows * scene.cols];
                for f in 0..frames {
                    let s = self.signal(scene, c, Some(noise::frame_seed(seed, f.into())))?;
                    sum.iter_mut().zip(s).for_each(|(a, b)| *a += b);
                }
                sum.iter_mut().for_each(|a| *a /= f64::from(frames));
                Ok(to_projection(scene, sum))
            })
            .collect()
    }

    /// Channel `c` through every stage; `seed` `None`: the noiseless expectation.
    fn signal(&self, e: &ExpectedImage, c: usize, seed: Option<u64>) -> Result<Vec<f64>> {
        let n = e.rows * e.cols;
        let mean = &e.mean[c * n..(c + 1) * n];
        let m2 = &e.second_moment[c * n..(c + 1) * n];
        let binning = self.readout.binning(e.pitch_u_mm, e.pitch_v_mm);
        let mut s = mean.to_vec();
        if let (Some(seed), true) = (seed, self.quantum_noise) {
            s.par_chunks_mut(e.cols)
                .enumerate()
                .try_for_each(|(r, row)| {
                    let mut rng = noise::stream(seed, Stage::Quanta, c, r);
                    let at = r * e.cols..(r + 1) * e.cols;
                    noise::sample_row(&mut rng, &mean[at.clone()], &m2[at], row)
                })?;
        }
        self.blur
            .apply(&mut s, e.rows, e.cols, e.pitch_u_mm, e.pitch_v_mm)?;
        s.par_chunks_mut(e.cols)
            .enumerate()
            .for_each(|(r, row)| self.readout.apply_row(row, r, c, seed, binning));
        Ok(s)
    }
}

fn to_projection(e: &ExpectedImage, s: Vec<f64>) -> Projection {
    Projection {
        rows: e.rows,
        cols: e.cols,
        data: s.into_iter().map(|v| v as f32).collect(),
    }
}

fn bad(msg: String) -> SimError {
    SimError::OutOfRange(msg)
}
