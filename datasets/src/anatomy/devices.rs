//! Devices: the pacemaker (titanium can and leads) and the patient table, painted into
//! the voxels or, on request, emitted as closed triangle meshes ([`DeviceMesh`]) with a
//! material of `tomograf_sim::material` and a density, to be traced exactly
//! (`tomograf_sim::mesh`) instead of blurred by the voxel grid.

use super::heart::Heart;
use super::patient::Params;
use super::shapes::Shape;
use super::tissue::Material;
use super::{Scene, Structure, Tissue, spline};
use glam::{DMat3, DVec3};
use tomograf_sim::mesh::{TriMesh, shapes};

/// A device as a closed mesh in world coordinates (LPS, mm; the phantom's grid is centred
/// on the origin with identity direction), with what it is made of.
#[derive(Debug, Clone)]
pub struct DeviceMesh {
    /// Name, e.g. `pacemaker-can`.
    pub name: String,
    /// Material name of `tomograf_sim::material::by_name`.
    pub material: String,
    /// Density, g/cm³.
    pub density_g_cm3: f64,
    /// The closed, outward-facing surface (world mm).
    pub mesh: TriMesh,
}

/// Density (g/cm³) given to the lead meshes: titanium at the density whose attenuation
/// matches the voxel phantom's leads (2600 HU ≈ 3.6 × water at 60–70 keV, where titanium's
/// μ/ρ is ≈ 1.33 × water's): a metal coil in silicone insulation, averaged.
pub const LEAD_DENSITY_G_CM3: f64 = 2.7;
/// Density (g/cm³) of the table's carbon-fibre skins (CFRP, ≈ 1.55–1.6).
pub const CFRP_DENSITY_G_CM3: f64 = 1.55;
/// Density (g/cm³) of the table's foam core and pad (−920 HU in the voxel phantom, taken as
/// PMMA foam).
pub const FOAM_DENSITY_G_CM3: f64 = 0.08;
/// Length of the table meshes along z, mm (the voxel table is infinitely long).
pub const TABLE_LENGTH_MM: f64 = 2000.0;

fn device(name: &str, material: &str, density: f64, mesh: TriMesh) -> DeviceMesh {
    DeviceMesh {
        name: name.into(),
        material: material.into(),
        density_g_cm3: density,
        mesh,
    }
}

/// Phase 13: a titanium can (rounded box ≈ 50 × 45 × 8 mm) under the skin of the left
/// upper chest, and two leads (right atrium, right ventricle) through the subclavian
/// vein, left brachiocephalic vein and superior vena cava. The leads are 1 mm in radius,
/// widened to about half the smallest voxel size so that point sampling does not break
/// them up on coarse grids. Returns the can's centre. With `meshes`, the can (titanium at
/// its nominal density) and the leads (1 mm radius, [`LEAD_DENSITY_G_CM3`]) are pushed
/// there as meshes instead of painted.
pub(crate) fn pacemaker(
    sc: &mut Scene,
    p: &Params,
    h: &Heart,
    min_spacing: f64,
    mut meshes: Option<&mut Vec<DeviceMesh>>,
) -> DVec3 {
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
    let r_lead = if meshes.is_some() {
        1.0
    } else {
        (1.0f64).max(0.55 * min_spacing)
    };
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
        if let Some(m) = meshes.as_deref_mut() {
            // A tube's rings cross on the inside of a sharp bend: corners turning by more
            // than 0.5 rad (where the venous course meets the heart) are cut first.
            let tube = shapes::tube(&gentle(&pts, 0.5), r_lead, 12).expect("valid lead course");
            m.push(device(
                &format!("pacemaker-lead-{}", k + 1),
                "titanium",
                LEAD_DENSITY_G_CM3,
                tube,
            ));
            continue;
        }
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
    match meshes {
        Some(m) => {
            let local = shapes::rounded_box(half, 3.5, 32, 17).expect("valid can");
            let can = TriMesh {
                vertices: local.vertices.iter().map(|&v| centre + rot * v).collect(),
                triangles: local.triangles,
            };
            let ti = tomograf_sim::material::by_name("titanium").expect("in the library");
            m.push(device("pacemaker-can", "titanium", ti.density(), can));
        }
        None => sc.add(
            Shape::rbox(centre, half, 3.5, rot),
            Tissue::Metal,
            Structure::Pacemaker,
        ),
    }
    centre
}

/// Phase 14: a patient table under the patient's back: a flat foam pad (mattress) on a
/// curved carbon-fibre couch top (2.5 mm skins, foam core, 45 mm thick, 460 mm wide, the
/// edges curving up with a 4 m radius). The pad's top touches the lowest (most posterior)
/// point of the body, so every table voxel lies posterior of every body voxel. Returns
/// the y of the pad's top. With `meshes`, the pad, the couch top (carbon fibre) and its
/// core (foam; listed after the top so it holds the rays inside it) are pushed there as
/// meshes [`TABLE_LENGTH_MM`] long instead of painted.
pub(crate) fn table(sc: &mut Scene, meshes: Option<&mut Vec<DeviceMesh>>) -> f64 {
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
    if let Some(m) = meshes {
        let parts = [
            (
                "table-pad",
                "pmma",
                FOAM_DENSITY_G_CM3,
                pad,
                1e9,
                y0 - pad + 1.0,
                half_w,
            ),
            (
                "table-top",
                "carbon",
                CFRP_DENSITY_G_CM3,
                y0,
                rc,
                thick,
                half_w,
            ),
            (
                "table-core",
                "pmma",
                FOAM_DENSITY_G_CM3,
                y0 + skin,
                rc,
                thick - 2.0 * skin,
                half_w - skin,
            ),
        ];
        for (name, material, rho, y, r, t, hw) in parts {
            m.push(device(name, material, rho, couch_mesh(y, r, t, hw)));
        }
        return pad;
    }
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

/// The couch shape `Shape::Couch { y0, rc, thick, half_w }` as a closed prism
/// [`TABLE_LENGTH_MM`] long centred on z = 0: its top follows the circle of radius `rc`
/// (48 pieces across), its bottom the same curve `thick` lower (+y).
fn couch_mesh(y0: f64, rc: f64, thick: f64, half_w: f64) -> TriMesh {
    let n = 48;
    let top = |x: f64| y0 - (rc - (rc * rc - x * x).max(0.0).sqrt());
    let xs: Vec<f64> = (0..=n)
        .map(|i| -half_w + 2.0 * half_w * i as f64 / n as f64)
        .collect();
    // Counter-clockwise in (x, y): along the bottom (+y side) left to right, back along
    // the top.
    let mut outline: Vec<[f64; 2]> = xs.iter().map(|&x| [x, top(x) + thick]).collect();
    outline.extend(xs.iter().rev().map(|&x| [x, top(x)]));
    shapes::prism(&outline, TABLE_LENGTH_MM).expect("valid couch outline")
}

/// `path` with interior points removed until no corner turns by more than `max_turn`
/// radians (end points kept): a polyline a tube can follow without its rings crossing.
fn gentle(path: &[DVec3], max_turn: f64) -> Vec<DVec3> {
    let mut p = path.to_vec();
    loop {
        let sharp = (1..p.len().saturating_sub(1)).find(|&i| {
            let (a, b) = (p[i] - p[i - 1], p[i + 1] - p[i]);
            a.angle_between(b) > max_turn
        });
        match sharp {
            Some(i) => {
                p.remove(i);
            }
            None => return p,
        }
    }
}
