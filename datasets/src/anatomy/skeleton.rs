//! Bones: spine (vertebral bodies with cortex and marrow, discs, arches, transverse and
//! spinous processes, spinal canal), ribs with costal cartilages, sternum, clavicles,
//! scapulae, arm bones and skull.

use super::body::{Arm, head};
use super::patient::{CAVITY_P, Params};
use super::shapes::Shape;
use super::{Scene, Structure, Tissue, frame, spline};
use glam::{DMat3, DVec3};
use std::f64::consts::PI;

/// Phase 11: the whole skeleton.
pub(crate) fn paint(sc: &mut Scene, p: &Params, arms: Option<&[Arm; 2]>) {
    spine(sc, p);
    for i in 1..=12 {
        for side in [-1.0, 1.0] {
            rib(sc, p, i, side);
        }
    }
    sternum(sc, p);
    for side in [-1.0, 1.0] {
        shoulder_girdle(sc, p, side);
    }
    if let Some(arms) = arms {
        arm_bones(sc, p, arms);
    }
    let (c, semi) = head(p);
    let sv = p.sv;
    sc.add(
        Shape::ellipsoid(c, semi - 3.0 * sv, DMat3::IDENTITY),
        Tissue::Bone,
        Structure::Head,
    );
    sc.add(
        Shape::ellipsoid(c, semi - 9.0 * sv, DMat3::IDENTITY),
        Tissue::SoftTissue,
        Structure::Head,
    );
}

/// A bony tube along a spline: cortex, then marrow `shell` mm inside.
fn bone_path(sc: &mut Scene, ctrl: &[(DVec3, f64)], shell: f64, st: Structure) {
    let (pts, rs) = spline(ctrl, 4.0);
    sc.path(&pts, &rs, Tissue::Bone, st);
    let inner: Vec<f64> = rs.iter().map(|r| (r - shell).max(0.6)).collect();
    sc.path(&pts, &inner, Tissue::Marrow, st);
}

/// Vertebral levels from the skull base to the lumbar spine: (centre z, height).
fn levels(p: &Params) -> Vec<(f64, f64)> {
    let h = p.h_vert;
    let (hc, hl) = (0.78 * h, 1.3 * h);
    let mut lv: Vec<(f64, f64)> = (1..=12).map(|i| (p.z_thoracic(i as f64), h)).collect();
    let mut z = p.z_t1 + 0.5 * (h + hc);
    while z - 0.5 * hc < p.z_neck_top() {
        lv.push((z, hc));
        z += hc;
    }
    let mut z = p.z_thoracic(12.0) - 0.5 * (h + hl);
    while z > p.z_base - 700.0 {
        lv.push((z, hl));
        z -= hl;
    }
    lv.sort_by(|a, b| a.0.total_cmp(&b.0));
    lv
}

fn spine(sc: &mut Scene, p: &Params) {
    let (s, sv, rc) = (p.s, p.sv, p.r_canal);
    let lv = levels(p);
    let (t1, t12) = (p.z_t1 + 0.5 * p.h_vert, p.z_thoracic(12.0) - 0.5 * p.h_vert);
    for &(z, hv) in &lv {
        let (a, b) = p.vertebra(z);
        let (y, yc) = (p.spine_y(z), p.canal_y(z));
        let hb = 0.39 * hv;
        let zcyl =
            |a: f64, b: f64, cy: f64, z0: f64, z1: f64| Shape::z_cylinder(0.0, cy, a, b, z0, z1);
        let v = Structure::Vertebra;
        sc.add(zcyl(a, b, y, z - hb, z + hb), Tissue::Bone, v);
        sc.add(
            zcyl(a - 1.8 * sv, b - 1.8 * sv, y, z - hb + 1.5, z + hb - 1.5),
            Tissue::Marrow,
            v,
        );
        sc.add(
            zcyl(0.96 * a, 0.96 * b, y, z + hb, z + hv - hb),
            Tissue::Cartilage,
            Structure::Disc,
        );
        let ra = rc + 3.5 * sv;
        sc.add(
            zcyl(ra, ra, yc, z - 0.33 * hv, z + 0.33 * hv),
            Tissue::Bone,
            v,
        );
        // Processes: (length of the spinous process in y, its downward slope, reach of the
        // transverse processes).
        let (len, slope, reach) = if z > t1 {
            (15.0 * s, 0.3, 8.0 * sv)
        } else if z < t12 {
            (24.0 * s, 0.15, 16.0 * sv)
        } else {
            (26.0 * s, 0.8, 12.0 * sv)
        };
        for side in [-1.0, 1.0] {
            sc.add(
                Shape::Tube {
                    a: DVec3::new(side * rc, yc - 1.0, z + 0.1 * hv),
                    b: DVec3::new(side * (a + reach), yc + 6.0 * sv, z + 0.1 * hv + 2.0),
                    ra: 4.0 * sv,
                    rb: 3.5 * sv,
                },
                Tissue::Bone,
                v,
            );
        }
        let root = DVec3::new(0.0, yc + rc + 1.0, z);
        sc.add(
            Shape::Tube {
                a: root,
                b: root + DVec3::new(0.0, len, -slope * len),
                ra: 4.5 * sv,
                rb: 3.0 * sv,
            },
            Tissue::Bone,
            v,
        );
    }
    let canal: Vec<DVec3> = lv
        .iter()
        .map(|&(z, _)| DVec3::new(0.0, p.canal_y(z), z))
        .collect();
    sc.path(
        &canal,
        &vec![rc; canal.len()],
        Tissue::SoftTissue,
        Structure::SpinalCanal,
    );
}

/// Height of the sternal attachment of rib `i` (1–7).
fn z_attach(p: &Params, i: usize) -> f64 {
    let zj = p.z_jugular();
    if i == 1 {
        zj - 14.0 * p.sv
    } else {
        zj - (45.0 + (i as f64 - 2.0) * 19.0) * p.sv
    }
}

/// Angle on the rib ring at height z where |x| = `x` on the anterior (`front`) or
/// posterior half.
fn ring_angle(p: &Params, x: f64, z: f64, front: bool) -> f64 {
    let k = p.ring(z);
    let pw = if front { CAVITY_P.0 } else { CAVITY_P.1 };
    let th = (x / k.a).clamp(0.0, 0.97).powf(pw / 2.0).asin();
    if front { PI - th } else { th }
}

/// Rib `i` (1–12) on `side`: from the vertebral body past the transverse process, then
/// around the rib ring, descending towards the front; costal cartilage to the sternum
/// (ribs 1–7) or to the costal margin (8–10); 11 and 12 float.
fn rib(sc: &mut Scene, p: &Params, i: usize, side: f64) {
    let sv = p.sv;
    let zi = p.z_thoracic(i as f64) + 0.35 * p.h_vert;
    let (a, b) = p.vertebra(zi);
    let r = p.r_rib
        * match i {
            1 => 0.85,
            11 | 12 => 0.8,
            _ => 1.0,
        };
    let head = DVec3::new(side * 0.8 * a, p.spine_y(zi) + 0.5 * b, zi);
    let tubercle = DVec3::new(side * (a + 10.0 * sv), p.canal_y(zi) + 3.0 * sv, zi - 1.0);
    let th_s = ring_angle(p, a + 26.0 * sv, zi, false);
    let th_e = [
        2.3, 2.45, 2.45, 2.45, 2.45, 2.45, 2.4, 2.3, 2.15, 2.0, 1.6, 1.25,
    ][i - 1];
    let drop = if i >= 11 {
        25.0
    } else {
        30.0 + 8.0 * (i as f64 - 1.0).min(6.0)
    } * sv;
    let n = (((th_e - th_s) / 0.07).ceil() as usize).max(2);
    let mut ctrl = vec![(head, 0.8 * r), (tubercle, 0.9 * r)];
    for k in 0..=n {
        let u = k as f64 / n as f64;
        let th = th_s + (th_e - th_s) * u;
        let z = zi - 2.0 - drop * u.powf(1.4);
        ctrl.push((p.ring_point(th, z, side), r * (0.9 + 0.2 * u)));
    }
    bone_path(sc, &ctrl, 1.6 * sv, Structure::Rib);
    if i > 10 {
        return;
    }
    let (end, _) = *ctrl.last().unwrap_or(&(head, r));
    let (th_a, z_a) = if i <= 7 {
        let z_a = z_attach(p, i);
        let half = if z_a > p.z_jugular() - 50.0 * sv {
            22.0
        } else {
            14.0
        } * sv;
        (ring_angle(p, half + 1.0, z_a, true), z_a)
    } else {
        (
            2.72 + 0.05 * (10 - i) as f64,
            end.z + (10.0 + 5.0 * (i as f64 - 8.0)) * sv,
        )
    };
    let cart: Vec<(DVec3, f64)> = (0..=8)
        .map(|k| {
            let u = k as f64 / 8.0;
            let th = th_e + (th_a - th_e) * u;
            (p.ring_point(th, end.z + (z_a - end.z) * u, side), 0.85 * r)
        })
        .collect();
    let (pts, rs) = spline(&cart, 4.0);
    sc.path(&pts, &rs, Tissue::Cartilage, Structure::CostalCartilage);
}

/// y of the rib ring's front at the midline (where the sternum lies).
fn front_y(p: &Params, z: f64) -> f64 {
    let k = p.ring(z);
    k.cy - k.ba
}

fn sternum(sc: &mut Scene, p: &Params) {
    let (sv, zj) = (p.sv, p.z_jugular());
    // (top, bottom, half-width, half-thickness) of manubrium, body, xiphoid.
    let parts = [
        (zj, zj - 50.0 * sv, 24.0 * sv, 6.0 * sv),
        (zj - 52.0 * sv, zj - 148.0 * sv, 15.0 * sv, 5.5 * sv),
        (zj - 150.0 * sv, zj - 175.0 * sv, 9.0 * sv, 3.5 * sv),
    ];
    for (k, (z0, z1, hw, ht)) in parts.into_iter().enumerate() {
        let top = DVec3::new(0.0, front_y(p, z0), z0);
        let bot = DVec3::new(0.0, front_y(p, z1), z1);
        let ez = (top - bot).normalize();
        let rot = DMat3::from_cols(DVec3::X, ez.cross(DVec3::X), ez);
        let c = (top + bot) / 2.0;
        let half = DVec3::new(hw, ht, (top - bot).length() / 2.0);
        sc.add(
            Shape::rbox(c, half, 3.0, rot),
            Tissue::Bone,
            Structure::Sternum,
        );
        if k < 2 {
            sc.add(
                Shape::rbox(c, half - 1.6 * sv, 2.0, rot),
                Tissue::Marrow,
                Structure::Sternum,
            );
        }
    }
}

/// Position of the shoulder joint (humeral head) with the arms down.
fn shoulder(p: &Params, side: f64) -> DVec3 {
    DVec3::new(
        side * (0.93 * p.width / 2.0 - 8.0),
        0.04 * p.depth,
        p.z_apex - 18.0 * p.sv,
    )
}

/// Clavicle (S-shaped, sternum to acromion) and scapula (thin triangular plate on the
/// posterolateral chest wall with its spine and glenoid neck).
fn shoulder_girdle(sc: &mut Scene, p: &Params, side: f64) {
    let (s, sv, zj, f) = (p.s, p.sv, p.z_jugular(), p.fat);
    let medial = DVec3::new(side * 20.0 * sv, front_y(p, zj) - 4.0 * sv, zj + 2.0);
    let at = |x: f64, dz: f64, depth: f64| {
        DVec3::new(side * x, p.torso_front(x, zj + dz) + f + depth, zj + dz)
    };
    let acromion = DVec3::new(side * 0.86 * p.width / 2.0, 0.02 * p.depth, zj + 26.0 * sv);
    bone_path(
        sc,
        &[
            (medial, 7.0 * sv),
            (at(55.0 * s, 10.0, 10.0 * s), 6.5 * sv),
            (at(100.0 * s, 20.0, 14.0 * s), 6.5 * sv),
            (acromion, 7.5 * sv),
        ],
        2.5 * sv,
        Structure::Clavicle,
    );
    let (top, bot) = (p.z_thoracic(1.6), p.z_thoracic(7.5));
    let (zc, hh) = ((top + bot) / 2.0, (top - bot) / 2.0);
    let th = 0.78;
    let c0 = p.ring_point(th, zc, side);
    let t = (p.ring_point(th + 0.01, zc, side) - p.ring_point(th - 0.01, zc, side)).normalize();
    let mut n = DVec3::Z.cross(t).normalize();
    if n.dot(c0 - DVec3::new(0.0, p.ring(zc).cy, zc)) < 0.0 {
        n = -n;
    }
    let c = c0 + n * (p.r_rib + 9.0 * sv);
    let rot = DMat3::from_cols(t, n, DVec3::Z);
    let plate =
        |cc: DVec3, hw: f64, hz: f64| Shape::rbox(cc, DVec3::new(hw, 2.5 * sv, hz), 2.0, rot);
    let st = Structure::Scapula;
    sc.add(
        plate(c + DVec3::Z * 0.35 * hh, 45.0 * s, 0.65 * hh),
        Tissue::Bone,
        st,
    );
    sc.add(
        plate(c - DVec3::Z * 0.45 * hh - t * 15.0 * s, 22.0 * s, 0.55 * hh),
        Tissue::Bone,
        st,
    );
    // Spine of the scapula up to the acromion; neck to the glenoid.
    let spine_start = c - t * 40.0 * s + DVec3::Z * 0.55 * hh + n * 3.0;
    sc.add(
        Shape::Tube {
            a: spine_start,
            b: acromion + DVec3::new(0.0, 10.0 * sv, -2.0),
            ra: 5.0 * sv,
            rb: 6.0 * sv,
        },
        Tissue::Bone,
        st,
    );
    let neck = c + t * 45.0 * s + DVec3::Z * 0.7 * hh;
    let joint = shoulder(p, side);
    let glenoid = joint - (joint - neck).normalize_or_zero() * 22.0 * sv;
    sc.add(
        Shape::Tube {
            a: neck,
            b: glenoid,
            ra: 7.0 * sv,
            rb: 9.0 * sv,
        },
        Tissue::Bone,
        st,
    );
}

/// Humerus (head with marrow, shaft with fatty medulla), radius and ulna.
fn arm_bones(sc: &mut Scene, p: &Params, arms: &[Arm; 2]) {
    let sv = p.sv;
    let st = Structure::ArmBone;
    for arm in arms {
        sc.add(
            Shape::ellipsoid(arm.head, DVec3::splat(22.0 * sv), DMat3::IDENTITY),
            Tissue::Bone,
            st,
        );
        sc.add(
            Shape::ellipsoid(arm.head, DVec3::splat(19.5 * sv), DMat3::IDENTITY),
            Tissue::Marrow,
            st,
        );
        for (r, tissue) in [(10.0, Tissue::Bone), (5.0, Tissue::Fat)] {
            sc.add(
                Shape::Tube {
                    a: arm.head,
                    b: arm.elbow,
                    ra: r * sv,
                    rb: 0.9 * r * sv,
                },
                tissue,
                st,
            );
        }
        let f = frame(arm.hand - arm.elbow, DVec3::Y);
        for (off, r) in [(6.0, 6.0), (-6.0, 5.5)] {
            let o = f.y_axis * off * sv;
            sc.add(
                Shape::Tube {
                    a: arm.elbow + o,
                    b: arm.hand + o * 1.3,
                    ra: r * sv,
                    rb: 0.8 * r * sv,
                },
                Tissue::Bone,
                st,
            );
        }
    }
}
