//! Body outline and soft-tissue layers: torso, neck, head, breasts and arms (fat, then
//! muscle), the viscera filling the thoracic cavity and upper abdomen, and the mediastinal
//! fat and paravertebral muscle that bound the lungs medially.

use super::patient::{BODY_P, CAVITY_P, Params, lerp, smoothstep};
use super::shapes::{SecKey, Section, Shape};
use super::{ArmPose, Scene, Structure, Tissue};
use glam::{DMat3, DVec3};

/// One arm: humeral head, elbow and hand positions and the limb radii (skin).
#[derive(Debug, Clone)]
pub(crate) struct Arm {
    pub side: f64,
    pub head: DVec3,
    pub elbow: DVec3,
    pub hand: DVec3,
    pub r_upper: f64,
    pub r_fore: f64,
    pub fat: f64,
}

/// Both arms (right, left) for the sampled pose.
pub(crate) fn arm_geometry(p: &Params) -> [Arm; 2] {
    let (w, d, s, sv) = (p.width / 2.0, p.depth, p.s, p.sv);
    let r_upper = 33.0 * sv + 0.5 * p.fat;
    let r_fore = 27.0 * sv + 0.3 * p.fat;
    [-1.0, 1.0].map(|side| {
        let (head, elbow, hand) = match p.arms {
            ArmPose::Down => {
                let head = DVec3::new(side * (0.93 * w - 8.0), 0.04 * d, p.z_apex - 18.0 * sv);
                let elbow =
                    DVec3::new(side * (w + r_upper + 8.0 * s), 0.06 * d, head.z - 290.0 * s);
                let hand = DVec3::new(elbow.x + side * 5.0, 0.02 * d, elbow.z - 260.0 * s);
                (head, elbow, hand)
            }
            ArmPose::Raised => {
                let head = DVec3::new(side * 0.9 * w, 0.04 * d, p.z_apex + 2.0);
                let ex = (0.72 * w).max(75.0 * sv + r_upper + 12.0);
                let elbow = DVec3::new(side * ex, 0.06 * d, head.z + 280.0 * s);
                let hand = DVec3::new(-side * 25.0 * s, 0.02 * d, elbow.z + 90.0 * s);
                (head, elbow, hand)
            }
        };
        Arm {
            side,
            head,
            elbow,
            hand,
            r_upper,
            r_fore,
            fat: 0.5 * p.fat + 2.0,
        }
    })
}

/// Keys of `f` at `n + 1` heights from `z0` to `z1`, preceded by one far below (the
/// section is constant down there).
fn keys(f: impl Fn(f64) -> SecKey, z0: f64, z1: f64, n: usize, far_below: bool) -> Vec<SecKey> {
    let mut k = Vec::with_capacity(n + 2);
    if far_below {
        k.push(f(z0 - 2000.0));
    }
    k.extend((0..=n).map(|i| f(lerp(z0, z1, i as f64 / n as f64))));
    k
}

fn section(keys: Vec<SecKey>, p: (f64, f64)) -> Shape {
    Shape::Section(Section {
        keys,
        p_ant: p.0,
        p_post: p.1,
        side: 0.0,
        dome: None,
    })
}

fn torso_keys(p: &Params, shrink: [f64; 3]) -> Vec<SecKey> {
    keys(
        |z| {
            let mut k = p.torso(z);
            k.a = (k.a - shrink[0]).max(5.0);
            k.ba = (k.ba - shrink[1]).max(5.0);
            k.bp = (k.bp - shrink[2]).max(5.0);
            k
        },
        p.z_base - 0.45 * p.lung_h,
        p.z_apex + 55.0,
        64,
        true,
    )
}

fn neck_keys(p: &Params, extra: f64) -> Vec<SecKey> {
    let (cy, a, ba, bp) = p.neck();
    [p.z_apex + 10.0, p.z_neck_top() + 30.0]
        .map(|z| SecKey {
            z,
            cx: 0.0,
            cy,
            a: a + extra,
            ba: ba + extra,
            bp: bp + extra,
            xm: 0.0,
        })
        .to_vec()
}

/// Centre and semi-axes of the head (skin).
pub(crate) fn head(p: &Params) -> (DVec3, DVec3) {
    let (cy, ..) = p.neck();
    (
        DVec3::new(0.0, cy - 5.0 * p.s, p.z_neck_top() + 80.0 * p.sv),
        DVec3::new(72.0, 88.0, 98.0) * p.sv,
    )
}

/// Centre and semi-axes of the breasts (right, left).
fn breasts(p: &Params) -> [(DVec3, DVec3); 2] {
    let z = p.z_base + p.dome_h[0] + 15.0 * p.s;
    [-1.0, 1.0].map(|side| {
        let x = side * 0.42 * p.width / 2.0;
        let front = p.torso_front(x, z);
        (
            DVec3::new(x, front + 12.0 * p.s, z),
            DVec3::new(58.0 * p.s, 38.0 * p.s * p.breast, 55.0 * p.s),
        )
    })
}

fn arm_tubes(sc: &mut Scene, arms: &[Arm; 2], shrink: f64, tissue: Tissue, st: Structure) {
    for arm in arms {
        let (ru, rf) = (arm.r_upper - shrink, arm.r_fore - shrink);
        sc.add(
            Shape::Tube {
                a: arm.head,
                b: arm.elbow,
                ra: ru,
                rb: 0.85 * ru,
            },
            tissue,
            st,
        );
        sc.add(
            Shape::Tube {
                a: arm.elbow,
                b: arm.hand,
                ra: rf,
                rb: 0.7 * rf,
            },
            tissue,
            st,
        );
        // Shoulder cap (deltoid).
        let out = DVec3::new(arm.side * 6.0, 0.0, 4.0);
        sc.add(
            Shape::ellipsoid(
                arm.head + out,
                DVec3::new(ru + 4.0, ru + 2.0, ru + 12.0),
                DMat3::IDENTITY,
            ),
            tissue,
            st,
        );
    }
}

/// Phase 1: subcutaneous fat — the body outline.
pub(crate) fn outline(sc: &mut Scene, p: &Params, arms: Option<&[Arm; 2]>) {
    sc.add(
        section(torso_keys(p, [0.0; 3]), BODY_P),
        Tissue::Fat,
        Structure::SubcutaneousFat,
    );
    sc.add(
        section(neck_keys(p, 0.0), (2.0, 2.0)),
        Tissue::Fat,
        Structure::SubcutaneousFat,
    );
    let (c, semi) = head(p);
    sc.add(
        Shape::ellipsoid(c, semi, DMat3::IDENTITY),
        Tissue::Fat,
        Structure::Head,
    );
    if p.female {
        for (c, semi) in breasts(p) {
            sc.add(
                Shape::ellipsoid(c, semi, DMat3::IDENTITY),
                Tissue::Fat,
                Structure::Breast,
            );
        }
    }
    if let Some(arms) = arms {
        arm_tubes(sc, arms, 0.0, Tissue::Fat, Structure::SubcutaneousFat);
    }
}

/// Phase 2: muscle under the fat; glandular breast tissue.
pub(crate) fn muscle(sc: &mut Scene, p: &Params, arms: Option<&[Arm; 2]>) {
    let f = p.fat;
    sc.add(
        section(torso_keys(p, [f, f, 0.8 * f]), BODY_P),
        Tissue::Muscle,
        Structure::Muscle,
    );
    sc.add(
        section(neck_keys(p, -0.5 * f), (2.0, 2.0)),
        Tissue::Muscle,
        Structure::Muscle,
    );
    if p.female {
        for (c, semi) in breasts(p) {
            sc.add(
                Shape::ellipsoid(
                    c + DVec3::new(0.0, 0.15 * semi.y, 0.0),
                    semi * DVec3::new(0.55, 0.5, 0.55),
                    DMat3::IDENTITY,
                ),
                Tissue::SoftTissue,
                Structure::Breast,
            );
        }
    }
    if let Some(arms) = arms {
        arm_tubes(sc, arms, arms[0].fat, Tissue::Muscle, Structure::Muscle);
    }
}

/// Phase 3: soft tissue filling the thoracic cavity and the upper abdomen.
pub(crate) fn viscera(sc: &mut Scene, p: &Params) {
    sc.add(
        section(
            keys(|z| p.cavity(z), p.z_base, p.z_apex, 48, true),
            CAVITY_P,
        ),
        Tissue::SoftTissue,
        Structure::Viscera,
    );
}

/// Phase 5: mediastinal fat between the lungs and the paravertebral muscles beside the
/// spine. Returns both shapes (they bound the lungs for tree growth and nodules).
pub(crate) fn mediastinum(sc: &mut Scene, p: &Params) -> Vec<Shape> {
    let band = section(
        keys(
            |z| {
                let e = p.cavity(z);
                let (_, b_vb) = p.vertebra(z);
                let y0 = e.cy - e.ba - 4.0;
                let y1 = p.spine_y(z) + 0.3 * b_vb;
                let half = (y1 - y0) / 2.0;
                SecKey {
                    z,
                    cx: 2.0 * p.s,
                    cy: (y0 + y1) / 2.0,
                    a: p.s * lerp(18.0, 26.0, smoothstep(0.55, 0.9, p.t(z))),
                    ba: half,
                    bp: half,
                    xm: 0.0,
                }
            },
            p.z_base,
            p.z_apex + 5.0,
            32,
            false,
        ),
        (2.0, 2.0),
    );
    let para = section(
        keys(
            |z| {
                let e = p.cavity(z);
                let (a_vb, b_vb) = p.vertebra(z);
                let cy = p.spine_y(z) + b_vb + p.r_canal + 6.0;
                let b = (e.cy + e.bp + 6.0 - cy).max(16.0 * p.s);
                SecKey {
                    z,
                    cx: 0.0,
                    cy,
                    a: a_vb + 18.0 * p.s,
                    ba: b,
                    bp: b,
                    xm: 0.0,
                }
            },
            p.z_base - 60.0,
            p.z_apex + 10.0,
            32,
            false,
        ),
        (2.0, 2.0),
    );
    sc.add(band.clone(), Tissue::Fat, Structure::Mediastinum);
    sc.add(para.clone(), Tissue::Muscle, Structure::Muscle);
    vec![band, para]
}
