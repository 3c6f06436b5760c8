//! Devices: the pacemaker (titanium can and leads) and the patient table.

use super::heart::Heart;
use super::patient::Params;
use super::shapes::Shape;
use super::tissue::Material;
use super::{Scene, Structure, Tissue, spline};
use glam::{DMat3, DVec3};

/// Phase 13: a titanium can (rounded box ≈ 50 × 45 × 8 mm) under the skin of the left
/// upper chest, and two leads (right atrium, right ventricle) through the subclavian
/// vein, left brachiocephalic vein and superior vena cava. The leads are 1 mm in radius,
/// widened to about half the smallest voxel size so that point sampling does not break
/// them up on coarse grids. Returns the can's centre.
pub(crate) fn pacemaker(sc: &mut Scene, p: &Params, h: &Heart, min_spacing: f64) -> DVec3 {
    let s = p.s;
    let z = p.z_jugular() - 30.0 * s;
    let x = 0.5 * p.width / 2.0;
    let front = p.torso_front(x, z);
    let slope = (p.torso_front(x + 5.0, z) - p.torso_front(x - 5.0, z)) / 10.0;
    let phi = slope.atan();
    let ex = DVec3::new(phi.cos(), phi.sin(), 0.0);
    let ey = DVec3::new(-phi.sin(), phi.cos(), 0.0);
    let half = DVec3::new(25.0, 4.0, 22.5);
    let centre = DVec3::new(x, front, z) + ey * (half.y + 3.0);
    let rot = DMat3::from_cols(ex, ey, DVec3::Z);
    let r_lead = (1.0f64).max(0.55 * min_spacing);
    let mut lead = Material::of(Tissue::Metal);
    lead.mean = 2600.0;
    lead.sigma = 60.0;
    let lead = sc.material(lead);
    // Shared course: out of the can's medial upper edge, under the clavicle into the
    // subclavian vein, then along the veins into the right atrium.
    let exit = centre - ex * 20.0 + DVec3::Z * 18.0;
    let mut course = vec![exit, h.venous_path[1]];
    course.extend_from_slice(&h.venous_path[2..]);
    course.push(h.ra);
    let ends = [
        vec![
            h.ra + (h.rv_apex - h.ra) * 0.45,
            h.rv_apex - (h.rv_apex - h.centre) * 0.1,
        ],
        vec![h.ra + DVec3::new(6.0 * s, -18.0 * s, 14.0 * s)],
    ];
    for (k, tail) in ends.into_iter().enumerate() {
        let offset = DVec3::new(0.0, 0.0, 2.5 * k as f64);
        let ctrl: Vec<(DVec3, f64)> = course
            .iter()
            .chain(&tail)
            .map(|&q| (q + offset, r_lead))
            .collect();
        let (pts, _) = spline(&ctrl, 3.0);
        for w in pts.windows(2) {
            sc.add_mat(
                Shape::Tube {
                    a: w[0],
                    b: w[1],
                    ra: r_lead,
                    rb: r_lead,
                },
                lead,
                Structure::PacemakerLead,
            );
        }
    }
    sc.add(
        Shape::rbox(centre, half, 3.5, rot),
        Tissue::Metal,
        Structure::Pacemaker,
    );
    centre
}

/// Phase 14: a patient table under the patient's back: a flat foam pad (mattress) on a
/// curved carbon-fibre couch top (2.5 mm skins, foam core, 45 mm thick, 460 mm wide, the
/// edges curving up with a 4 m radius). The pad's top touches the lowest (most posterior)
/// point of the body, so every table voxel lies posterior of every body voxel. Returns
/// the y of the pad's top.
pub(crate) fn table(sc: &mut Scene) -> f64 {
    let (rc, half_w, thick, skin): (f64, f64, f64, f64) = (4000.0, 230.0, 45.0, 2.5);
    let rise = rc - (rc * rc - half_w * half_w).sqrt();
    let back = sc
        .prims
        .iter()
        .filter(|p| p.lo.x <= half_w && p.hi.x >= -half_w)
        .map(|p| p.hi.y)
        .fold(f64::NEG_INFINITY, f64::max);
    let pad = back + 0.5;
    let y0 = back + 1.0 + rise;
    sc.add(
        Shape::Couch {
            y0: pad,
            rc: 1e9,
            thick: y0 - pad + 1.0,
            half_w,
        },
        Tissue::Foam,
        Structure::Table,
    );
    sc.add(
        Shape::Couch {
            y0,
            rc,
            thick,
            half_w,
        },
        Tissue::Plastic,
        Structure::Table,
    );
    sc.add(
        Shape::Couch {
            y0: y0 + skin,
            rc,
            thick: thick - 2.0 * skin,
            half_w: half_w - skin,
        },
        Tissue::Foam,
        Structure::Table,
    );
    pad
}
