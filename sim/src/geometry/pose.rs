//! Source pose around the isocentre (the paper's ξ = (θ, φ), Methods 1.2.1).

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// The source's position on a sphere around the isocentre; it always faces the isocentre.
///
/// * `theta_deg` (θ) — gantry angle about the patient's superior axis (+z, LPS), degrees.
///   θ = 0: source **anterior** (at −y), beam travelling posterior: the AP view.
///   θ = 90: source at the patient's **left** (+x): a left-to-right lateral view.
/// * `phi_deg` (φ) — elevation towards the head, degrees: φ = 90 puts the source at +z.
///
/// Unit vector from isocentre to source: `s = (sin θ cos φ, −cos θ cos φ, sin φ)`.
/// Detector "up" (towards row 0) is `w = ∂s/∂φ = (−sin θ sin φ, cos θ sin φ, cos φ)`,
/// i.e. the patient's head for φ = 0. Detector columns run along `u = (−s) × w`, rows
/// along `−w`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Gantry angle θ about +z, degrees.
    pub theta_deg: f64,
    /// Elevation φ towards +z, degrees.
    #[serde(default)]
    pub phi_deg: f64,
}

/// An orthonormal frame attached to a pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseFrame {
    /// Unit vector from the isocentre to the source.
    pub to_source: DVec3,
    /// Unit vector along detector columns (viewer's right, beam's-eye view).
    pub u: DVec3,
    /// Unit vector along detector rows (down).
    pub v: DVec3,
}

impl Pose {
    /// Anterior–posterior view: θ = 0, φ = 0.
    pub const AP: Pose = Pose {
        theta_deg: 0.0,
        phi_deg: 0.0,
    };
    /// Lateral view, source at the patient's left: θ = 90, φ = 0.
    pub const LATERAL: Pose = Pose {
        theta_deg: 90.0,
        phi_deg: 0.0,
    };

    /// A pose from angles in degrees.
    pub fn new(theta_deg: f64, phi_deg: f64) -> Self {
        Self { theta_deg, phi_deg }
    }

    /// The source direction and detector axes of this pose.
    pub fn frame(&self) -> PoseFrame {
        let (st, ct) = self.theta_deg.to_radians().sin_cos();
        let (sp, cp) = self.phi_deg.to_radians().sin_cos();
        let to_source = DVec3::new(st * cp, -ct * cp, sp);
        let up = DVec3::new(-st * sp, ct * sp, cp);
        PoseFrame {
            to_source,
            u: (-to_source).cross(up),
            v: -up,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn ap_and_lateral_frames() {
        let f = Pose::AP.frame();
        assert!(
            close(f.to_source, DVec3::new(0.0, -1.0, 0.0)),
            "AP source anterior"
        );
        assert!(close(f.u, DVec3::X), "AP columns towards patient left");
        assert!(close(f.v, -DVec3::Z), "AP rows towards feet");
        let f = Pose::LATERAL.frame();
        assert!(close(f.to_source, DVec3::X));
        assert!(close(f.u, DVec3::Y), "lateral columns towards posterior");
        assert!(close(f.v, -DVec3::Z));
    }

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        for (t, p) in [(13.0, 0.0), (200.0, 35.0), (-75.0, -60.0), (90.0, 89.0)] {
            let f = Pose::new(t, p).frame();
            for x in [f.to_source, f.u, f.v] {
                assert!((x.length() - 1.0).abs() < 1e-12);
            }
            assert!(f.u.dot(f.v).abs() < 1e-12 && f.u.dot(f.to_source).abs() < 1e-12);
            // Looking from the source (along −s), u × v points away from the source.
            assert!(close(f.u.cross(f.v), -f.to_source));
        }
    }
}
