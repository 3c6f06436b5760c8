//! What a pixel records: the line integral, the transmission or the intensity.

use crate::error::{Result, SimError};
use serde::{Deserialize, Serialize};

/// What a pixel records.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Quantity {
    /// The line integral L = ∫mu ds (dimensionless).
    LineIntegral,
    /// exp(−L), in [0, 1]; underflows to 0 (never NaN) beyond L ≈ 745.
    Transmission,
    /// I0 · exp(−L).
    Intensity {
        /// Unattenuated intensity (any unit; e.g. photons per pixel).
        i0: f64,
    },
}

impl Quantity {
    /// The quantity names scenes, the command line and Python accept.
    pub const NAMES: &'static str = "line-integral, transmission or intensity";

    /// The quantity called `name` (`line-integral`, `transmission` or `intensity`; any
    /// case, `_` for `-`); `i0` is the intensity's unattenuated value (unused otherwise).
    /// Checked ([`Quantity::validate`]).
    pub fn from_name(name: &str, i0: f64) -> Result<Self> {
        let q = match name.trim().to_ascii_lowercase().replace('_', "-").as_str() {
            "line-integral" => Self::LineIntegral,
            "transmission" => Self::Transmission,
            "intensity" => Self::Intensity { i0 },
            _ => return Err(SimError::unknown_name("quantity", name, Self::NAMES)),
        };
        q.validate()?;
        Ok(q)
    }

    /// Converts one line integral.
    #[inline]
    pub fn from_line_integral(&self, l: f64) -> f64 {
        match *self {
            Self::LineIntegral => l,
            Self::Transmission => (-l).exp(),
            Self::Intensity { i0 } => i0 * (-l).exp(),
        }
    }

    /// Checks parameters (I0 finite and > 0).
    pub fn validate(&self) -> Result<()> {
        // Images are f32: an open-beam value beyond f32's range would be +Inf.
        if let Self::Intensity { i0 } = *self
            && !(i0.is_finite() && i0 > 0.0 && i0 <= f64::from(f32::MAX))
        {
            return Err(SimError::OutOfRange(format!(
                "I0 = {i0}; it must be finite, > 0 and at most {:e} (images are float32)",
                f32::MAX
            )));
        }
        Ok(())
    }
}
