//! A calibrated acquisition set-up — the paper's K = (SAD, SID) — that turns poses into
//! views.

use super::{Detector, Pose, View, ViewBeam};
use crate::error::{Result, SimError};
use crate::volume::Volume;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// The beam of a set-up.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Beam {
    /// Flat-panel cone beam.
    Cone {
        /// Source-to-isocentre distance (SAD), mm.
        sad_mm: f64,
        /// Source-to-detector distance (SID), mm; ≥ SAD.
        sid_mm: f64,
    },
    /// Parallel beam; the detector plane passes through the isocentre and pixel pitch is
    /// measured there.
    Parallel,
}

/// Beam, detector and isocentre: everything but the pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Geometry {
    /// Cone or parallel beam.
    pub beam: Beam,
    /// The flat panel.
    pub detector: Detector,
    /// The point the source rotates about and always faces, world LPS mm.
    pub isocentre: DVec3,
}

/// Largest SAD or SID, mm (100 m, far beyond any X-ray set-up; a source at 1e300 mm
/// loses every digit of the ray directions and renders zeros).
pub const MAX_DISTANCE_MM: f64 = 1e5;

impl Geometry {
    /// Checks distances and the detector.
    pub fn validate(&self) -> Result<()> {
        self.detector.validate()?;
        if !self.isocentre.is_finite() {
            return Err(SimError::InvalidGeometry(format!(
                "isocentre {} is not finite",
                self.isocentre
            )));
        }
        if let Beam::Cone { sad_mm, sid_mm } = self.beam {
            if !(sad_mm.is_finite() && sad_mm > 0.0 && sad_mm <= MAX_DISTANCE_MM) {
                return Err(SimError::InvalidGeometry(format!(
                    "SAD is {sad_mm} mm; it must be finite, > 0 and at most {MAX_DISTANCE_MM} mm \
                     (for rays that are parallel, use a parallel beam)"
                )));
            }
            if !(sid_mm.is_finite() && sid_mm <= MAX_DISTANCE_MM) {
                return Err(SimError::InvalidGeometry(format!(
                    "SID is {sid_mm} mm; it must be finite and at most {MAX_DISTANCE_MM} mm"
                )));
            }
            if sid_mm < sad_mm {
                return Err(SimError::InvalidGeometry(format!(
                    "SID ({sid_mm} mm) is smaller than SAD ({sad_mm} mm): the detector would sit between the source and the isocentre"
                )));
            }
        }
        Ok(())
    }

    /// The view for one pose.
    pub fn view(&self, pose: Pose) -> Result<View> {
        self.validate()?;
        if !(pose.theta_deg.is_finite() && pose.phi_deg.is_finite()) {
            return Err(SimError::InvalidGeometry(format!(
                "pose angles θ = {}, φ = {} must be finite",
                pose.theta_deg, pose.phi_deg
            )));
        }
        let f = pose.frame();
        let d = &self.detector;
        let (beam, plane_centre) = match self.beam {
            Beam::Cone { sad_mm, sid_mm } => (
                ViewBeam::Cone {
                    source: self.isocentre + sad_mm * f.to_source,
                },
                self.isocentre - (sid_mm - sad_mm) * f.to_source,
            ),
            Beam::Parallel => (
                ViewBeam::Parallel {
                    direction: -f.to_source,
                },
                self.isocentre,
            ),
        };
        let centre = plane_centre + d.offset_u_mm * f.u + d.offset_v_mm * f.v;
        let u = d.pitch_u_mm * f.u;
        let v = d.pitch_v_mm * f.v;
        let view = View {
            beam,
            detector_origin: centre
                - 0.5 * (d.cols as f64 - 1.0) * u
                - 0.5 * (d.rows as f64 - 1.0) * v,
            u,
            v,
            rows: d.rows,
            cols: d.cols,
        };
        view.validate()?;
        Ok(view)
    }

    /// Views for several poses.
    pub fn views(&self, poses: &[Pose]) -> Result<Vec<View>> {
        poses.iter().map(|&p| self.view(p)).collect()
    }

    /// The square pixel pitch (mm) at which every corner of `volume` projects onto the
    /// panel in every pose, with a 2 % margin (this geometry's own pitch is ignored). A
    /// line detector (one row or one column) is fitted along its long axis only; a 1 × 1
    /// detector cannot be fitted (give the pitch).
    /// Corners behind a cone-beam source (a source inside the volume) are skipped.
    pub fn fit_pitch(&self, poses: &[Pose], volume: &Volume) -> Result<f64> {
        let mut unit = *self;
        unit.detector.pitch_u_mm = 1.0;
        unit.detector.pitch_v_mm = 1.0;
        let d = unit.detector;
        let (mid_r, mid_c) = ((d.rows as f64 - 1.0) / 2.0, (d.cols as f64 - 1.0) / 2.0);
        let mut pitch: f64 = 0.0;
        for &pose in poses {
            let view = unit.view(pose)?;
            for c in volume.world_corners() {
                if let ViewBeam::Cone { source } = view.beam
                    && (c - source).dot(view.pixel_centre(mid_r, mid_c) - source) <= 0.0
                {
                    continue;
                }
                if let Some((r, col)) = view.project_point(c) {
                    // A line detector (one row or one column) samples one line through the
                    // centre: the volume is fitted along its other axis only.
                    if d.rows > 1 {
                        pitch = pitch.max((r - mid_r).abs() / (d.rows as f64 / 2.0));
                    }
                    if d.cols > 1 {
                        pitch = pitch.max((col - mid_c).abs() / (d.cols as f64 / 2.0));
                    }
                }
            }
        }
        if !(pitch.is_finite() && pitch > 0.0) {
            return Err(SimError::InvalidGeometry(
                "cannot fit the volume on the detector (a 1 × 1 detector, or no corner of the \
                 volume projects onto the panel); give the pixel pitch"
                    .into(),
            ));
        }
        Ok(pitch * 1.02)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cone(sad: f64, sid: f64) -> Geometry {
        Geometry {
            beam: Beam::Cone {
                sad_mm: sad,
                sid_mm: sid,
            },
            detector: Detector::new(3, 5, 2.0),
            isocentre: DVec3::new(1.0, 2.0, 3.0),
        }
    }

    #[test]
    fn cone_view_places_source_and_panel() {
        let v = cone(1000.0, 1500.0).view(Pose::AP).unwrap();
        let ViewBeam::Cone { source } = v.beam else {
            panic!()
        };
        assert!((source - DVec3::new(1.0, -998.0, 3.0)).length() < 1e-9);
        let centre = v.pixel_centre(1.0, 2.0);
        assert!((centre - DVec3::new(1.0, 502.0, 3.0)).length() < 1e-9);
        // Pixel (0,0): patient right (−x) and head (+z) side.
        let p00 = v.pixel_centre(0.0, 0.0);
        assert!(p00.x < centre.x && p00.z > centre.z);
        // The isocentre projects onto the panel centre.
        let (r, c) = v.project_point(DVec3::new(1.0, 2.0, 3.0)).unwrap();
        assert!((r - 1.0).abs() < 1e-9 && (c - 2.0).abs() < 1e-9);
    }

    /// A line detector (1 × 8 or 8 × 1) gets the pitch that fits the cube along its long
    /// axis — the square 8 × 8 panel's, since a cube spans as much along rows as along
    /// columns — not one 8× larger that fits the cube's height into its single row (every
    /// column centre then fell beside the volume); a 1 × 1 detector is refused by name.
    #[test]
    fn line_detectors_are_fitted_along_their_long_axis() {
        let cube = Volume::centred(
            [10; 3],
            DVec3::ONE,
            DVec3::new(1.0, 2.0, 3.0),
            vec![1.0; 1000],
        )
        .unwrap();
        let fit = |rows: usize, cols: usize| {
            let mut g = cone(1000.0, 1500.0);
            g.detector = Detector::new(rows, cols, 1.0);
            g.fit_pitch(&[Pose::AP, Pose::LATERAL], &cube)
        };
        let square = fit(8, 8).unwrap();
        for (r, c) in [(1, 8), (8, 1)] {
            let p = fit(r, c).unwrap();
            assert!(
                (p - square).abs() < 1e-9 * square,
                "{r}×{c}: {p} mm vs {square} mm"
            );
        }
        let e = fit(1, 1).unwrap_err().to_string();
        assert!(e.contains("1 × 1 detector"), "{e}");
    }

    #[test]
    fn impossible_geometry_is_named() {
        let e = cone(1000.0, 900.0).validate().unwrap_err().to_string();
        assert!(
            e.contains("SID (900 mm) is smaller than SAD (1000 mm)"),
            "{e}"
        );
        let e = cone(0.0, 900.0).validate().unwrap_err().to_string();
        assert!(e.contains("SAD is 0 mm"), "{e}");
        let mut g = cone(1000.0, 1500.0);
        g.detector.rows = 0;
        assert!(
            g.validate()
                .unwrap_err()
                .to_string()
                .contains("empty detector")
        );
        g.detector.rows = 4;
        g.detector.pitch_u_mm = -1.0;
        assert!(
            g.validate()
                .unwrap_err()
                .to_string()
                .contains("column pitch is -1 mm")
        );
        let e = cone(1000.0, 1500.0)
            .view(Pose::new(f64::NAN, 0.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("must be finite"), "{e}");
    }
}
