//! Readout electronics: per-pixel gain and offset, electronic noise, saturation and the
//! analogue-to-digital converter (ADC).
//!
//! Applied to the (blurred) signal s of pixel (r, c) of channel ch, in this order:
//! 1. gain: s·g(r, c), g uniform in [1 − x, 1 + x] (x = `gain_nonuniformity`);
//! 2. offset: + o₀ + δ(r, c), δ uniform in [−y, y] (y = `offset_nonuniformity_adu`);
//! 3. electronic noise: + σₑ·N(0, 1), new every frame;
//! 4. saturation: min(·, `saturation_adu`) (the analogue full well, in ADU);
//! 5. ADC with `bits`: clipped to [0, 2^bits − 1] and rounded to the nearest integer
//!    (halves up).
//!    Stored as f32, so integers above 2^24 (bits > 24) are rounded to f32 precision.
//!
//! The gain and offset maps are fixed properties of the panel: drawn from `map_seed`
//! (streams per channel and row), identical in every frame, flat and dark.

use super::noise::{self, Stage};
use rand::Rng;
use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};

/// Readout parameters (signal units: ADU for energy integration, counts for counting).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct Readout {
    /// Half-width x of the per-pixel gain spread, gain uniform in [1 − x, 1 + x];
    /// in [0, 0.5]. 0: unit gain everywhere.
    #[serde(default)]
    pub gain_nonuniformity: f64,
    /// Mean dark offset o₀, ADU; finite.
    #[serde(default)]
    pub offset_adu: f64,
    /// Half-width y of the per-pixel offset spread, ADU; ≥ 0.
    #[serde(default)]
    pub offset_nonuniformity_adu: f64,
    /// Standard deviation σₑ of the additive electronic noise, ADU; ≥ 0.
    #[serde(default)]
    pub electronic_noise_adu: f64,
    /// Seed of the fixed gain and offset maps.
    #[serde(default)]
    pub map_seed: u64,
    /// Analogue saturation level, ADU (> 0); none: no saturation before the ADC.
    #[serde(default)]
    pub saturation_adu: Option<f64>,
    /// ADC bit depth, 1–32; none: no quantisation (floating-point output).
    #[serde(default)]
    pub bits: Option<u32>,
    /// Pitch of the panel's own pixels, mm; none: the simulated pixels are the panel's.
    /// A simulated pixel of area A larger than native² is read as the digital sum of
    /// n = A/native² native pixels, each with its own offset, electronic noise, full well
    /// and ADC: the mean offset and the saturation and ADC range scale by n, the offset
    /// spread and the electronic noise by √n (independent pixels), and the sum is an
    /// integer code. (Each native pixel is taken to see the simulated pixel's mean signal.)
    #[serde(default)]
    pub native_pitch_mm: Option<f64>,
}

impl Readout {
    /// Unit gain, no offset, no noise, no saturation, no quantisation.
    pub fn ideal() -> Self {
        Self::default()
    }

    /// Checks ranges and finiteness.
    pub fn validate(&self) -> Result<()> {
        let g = self.gain_nonuniformity;
        if !(g.is_finite() && (0.0..=0.5).contains(&g)) {
            return Err(bad(format!(
                "gain non-uniformity is {g}; it must be in [0, 0.5]"
            )));
        }
        if !self.offset_adu.is_finite() {
            return Err(bad(format!(
                "detector offset is {} ADU; it must be finite",
                self.offset_adu
            )));
        }
        for (name, v) in [
            ("offset non-uniformity", self.offset_nonuniformity_adu),
            ("electronic noise", self.electronic_noise_adu),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(format!("{name} is {v} ADU; it must be finite and ≥ 0")));
            }
        }
        if let Some(s) = self.saturation_adu
            && !(s.is_finite() && s > 0.0)
        {
            return Err(bad(format!(
                "saturation level is {s} ADU; it must be finite and > 0"
            )));
        }
        if let Some(b) = self.bits
            && !(1..=32).contains(&b)
        {
            return Err(bad(format!("ADC bit depth is {b}; it must be 1 to 32")));
        }
        if let Some(p) = self.native_pitch_mm
            && !(p.is_finite() && p > 0.0)
        {
            return Err(bad(format!(
                "native pixel pitch is {p} mm; it must be finite and > 0"
            )));
        }
        Ok(())
    }

    /// Largest ADC code, 2^bits − 1 (none without an ADC).
    pub fn max_code(&self) -> Option<f64> {
        self.bits.map(|b| ((1u64 << b) - 1) as f64)
    }

    /// The largest signal a simulated pixel of `binning` native pixels can record (ADU):
    /// the lower of the analogue saturation and the ADC's largest code; ∞ without either.
    pub fn ceiling(&self, binning: f64) -> f64 {
        let sat = self.saturation_adu.map_or(f64::INFINITY, |s| s * binning);
        self.max_code().map_or(sat, |m| sat.min(m * binning))
    }

    /// Native pixels summed into one simulated pixel of `pitch_u_mm` × `pitch_v_mm`
    /// (≥ 1; 1 without a native pitch). See [`Readout::native_pitch_mm`].
    pub fn binning(&self, pitch_u_mm: f64, pitch_v_mm: f64) -> f64 {
        self.native_pitch_mm
            .map_or(1.0, |p| (pitch_u_mm * pitch_v_mm / (p * p)).max(1.0))
    }

    /// Reads out row `r` of channel `channel` in place, for simulated pixels that sum
    /// `binning` native pixels. `frame_seed`: the frame's seed (electronic noise, rounding
    /// to ADC codes); `None`: the noiseless expectation (no electronic noise, no rounding,
    /// but the same gain, offset and clipping).
    pub(crate) fn apply_row(
        &self,
        row: &mut [f64],
        r: usize,
        channel: usize,
        frame_seed: Option<u64>,
        binning: f64,
    ) {
        let (x, y, se) = (
            self.gain_nonuniformity,
            self.offset_nonuniformity_adu * binning.sqrt(),
            self.electronic_noise_adu * binning.sqrt(),
        );
        let offset = self.offset_adu * binning;
        // One map draw per pixel: the gain from its high 32 bits, the offset from its low.
        let mut maps =
            (x > 0.0 || y > 0.0).then(|| noise::stream(self.map_seed, Stage::Maps, channel, r));
        let mut elec = frame_seed
            .filter(|_| se > 0.0)
            .map(|s| noise::stream(s, Stage::Electronic, channel, r));
        let sat = self.saturation_adu.map_or(f64::INFINITY, |s| s * binning);
        let max = self.max_code().map(|m| m * binning);
        for v in row.iter_mut() {
            let mut s = *v;
            if let Some(m) = maps.as_mut() {
                let bits: u64 = m.random();
                let unit = |b: u64| (b as f64 + 0.5) / 4_294_967_296.0; // (0, 1)
                s = s * (1.0 + x * (2.0 * unit(bits >> 32) - 1.0))
                    + offset
                    + y * (2.0 * unit(bits & 0xffff_ffff) - 1.0);
            } else {
                s += offset;
            }
            if let Some(e) = elec.as_mut() {
                s += se * noise::normal(e);
            }
            s = s.min(sat);
            if let Some(m) = max {
                s = s.clamp(0.0, m);
                if frame_seed.is_some() {
                    // Round half up (s ≥ 0 here; `as` truncates, a fast floor).
                    s = (s + 0.5) as u64 as f64;
                }
            }
            *v = s;
        }
    }
}

fn bad(msg: String) -> SimError {
    SimError::OutOfRange(msg)
}
