//! Flat- and dark-field correction and the −log, as a clinical preprocessing chain does.
//!
//! * transmission T = (raw − dark)/(flat − dark), per pixel and channel; it may be ≤ 0 or
//!   > 1 where noise says so and is returned as it is;
//! * line integral L = −ln(max(T, ε)), ε = floor/(flat − dark). For a detector whose signal
//!   comes in units (quantum noise, electronic noise or an ADC: [`FlatField::HALF_UNIT`]) the
//!   floor is half a signal unit (half an ADC step, half a count): a pixel whose
//!   dark-corrected signal is ≤ 0.5 ADU reads as 0.5 ADU, so L ≤ ln(2·(flat − dark)). A
//!   noiseless detector without an ADC has no such unit: its floor is the smallest positive
//!   f64 ([`FlatField::NOISELESS`]), so L is the exact −ln T of the expected signal. Either
//!   way L is finite: never NaN or +∞. [`FlatField::clipped`] counts the pixels the floor
//!   changed, so a caller can say when photon starvation clipped a line integral.
//!
//! The flat and dark fields come from [`super::DetectorModel::calibrate`]: either the
//! noiseless expectation, or the average of N recorded frames ([`Calibration`]).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::render::Projection;

/// How flat and dark fields are acquired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct Calibration {
    /// Open-beam frames averaged into the flat field; 0: the noiseless expectation.
    #[serde(default)]
    pub flat_frames: u32,
    /// Dark frames (no beam) averaged into the dark field; 0: the noiseless expectation.
    #[serde(default)]
    pub dark_frames: u32,
}

impl Calibration {
    /// The most frames a flat or dark field averages (each is a whole noisy image; a
    /// thousand already leave a calibration noise far below any frame's).
    pub const MAX_FRAMES: u32 = 10_000;

    /// Checks the frame counts against [`Self::MAX_FRAMES`].
    pub fn validate(&self) -> Result<()> {
        for (name, n) in [
            ("flat_frames", self.flat_frames),
            ("dark_frames", self.dark_frames),
        ] {
            if n > Self::MAX_FRAMES {
                return Err(SimError::OutOfRange(format!(
                    "[detector.calibration] {name} = {n}; at most {} frames are averaged",
                    Self::MAX_FRAMES
                )));
            }
        }
        Ok(())
    }
}

/// What the detector chain returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Output {
    /// The raw signal (ADU or counts).
    Raw,
    /// Flat- and dark-corrected transmission.
    FlatField,
    /// −ln of the corrected transmission (clamped, see the module docs).
    #[default]
    LogLineIntegral,
}

impl Output {
    /// The signal names scenes, the command line and Python accept.
    pub const NAMES: &'static str = "raw, flat-field or log-line-integral";

    /// The output called `name` (`raw`, `flat-field` or `log-line-integral`; any case).
    pub fn from_name(name: &str) -> Result<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "raw" => Ok(Self::Raw),
            "flat-field" => Ok(Self::FlatField),
            "log-line-integral" => Ok(Self::LogLineIntegral),
            _ => Err(SimError::unknown_name("signal", name, Self::NAMES)),
        }
    }
}

/// Flat and dark fields, one image per channel, checked: same sizes, finite, and the flat
/// above the dark everywhere.
#[derive(Debug, Clone, PartialEq)]
pub struct FlatField {
    flat: Vec<Projection>,
    dark: Vec<Projection>,
    floor: f64,
}

impl FlatField {
    /// Checks and keeps the fields.
    pub fn new(flat: Vec<Projection>, dark: Vec<Projection>) -> Result<Self> {
        if flat.is_empty() || flat.len() != dark.len() {
            return Err(bad(format!(
                "{} flat-field and {} dark-field channels; need the same number, ≥ 1",
                flat.len(),
                dark.len()
            )));
        }
        for (ch, (f, d)) in flat.iter().zip(&dark).enumerate() {
            same_size(f, d, "dark field", "flat field")?;
            for (i, (&fv, &dv)) in f.data.iter().zip(&d.data).enumerate() {
                if !(fv.is_finite() && dv.is_finite() && fv > dv) {
                    return Err(bad(format!(
                        "channel {ch}, pixel (row {}, col {}): flat field {fv} is not above \
                         dark field {dv}; the open beam gives no usable signal there (too few \
                         photons for the detector's noise: raise the exposure, mas)",
                        i / f.cols,
                        i % f.cols
                    )));
                }
            }
        }
        Ok(Self {
            flat,
            dark,
            floor: Self::HALF_UNIT,
        })
    }

    /// The −log floor of a detector with a signal unit: half an ADU or half a count.
    pub const HALF_UNIT: f64 = 0.5;
    /// The −log floor of a noiseless detector without an ADC: no unit, only L < ∞.
    pub const NOISELESS: f64 = f64::MIN_POSITIVE;

    /// The same fields with the −log floor `floor` (dark-corrected signal units, > 0): see
    /// the module docs.
    pub fn with_floor(mut self, floor: f64) -> Result<Self> {
        if !(floor.is_finite() && floor > 0.0) {
            return Err(bad(format!(
                "−log floor is {floor}; it must be finite and > 0"
            )));
        }
        self.floor = floor;
        Ok(self)
    }

    /// The −log floor, in dark-corrected signal units (ADU or counts).
    pub fn floor(&self) -> f64 {
        self.floor
    }

    /// Pixels of `raw` (all channels) whose dark-corrected signal is at or below the −log
    /// floor: their line integrals read ln((flat − dark)/floor), not the object's.
    pub fn clipped(&self, raw: &[Projection]) -> usize {
        raw.iter()
            .zip(self.dark.iter())
            .map(|(r, d)| {
                r.data
                    .iter()
                    .zip(&d.data)
                    .filter(|&(&r, &d)| f64::from(r) - f64::from(d) <= self.floor)
                    .count()
            })
            .sum()
    }

    /// Flat fields, one per channel.
    pub fn flat(&self) -> &[Projection] {
        &self.flat
    }

    /// Dark fields, one per channel.
    pub fn dark(&self) -> &[Projection] {
        &self.dark
    }

    /// Corrects raw channels into the requested output.
    pub fn apply(&self, raw: &[Projection], output: Output) -> Result<Vec<Projection>> {
        if raw.len() != self.flat.len() {
            return Err(bad(format!(
                "{} raw channels but {} calibrated channels",
                raw.len(),
                self.flat.len()
            )));
        }
        raw.iter()
            .zip(self.flat.iter().zip(&self.dark))
            .map(|(r, (f, d))| match output {
                Output::Raw => Ok(r.clone()),
                Output::FlatField => flat_field_correct(r, f, d),
                Output::LogLineIntegral => log_line_integral_floored(r, f, d, self.floor),
            })
            .collect()
    }
}

/// T = (raw − dark)/(flat − dark) per pixel; errors on mismatched sizes, non-finite
/// values, or flat ≤ dark.
pub fn flat_field_correct(
    raw: &Projection,
    flat: &Projection,
    dark: &Projection,
) -> Result<Projection> {
    map3(raw, flat, dark, |r, f, d| (r - d) / (f - d))
}

/// L = −ln(max(T, `floor`)) for a transmission image; `floor` finite and > 0.
pub fn log_line_integral(transmission: &Projection, floor: f64) -> Result<Projection> {
    if !(floor.is_finite() && floor > 0.0) {
        return Err(bad(format!(
            "transmission floor is {floor}; it must be finite and > 0"
        )));
    }
    let data = transmission
        .data
        .iter()
        .map(|&t| {
            if t.is_nan() {
                Err(bad("transmission image holds NaN".into()))
            } else {
                Ok(-f64::from(t).max(floor).ln() as f32)
            }
        })
        .collect::<Result<_>>()?;
    Ok(Projection {
        rows: transmission.rows,
        cols: transmission.cols,
        data,
    })
}

/// −ln(max(T, 0.5/(flat − dark))) straight from raw, flat and dark (the floor of a detector
/// with a signal unit, [`FlatField::HALF_UNIT`]).
pub fn log_line_integral_clamped(
    raw: &Projection,
    flat: &Projection,
    dark: &Projection,
) -> Result<Projection> {
    log_line_integral_floored(raw, flat, dark, FlatField::HALF_UNIT)
}

fn log_line_integral_floored(
    raw: &Projection,
    flat: &Projection,
    dark: &Projection,
    floor: f64,
) -> Result<Projection> {
    map3(raw, flat, dark, |r, f, d| {
        let open = f - d;
        -((r - d) / open).max(floor / open).ln()
    })
}

fn map3(
    raw: &Projection,
    flat: &Projection,
    dark: &Projection,
    op: impl Fn(f64, f64, f64) -> f64 + Sync,
) -> Result<Projection> {
    same_size(raw, flat, "raw image", "flat field")?;
    same_size(raw, dark, "raw image", "dark field")?;
    let data = (0..raw.data.len())
        .into_par_iter()
        .map(|i| {
            let (r, f, d) = (
                f64::from(raw.data[i]),
                f64::from(flat.data[i]),
                f64::from(dark.data[i]),
            );
            if !(r.is_finite() && f.is_finite() && d.is_finite() && f > d) {
                return Err(bad(format!(
                    "pixel (row {}, col {}): raw {r}, flat {f}, dark {d}; all must be finite \
                     and the flat above the dark",
                    i / raw.cols,
                    i % raw.cols
                )));
            }
            Ok(op(r, f, d) as f32)
        })
        .collect::<Result<_>>()?;
    Ok(Projection {
        rows: raw.rows,
        cols: raw.cols,
        data,
    })
}

fn same_size(a: &Projection, b: &Projection, an: &str, bn: &str) -> Result<()> {
    if a.rows != b.rows || a.cols != b.cols || a.data.len() != a.rows * a.cols {
        return Err(bad(format!(
            "{an} is {} × {} but {bn} is {} × {}",
            a.rows, a.cols, b.rows, b.cols
        )));
    }
    if b.data.len() != b.rows * b.cols {
        return Err(bad(format!("{bn} data length does not match its size")));
    }
    Ok(())
}

fn bad(msg: String) -> SimError {
    SimError::OutOfRange(msg)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(v: &[f32]) -> Projection {
        Projection {
            rows: 1,
            cols: v.len(),
            data: v.to_vec(),
        }
    }

    #[test]
    fn zero_and_negative_counts_give_finite_line_integrals() {
        // flat − dark = 100: floor 0.005, L ≤ ln 200.
        let l = log_line_integral_clamped(
            &img(&[0.0, -3.0, 10.0, 110.0]),
            &img(&[110.0; 4]),
            &img(&[10.0; 4]),
        )
        .unwrap();
        let cap = (200.0f64).ln() as f32;
        assert_eq!(l.data[0], cap);
        assert_eq!(l.data[1], cap);
        assert_eq!(l.data[2], cap); // raw = dark: zero signal
        assert_eq!(l.data[3], 0.0);
        assert!(log_line_integral(&img(&[0.0]), 0.0).is_err());
        assert_eq!(
            log_line_integral(&img(&[0.0]), 0.25).unwrap().data[0],
            4f32.ln()
        );
    }

    #[test]
    fn the_floor_is_half_a_unit_or_none_and_clipping_is_counted() {
        let (flat, dark) = (img(&[110.0; 3]), img(&[10.0; 3]));
        // 0.2 ADU of signal: below half a unit, above the noiseless floor.
        let raw = vec![img(&[10.2, 60.0, 10.0])];
        let unit = FlatField::new(vec![flat.clone()], vec![dark.clone()]).unwrap();
        let l = unit.apply(&raw, Output::LogLineIntegral).unwrap();
        assert_eq!(l[0].data[0], (200.0f64).ln() as f32);
        assert_eq!(unit.clipped(&raw), 2);
        let exact = unit.with_floor(FlatField::NOISELESS).unwrap();
        let l = exact.apply(&raw, Output::LogLineIntegral).unwrap();
        assert!(
            (l[0].data[0] - (500.0f32).ln()).abs() < 1e-4,
            "{}",
            l[0].data[0]
        );
        assert!(l[0].data[2].is_finite() && l[0].data[2] > 700.0);
        assert_eq!(exact.clipped(&raw), 1); // only the pixel with no signal at all
        assert!(exact.with_floor(0.0).is_err());
    }

    #[test]
    fn flat_not_above_dark_is_an_error() {
        let e = flat_field_correct(&img(&[1.0]), &img(&[5.0]), &img(&[5.0])).unwrap_err();
        assert!(e.to_string().contains("flat"), "{e}");
        assert!(FlatField::new(vec![img(&[5.0, 2.0])], vec![img(&[1.0, 3.0])]).is_err());
        assert!(flat_field_correct(&img(&[1.0]), &img(&[5.0, 6.0]), &img(&[0.0])).is_err());
    }
}
