//! The flat-panel detector: pixel grid, pitch and offsets.

use crate::error::{Result, SimError};
use serde::{Deserialize, Serialize};

/// A flat-panel detector of `rows × cols` pixels.
///
/// **Pixel (0, 0) is the top-left pixel as seen from the source looking at the detector
/// (beam's-eye view)**; columns run to the viewer's right, rows run down. In the AP view
/// (θ = φ = 0) that puts the patient's right on the image's left and the head at the top,
/// as a radiograph is read. Images are stored row-major: pixel `(r, c)` at `r·cols + c`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Detector {
    /// Pixel rows (image height).
    pub rows: usize,
    /// Pixel columns (image width).
    pub cols: usize,
    /// Centre-to-centre distance between columns, mm (at the detector, not the isocentre).
    pub pitch_u_mm: f64,
    /// Centre-to-centre distance between rows, mm.
    pub pitch_v_mm: f64,
    /// Shift of the panel centre along the column direction (viewer's right), mm.
    #[serde(default)]
    pub offset_u_mm: f64,
    /// Shift of the panel centre along the row direction (down), mm.
    #[serde(default)]
    pub offset_v_mm: f64,
}

impl Detector {
    /// A centred square-pixel detector.
    pub fn new(rows: usize, cols: usize, pitch_mm: f64) -> Self {
        Self {
            rows,
            cols,
            pitch_u_mm: pitch_mm,
            pitch_v_mm: pitch_mm,
            offset_u_mm: 0.0,
            offset_v_mm: 0.0,
        }
    }

    /// Checks sizes, pitches and offsets.
    pub fn validate(&self) -> Result<()> {
        if self.rows == 0 || self.cols == 0 {
            return Err(SimError::InvalidGeometry(format!(
                "empty detector: {} rows × {} columns",
                self.rows, self.cols
            )));
        }
        if self.rows.checked_mul(self.cols).is_none_or(|n| n > 1 << 28) {
            return Err(SimError::InvalidGeometry(format!(
                "detector of {} × {} pixels is larger than 2^28 pixels",
                self.rows, self.cols
            )));
        }
        for (name, p) in [("column", self.pitch_u_mm), ("row", self.pitch_v_mm)] {
            if !(p.is_finite() && p > 0.0) {
                return Err(SimError::InvalidGeometry(format!(
                    "detector {name} pitch is {p} mm; it must be finite and > 0"
                )));
            }
        }
        if !(self.offset_u_mm.is_finite() && self.offset_v_mm.is_finite()) {
            return Err(SimError::InvalidGeometry(
                "detector offsets must be finite".into(),
            ));
        }
        Ok(())
    }

    /// Physical width × height of the panel, mm.
    pub fn size_mm(&self) -> (f64, f64) {
        (
            self.cols as f64 * self.pitch_u_mm,
            self.rows as f64 * self.pitch_v_mm,
        )
    }
}
