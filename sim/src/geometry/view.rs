//! One projection view in the general form: source (or beam direction), the centre of
//! pixel (0, 0), and the two pixel-step vectors.

use crate::error::{Result, SimError};
use crate::ray::Ray;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Where the rays of a view come from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ViewBeam {
    /// A point source (cone beam). Each ray runs from `source` to a pixel centre, so
    /// nothing behind the detector is integrated.
    Cone {
        /// Source position, world LPS mm.
        source: DVec3,
    },
    /// Parallel rays along `direction` (unit, source → detector) through each pixel
    /// centre; each ray is the whole line.
    Parallel {
        /// Unit beam direction, from source side to detector side.
        direction: DVec3,
    },
}

/// A projection view. Pixel `(r, c)` (row `r`, column `c`) has its centre at
/// `detector_origin + c·u + r·v` (world LPS mm). This form describes any calibrated
/// flat-panel geometry (C-arm projection matrices decompose into it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct View {
    /// The source or beam direction.
    pub beam: ViewBeam,
    /// Centre of pixel (0, 0), world mm.
    pub detector_origin: DVec3,
    /// Step from one column to the next, world mm.
    pub u: DVec3,
    /// Step from one row to the next, world mm.
    pub v: DVec3,
    /// Pixel rows.
    pub rows: usize,
    /// Pixel columns.
    pub cols: usize,
}

impl View {
    /// Checks that the view describes a real detector that the beam can reach.
    pub fn validate(&self) -> Result<()> {
        if self.rows == 0 || self.cols == 0 {
            return Err(SimError::InvalidGeometry(format!(
                "empty detector: {} rows × {} columns",
                self.rows, self.cols
            )));
        }
        for (name, x) in [
            ("detector origin", self.detector_origin),
            ("column step u", self.u),
            ("row step v", self.v),
        ] {
            if !x.is_finite() {
                return Err(SimError::InvalidGeometry(format!(
                    "{name} {x} is not finite"
                )));
            }
        }
        let normal = self.u.cross(self.v);
        if self.u.length() == 0.0
            || self.v.length() == 0.0
            || normal.length() < 1e-9 * self.u.length() * self.v.length()
        {
            return Err(SimError::InvalidGeometry(format!(
                "pixel steps u = {} and v = {} must be non-zero and not parallel",
                self.u, self.v
            )));
        }
        let normal = normal.normalize();
        match self.beam {
            ViewBeam::Cone { source } => {
                if !source.is_finite() {
                    return Err(SimError::InvalidGeometry(format!(
                        "source {source} is not finite"
                    )));
                }
                let dist = (source - self.detector_origin).dot(normal).abs();
                if dist < 1e-6 {
                    return Err(SimError::InvalidGeometry(format!(
                        "the source {source} lies in the detector plane"
                    )));
                }
            }
            ViewBeam::Parallel { direction } => {
                if !direction.is_finite() || (direction.length() - 1.0).abs() > 1e-6 {
                    return Err(SimError::InvalidGeometry(format!(
                        "parallel beam direction {direction} must be a unit vector"
                    )));
                }
                if direction.dot(normal).abs() < 1e-6 {
                    return Err(SimError::InvalidGeometry(format!(
                        "parallel beam direction {direction} lies in the detector plane"
                    )));
                }
            }
        }
        Ok(())
    }

    /// World position (mm) of the centre of pixel `(row, col)`; fractional indices allowed.
    pub fn pixel_centre(&self, row: f64, col: f64) -> DVec3 {
        self.detector_origin + col * self.u + row * self.v
    }

    /// The ray that pixel `(row, col)` records (through its centre).
    pub fn ray(&self, row: f64, col: f64) -> Ray {
        let pixel = self.pixel_centre(row, col);
        match self.beam {
            ViewBeam::Cone { source } => Ray::segment(source, pixel),
            ViewBeam::Parallel { direction } => Ray {
                origin: pixel,
                direction,
                t_min: f64::NEG_INFINITY,
                t_max: f64::INFINITY,
            },
        }
    }

    /// Continuous `(row, col)` where the straight line from the source (or along the beam)
    /// through world point `p` meets the detector; `None` if it never does.
    pub fn project_point(&self, p: DVec3) -> Option<(f64, f64)> {
        let normal = self.u.cross(self.v);
        let (from, dir) = match self.beam {
            ViewBeam::Cone { source } => (source, p - source),
            ViewBeam::Parallel { direction } => (p, direction),
        };
        let denom = dir.dot(normal);
        if denom.abs() < 1e-300 {
            return None;
        }
        let s = (self.detector_origin - from).dot(normal) / denom;
        let hit = from + s * dir - self.detector_origin;
        // Solve hit = col·u + row·v in the detector plane.
        let (uu, uv, vv) = (self.u.dot(self.u), self.u.dot(self.v), self.v.dot(self.v));
        let (hu, hv) = (hit.dot(self.u), hit.dot(self.v));
        let det = uu * vv - uv * uv;
        Some(((uu * hv - uv * hu) / det, (vv * hu - uv * hv) / det))
    }
}
