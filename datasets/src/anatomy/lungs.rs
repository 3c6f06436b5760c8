//! Lungs (shaped by the thoracic cavity, the mediastinum and the hemidiaphragm domes),
//! lung nodules, and the stomach gas bubble under the left dome.

use super::patient::{CAVITY_P, Params, lerp, rng, stream};
use super::shapes::{Dome, Section, Shape};
use super::tissue::Material;
use super::{NoduleInfo, Scene, Structure, Tissue};
use glam::{DMat3, DVec3, EulerRot};
use rand::Rng;

/// The two lungs: the thoracic cavity on each side of the mediastinum, cut from below by
/// the hemidiaphragm domes. Their apex is where the cavity narrows to the mediastinum.
pub(crate) struct Lungs {
    right: Section,
    left: Section,
}

impl Lungs {
    pub fn new(p: &Params) -> Self {
        let n = 56;
        let keys: Vec<_> = (0..=n)
            .map(|i| p.cavity(lerp(p.z_base, p.z_apex, i as f64 / n as f64)))
            .collect();
        let b_e = (p.yp_e - p.ya_e) / 2.0;
        let cy_e = (p.yp_e + p.ya_e) / 2.0;
        let lung = |side: f64, height: f64| Section {
            keys: keys.clone(),
            p_ant: CAVITY_P.0,
            p_post: CAVITY_P.1,
            side,
            dome: Some(Dome {
                zb: p.z_base,
                height,
                cx: side * 0.45 * p.a_e,
                cy: cy_e - 0.1 * b_e,
                rx: 0.55 * p.a_e,
                ry: 0.95 * b_e,
            }),
        };
        Lungs {
            right: lung(-1.0, p.dome_h[0]),
            left: lung(1.0, p.dome_h[1]),
        }
    }

    /// +1 if `q` is inside the left lung's envelope, −1 inside the right one's.
    pub fn side_of(&self, q: DVec3) -> Option<f64> {
        if q.x >= 0.0 && self.left.contains(q) {
            Some(1.0)
        } else if q.x < 0.0 && self.right.contains(q) {
            Some(-1.0)
        } else {
            None
        }
    }

    /// Phase 4: parenchyma, denser posteriorly (gravity-dependent in a supine patient).
    pub fn paint(&self, sc: &mut Scene, p: &Params) {
        let b_e = (p.yp_e - p.ya_e) / 2.0;
        let mut m = Material::of(Tissue::Lung);
        m.y0 = ((p.yp_e + p.ya_e) / 2.0) as f32;
        m.grad_y = (70.0 / (2.0 * b_e)) as f32;
        let mat = sc.material(m);
        sc.add_mat(
            Shape::Section(self.right.clone()),
            mat,
            Structure::LungRight,
        );
        sc.add_mat(Shape::Section(self.left.clone()), mat, Structure::LungLeft);
    }
}

/// Phase 10: 0–3 nodules of 3–30 mm (log-uniform diameter), 0–100 HU, slightly
/// ellipsoidal, at random places inside the lungs (`free` tells lung from everything
/// else). Returns what was placed.
pub(crate) fn nodules(
    sc: &mut Scene,
    p: &Params,
    seed: u64,
    free: &dyn Fn(DVec3, f64) -> bool,
) -> Vec<NoduleInfo> {
    let mut r = rng(seed, stream::NODULES);
    let mut out = Vec::new();
    for _ in 0..p.nodule_count {
        let side = if r.random_bool(0.5) { 1.0 } else { -1.0 };
        let mut d = r.random_range(3f64.ln()..30f64.ln()).exp();
        let hu: f64 = r.random_range(0.0..100.0);
        let stretch = DVec3::new(
            r.random_range(0.85..1.15),
            r.random_range(0.85..1.15),
            r.random_range(0.85..1.15),
        );
        // Unit geometric mean: `d` is the diameter of the sphere of the same volume.
        let stretch = stretch / (stretch.x * stretch.y * stretch.z).cbrt();
        let rot = DMat3::from_euler(
            EulerRot::ZXZ,
            r.random_range(0.0..std::f64::consts::TAU),
            r.random_range(0.0..std::f64::consts::PI),
            r.random_range(0.0..std::f64::consts::TAU),
        );
        let mut placed = None;
        'size: for _ in 0..4 {
            let reach = 0.5 * d * stretch.max_element();
            for _ in 0..300 {
                let c = DVec3::new(
                    side * r.random_range(0.0..p.a_e),
                    r.random_range(p.ya_e..p.yp_e),
                    r.random_range(p.z_base..p.z_apex),
                );
                let probes = [
                    DVec3::X,
                    -DVec3::X,
                    DVec3::Y,
                    -DVec3::Y,
                    DVec3::Z,
                    -DVec3::Z,
                ];
                if free(c, side) && probes.iter().all(|&o| free(c + o * reach, side)) {
                    placed = Some(c);
                    break 'size;
                }
            }
            d = (0.7 * d).max(3.0);
        }
        let Some(c) = placed else { continue };
        let mut m = Material::of(Tissue::Nodule);
        m.mean = hu as f32;
        let mat = sc.material(m);
        sc.add_mat(
            Shape::ellipsoid(c, stretch * (d / 2.0), rot),
            mat,
            Structure::Nodule,
        );
        out.push(NoduleInfo {
            centre_mm: c.to_array(),
            diameter_mm: d,
            hu,
        });
    }
    out
}

/// Phase 12: a gas bubble in the stomach fundus under the left dome (most patients).
pub(crate) fn stomach_gas(sc: &mut Scene, p: &Params) {
    if !p.stomach_gas {
        return;
    }
    let b_e = (p.yp_e - p.ya_e) / 2.0;
    let cy_e = (p.yp_e + p.ya_e) / 2.0;
    sc.add(
        Shape::ellipsoid(
            DVec3::new(
                0.42 * p.a_e,
                cy_e - 0.15 * b_e,
                p.z_base + p.dome_h[1] - 40.0 * p.s,
            ),
            DVec3::new(30.0, 24.0, 13.0) * p.s,
            DMat3::IDENTITY,
        ),
        Tissue::Air,
        Structure::StomachGas,
    );
}
