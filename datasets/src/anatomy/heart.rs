//! Heart: pericardial fat, myocardium, chambers (the great vessels leaving it:
//! [`super::great_vessels`]).

use super::mediastinum::trachea_y;
use super::patient::Params;
use super::shapes::Shape;
use super::{Scene, Structure, Tissue, frame};
use glam::{DMat3, DQuat, DVec3};

/// Heart geometry and cardiac landmarks.
pub(crate) struct Heart {
    pub centre: DVec3,
    rot: DMat3,
    semi: DVec3,
    /// Half extents of the heart's bounding box.
    ext: DVec3,
    pub la: DVec3,
    pub ra: DVec3,
    pub rv_apex: DVec3,
    pub aortic_root: DVec3,
    pub pa_root: DVec3,
    /// Venous path from the left subclavian vein to the right atrium (used by the
    /// pacemaker leads): subclavian, left brachiocephalic vein, SVC.
    pub venous_path: Vec<DVec3>,
}

impl Heart {
    pub fn new(p: &Params) -> Self {
        let s = p.s;
        let hs = p.sv * p.heart_scale;
        let semi = DVec3::new(58.0, 44.0, 38.0) * hs;
        // Long axis from the base (right, posterior, superior) to the apex (left,
        // anterior, inferior).
        let u = DQuat::from_rotation_z(p.heart_turn) * DVec3::new(0.62, -0.55, -0.55);
        let rot = frame(u, DVec3::Z);
        let (_, ext) = Shape::ellipsoid(DVec3::ZERO, semi, rot).bounds();
        let z_dia = p.z_base + (p.dome_h[0] + p.dome_h[1]) / 2.0;
        let o = p.heart_off;
        let centre = DVec3::new(
            14.0 * s + o.x,
            p.ya_e + ext.y + 4.0 + o.y,
            z_dia + 0.85 * ext.z + o.z,
        );
        let at = |f: DVec3| centre + f * ext;
        let z_arch = p.z_thoracic(3.4);
        let ytr = trachea_y(p, z_arch);
        let w = p.width / 2.0;
        let venous_path = vec![
            DVec3::new(0.8 * w, -0.02 * p.depth, p.z_apex - 30.0 * s),
            DVec3::new(70.0 * s, ytr - 20.0 * s, p.z_apex - 6.0 * s),
            DVec3::new(30.0 * s, ytr - 14.0 * s, p.z_jugular() + 10.0 * s),
            DVec3::new(10.0 * s, ytr - 32.0 * s, z_arch + 20.0 * s),
            DVec3::new(-36.0 * s, ytr - 18.0 * s, z_arch + 12.0 * s),
            DVec3::new(-38.0 * s, ytr - 16.0 * s, z_arch - 30.0 * s),
        ];
        let ra = at(DVec3::new(-0.6, 0.05, 0.15));
        let mut heart = Heart {
            centre,
            rot,
            semi,
            ext,
            la: at(DVec3::new(0.05, 0.55, 0.25)),
            ra,
            rv_apex: at(DVec3::new(0.25, -0.6, -0.45)),
            aortic_root: at(DVec3::new(-0.15, 0.05, 0.55)),
            pa_root: at(DVec3::new(0.1, -0.35, 0.6)),
            venous_path,
        };
        heart
            .venous_path
            .push(ra + DVec3::new(0.0, 0.0, 0.3 * heart.ext.z));
        heart
    }

    /// The pericardial sac (the heart with its fat), which lungs must stay out of.
    pub fn pericardium(&self) -> Shape {
        Shape::ellipsoid(self.centre, self.semi + 5.0, self.rot)
    }

    /// Phase 6: pericardial fat, myocardium, blood in the chambers.
    pub fn paint(&self, sc: &mut Scene) {
        let (c, r, sm) = (self.centre, self.rot, self.semi);
        sc.add(self.pericardium(), Tissue::Fat, Structure::Heart);
        sc.add(Shape::ellipsoid(c, sm, r), Tissue::Heart, Structure::Heart);
        let local = |f: DVec3| c + r * (f * sm);
        let chambers = [
            // Left ventricle, right ventricle (along the long axis).
            (
                local(DVec3::new(0.15, 0.22, 0.0)),
                sm * DVec3::new(0.55, 0.4, 0.45),
            ),
            (
                local(DVec3::new(0.05, -0.45, 0.05)),
                sm * DVec3::new(0.5, 0.25, 0.45),
            ),
        ];
        for (cc, semi) in chambers {
            sc.add(
                Shape::ellipsoid(cc, semi, r),
                Tissue::Blood,
                Structure::Heart,
            );
        }
        for (cc, rad) in [(self.la, 0.34), (self.ra, 0.36)] {
            sc.add(
                Shape::ellipsoid(cc, DVec3::splat(rad * sm.y), DMat3::IDENTITY),
                Tissue::Blood,
                Structure::Heart,
            );
        }
    }
}
