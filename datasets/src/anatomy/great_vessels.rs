//! The great vessels: aorta, pulmonary trunk and arteries, venae cavae, brachiocephalic,
//! jugular and subclavian vessels, carotids; and the oesophagus — placed around the heart
//! and the airways.

use super::heart::Heart;
use super::mediastinum::{esophagus_radius, esophagus_y, trachea_y, z_carina};
use super::patient::Params;
use super::shapes::Shape;
use super::trees::Airways;
use super::{Scene, Structure, Tissue};
use glam::DVec3;

fn vessel(sc: &mut Scene, ctrl: &[(DVec3, f64)], tissue: Tissue, st: Structure) {
    let (pts, rs) = super::spline(ctrl, 6.0);
    sc.path(&pts, &rs, tissue, st);
}

/// Phase 7: great vessels and oesophagus.
pub(crate) fn great_vessels(sc: &mut Scene, p: &Params, h: &Heart, aw: &Airways) {
    let (s, w) = (p.s, p.width / 2.0);
    let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let z_arch = p.z_thoracic(3.4);
    let ytr = trachea_y(p, z_arch);
    let (zj, zn) = (p.z_jugular(), p.z_neck_top());
    let (ncy, ..) = p.neck();
    let desc = |z: f64| {
        let (a, b) = p.vertebra(z);
        v(a + 0.7 * 12.0 * s + 3.0, p.spine_y(z) - 0.8 * b, z)
    };
    // Aorta: root, ascending, arch over the left main bronchus, descending beside the spine.
    let zd = z_arch - 40.0 * s;
    let aorta = [
        (h.aortic_root, 14.0 * s),
        (h.aortic_root + v(-4.0 * s, -6.0 * s, 25.0 * s), 15.0 * s),
        (v(-10.0 * s, ytr - 30.0 * s, z_arch - 25.0 * s), 15.0 * s),
        (v(-4.0 * s, ytr - 20.0 * s, z_arch - 4.0 * s), 14.0 * s),
        (v(8.0 * s, ytr - 6.0 * s, z_arch), 13.5 * s),
        (v(20.0 * s, ytr + 10.0 * s, z_arch - 10.0 * s), 13.0 * s),
        (desc(zd), 12.0 * s),
        (desc(p.z_base + 20.0), 11.5 * s),
        (
            desc(p.z_base - 150.0) - v(10.0 * s, 10.0 * s, 0.0),
            11.0 * s,
        ),
        (
            desc(p.z_base - 600.0) - v(18.0 * s, 12.0 * s, 0.0),
            10.0 * s,
        ),
    ];
    vessel(sc, &aorta, Tissue::Blood, Structure::Aorta);
    let gv = Structure::GreatVessel;
    let apex = p.z_apex;
    // Arch branches: brachiocephalic trunk with right subclavian and carotid, left carotid,
    // left subclavian. The subclavian vessels run over the lung apices to the axillae.
    let bct = v(-14.0 * s, ytr - 16.0 * s, z_arch + 30.0 * s);
    vessel(
        sc,
        &[
            (v(-6.0 * s, ytr - 18.0 * s, z_arch), 6.5 * s),
            (bct, 6.5 * s),
        ],
        Tissue::Blood,
        gv,
    );
    for side in [-1.0, 1.0] {
        let start = if side < 0.0 {
            bct
        } else {
            v(12.0 * s, ytr + 2.0 * s, z_arch - 2.0 * s)
        };
        let carotid_start = if side < 0.0 {
            bct
        } else {
            v(2.0 * s, ytr - 10.0 * s, z_arch)
        };
        vessel(
            sc,
            &[
                (start, 5.0 * s),
                (v(side * 40.0 * s, ytr, apex + 14.0 * s), 4.8 * s),
                (v(side * 70.0 * s, ytr - 5.0 * s, apex + 8.0 * s), 4.5 * s),
                (v(side * 0.8 * w, 0.0, apex - 25.0 * s), 4.5 * s),
            ],
            Tissue::Blood,
            gv,
        );
        vessel(
            sc,
            &[
                (carotid_start, 4.0 * s),
                (v(side * 20.0 * s, ncy - 12.0 * s, zj + 25.0 * s), 3.8 * s),
                (v(side * 24.0 * s, ncy - 10.0 * s, zn), 3.5 * s),
            ],
            Tissue::Blood,
            gv,
        );
        // Internal jugular and subclavian veins meeting behind the clavicle.
        let junction = v(side * 30.0 * s, ytr - 14.0 * s, zj + 10.0 * s);
        vessel(
            sc,
            &[
                (v(side * 32.0 * s, ncy - 6.0 * s, zn), 6.0 * s),
                (v(side * 31.0 * s, ncy - 8.0 * s, zj + 30.0 * s), 6.5 * s),
                (junction, 6.5 * s),
            ],
            Tissue::Blood,
            gv,
        );
        let mut sub: Vec<(DVec3, f64)> = h.venous_path[..3]
            .iter()
            .map(|q| (v(side * q.x.abs(), q.y, q.z), 5.5 * s))
            .collect();
        sub[2].0 = junction;
        vessel(sc, &sub, Tissue::Blood, gv);
    }
    // Brachiocephalic veins into the superior vena cava, down into the right atrium.
    let svc_top = h.venous_path[4];
    vessel(
        sc,
        &[
            (v(-30.0 * s, ytr - 14.0 * s, zj + 10.0 * s), 6.5 * s),
            (svc_top, 7.0 * s),
        ],
        Tissue::Blood,
        gv,
    );
    let left_bcv: Vec<_> = h.venous_path[2..5].iter().map(|&q| (q, 6.0 * s)).collect();
    vessel(sc, &left_bcv, Tissue::Blood, gv);
    let svc: Vec<_> = h.venous_path[4..].iter().map(|&q| (q, 9.0 * s)).collect();
    vessel(sc, &svc, Tissue::Blood, gv);
    // Inferior vena cava from the right atrium through the liver.
    let ivc_y = |z: f64| p.spine_y(z) - p.vertebra(z).1 - 12.0 * s;
    vessel(
        sc,
        &[
            (h.ra - v(0.0, 0.0, 10.0 * s), 11.0 * s),
            (v(-20.0 * s, ivc_y(p.z_base), p.z_base + 10.0), 11.0 * s),
            (
                v(-20.0 * s, ivc_y(p.z_base - 300.0), p.z_base - 300.0),
                10.0 * s,
            ),
        ],
        Tissue::Blood,
        gv,
    );
    // Pulmonary trunk, bifurcation under the arch, right and left pulmonary arteries to
    // the hila, then to each lobar artery of the tree.
    let zc = z_carina(p);
    let bif = v(6.0 * s, trachea_y(p, zc) - 22.0 * s, zc - 4.0 * s);
    vessel(
        sc,
        &[
            (h.pa_root, 13.0 * s),
            (h.pa_root + v(4.0 * s, 6.0 * s, 20.0 * s), 13.0 * s),
            (bif, 12.0 * s),
        ],
        Tissue::Blood,
        gv,
    );
    for side in [-1.0, 1.0] {
        let roots = aw.artery_roots(side);
        if roots.is_empty() {
            continue;
        }
        let hilum = roots.iter().map(|r| r.0).sum::<DVec3>() / roots.len() as f64;
        let mid = if side < 0.0 {
            v(-20.0 * s, trachea_y(p, zc) - 14.0 * s, zc - 12.0 * s)
        } else {
            v(22.0 * s, trachea_y(p, zc) - 6.0 * s, zc - 4.0 * s)
        };
        vessel(
            sc,
            &[(bif, 10.0 * s), (mid, 10.0 * s), (hilum, 8.0 * s)],
            Tissue::Blood,
            gv,
        );
        for (q, r) in roots {
            sc.add(
                Shape::Tube {
                    a: hilum,
                    b: q,
                    ra: 7.0 * s,
                    rb: r,
                },
                Tissue::Blood,
                gv,
            );
        }
    }
    // Oesophagus in front of the spine, turning left into the stomach under the dome.
    let zs = p.z_base + p.dome_h[1] - 20.0;
    let mut eso: Vec<(DVec3, f64)> = (0..=12)
        .map(|i| {
            let z = zn + (zs - zn) * i as f64 / 12.0;
            (v(3.0 * s, esophagus_y(p, z), z), esophagus_radius(p))
        })
        .collect();
    let b_e = (p.yp_e - p.ya_e) / 2.0;
    eso.push((
        v(
            0.3 * p.a_e,
            (p.yp_e + p.ya_e) / 2.0 - 0.1 * b_e,
            zs - 25.0 * s,
        ),
        esophagus_radius(p),
    ));
    vessel(sc, &eso, Tissue::SoftTissue, Structure::Esophagus);
}
