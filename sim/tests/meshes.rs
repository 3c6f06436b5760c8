//! Mesh objects: path lengths against independent references, robustness on edges and
//! vertices, watertightness errors and repair, file loading and placement.
//!
//! References and tolerances:
//! * convex meshes (box, icosphere, cylinder): the chord of the intersection of the face
//!   half-spaces (plane equations; no ray–triangle test), 1e-9 mm — both are exact up to
//!   f64 rounding of a few operations on coordinates of ~100 mm;
//! * spheres and cylinders: the analytic chord bounds the polyhedron's from above, and the
//!   chord of the inscribed ball/cylinder (radius = nearest face plane) from below;
//! * (voxels and meshes together: `mesh_render.rs`).

mod common;

use common::*;
use glam::DVec3;
use rand::Rng;
use tomograf_sim::Ray;
use tomograf_sim::mesh::topology::{self, repair};
use tomograf_sim::mesh::{MeshError, MeshObject, Placement, TriMesh, io, shapes};

fn object(mesh: &TriMesh, at: DVec3) -> MeshObject {
    MeshObject::new(
        "m",
        mesh,
        &Placement::translation(at),
        "test",
        Some(0.1),
        true,
    )
    .unwrap()
}

/// Chord of the convex polyhedron `m` (placed at `at`) along `ray`, from face planes.
fn convex_chord(m: &TriMesh, at: DVec3, ray: &Ray) -> f64 {
    let (mut t0, mut t1) = (ray.t_min, ray.t_max);
    for t in 0..m.triangles.len() {
        let [a, b, c] = m.corners(t).map(|v| v + at);
        let n = (b - a).cross(c - a);
        let (num, den) = (n.dot(a - ray.origin), n.dot(ray.direction));
        if den == 0.0 {
            if num < 0.0 {
                return 0.0;
            }
            continue;
        }
        let x = num / den;
        if den > 0.0 {
            t1 = t1.min(x);
        } else {
            t0 = t0.max(x);
        }
    }
    (t1 - t0).max(0.0)
}

fn through(p: DVec3, d: DVec3) -> Ray {
    let d = d.normalize();
    Ray::segment(p - 500.0 * d, p + 500.0 * d)
}

#[test]
fn convex_meshes_match_half_space_chords_on_random_rays() {
    let mut r = rng(21);
    let at = DVec3::new(12.0, -30.0, 7.0);
    for mesh in [
        shapes::cuboid(DVec3::new(40.0, 25.0, 60.0)).unwrap(),
        shapes::icosphere(30.0, 3).unwrap(),
        shapes::cylinder(20.0, 50.0, 24).unwrap(),
    ] {
        let o = object(&mesh, at);
        let mut hits = 0;
        for _ in 0..2000 {
            let p = at
                + DVec3::new(
                    r.random_range(-35.0..35.0),
                    r.random_range(-35.0..35.0),
                    r.random_range(-35.0..35.0),
                );
            let d = DVec3::new(
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
            );
            if d.length() < 1e-3 {
                continue;
            }
            let ray = through(p, d);
            let (ours, reference) = (o.path_length(&ray), convex_chord(&mesh, at, &ray));
            assert!(
                (ours - reference).abs() < 1e-9,
                "{ours} vs {reference} for {ray:?}"
            );
            hits += usize::from(reference > 0.0);
        }
        assert!(hits > 500);
    }
}

/// Rays through every vertex, every edge midpoint and points along edges of a cube and an
/// icosphere, in generic and in axis directions: no leak, no double count.
#[test]
fn rays_through_vertices_and_edges() {
    let mut r = rng(5);
    let at = DVec3::new(0.25, -3.0, 1.5);
    for mesh in [
        shapes::cuboid(DVec3::new(20.0, 20.0, 20.0)).unwrap(),
        shapes::icosphere(15.0, 2).unwrap(),
    ] {
        let o = object(&mesh, at);
        let mut points: Vec<DVec3> = mesh.vertices.iter().map(|&v| v + at).collect();
        for t in &mesh.triangles {
            for e in 0..3 {
                let (a, b) = (
                    mesh.vertices[t[e] as usize],
                    mesh.vertices[t[(e + 1) % 3] as usize],
                );
                for f in [0.5, 0.25, 0.1] {
                    points.push(at + a + f * (b - a));
                }
            }
        }
        let mut dirs = vec![
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 1.0),
        ];
        for _ in 0..6 {
            dirs.push(DVec3::new(
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
            ));
        }
        let (lo, hi) = mesh.bounds();
        let extent = (hi - lo).length();
        let mut inside = 0;
        for &p in &points {
            // Also a point nudged into the solid towards the centre: rays through it cross the
            // surface at generic points.
            for q in [p, p + (at - p) * 1e-3] {
                for &d in &dirs {
                    for d in [d, -d] {
                        let ray = through(q, d);
                        let (ours, reference) =
                            (o.path_length(&ray), convex_chord(&mesh, at, &ray));
                        // A ray lying in a face's plane runs along the surface: its length
                        // is a matter of convention (and the half-space reference rounds
                        // either way there); it must only not leak out of the mesh's box.
                        let in_surface = (0..mesh.triangles.len()).any(|t| {
                            let [a, b, c] = mesh.corners(t).map(|v| v + at);
                            let n = (b - a).cross(c - a).normalize();
                            n.dot(ray.direction).abs() < 1e-12 && n.dot(q - a).abs() < 1e-9
                        });
                        let ok = if in_surface {
                            (0.0..=extent).contains(&ours)
                        } else {
                            (ours - reference).abs() < 1e-9
                        };
                        assert!(ok, "{ours} vs {reference} through {q} along {d}");
                        inside += usize::from(reference > 1e-6);
                    }
                }
            }
        }
        assert!(inside > 100);
    }
}

/// Polyhedral spheres and cylinders are bracketed by the analytic chords of the
/// circumscribed and inscribed shapes, and converge to the analytic chord.
#[test]
fn spheres_and_cylinders_converge_to_analytic_chords() {
    let radius = 25.0;
    let offsets = [0.0, 7.3, 15.1, 22.2];
    let mut previous = f64::INFINITY;
    for level in 0..=5 {
        let mesh = shapes::icosphere(radius, level).unwrap();
        let r_in = (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.corners(t);
                (b - a).cross(c - a).normalize().dot(a).abs()
            })
            .fold(f64::INFINITY, f64::min);
        let o = object(&mesh, DVec3::ZERO);
        let mut worst = 0.0f64;
        for &d in &offsets {
            for dir in [DVec3::new(1.0, 0.2, 0.1), DVec3::new(-0.3, 1.0, 0.7)] {
                let dir = dir.normalize();
                let side = dir.any_orthonormal_vector();
                let l = o.path_length(&through(side * d, dir));
                let outer = 2.0 * (radius * radius - d * d).max(0.0).sqrt();
                let inner = 2.0 * (r_in * r_in - d * d).max(0.0).sqrt();
                assert!(
                    l <= outer + 1e-9 && l >= inner - 1e-9,
                    "level {level} d {d}: {inner} ≤ {l} ≤ {outer}"
                );
                worst = worst.max((outer - l) / (2.0 * radius));
            }
        }
        // The gap to the sphere shrinks ~4× per level (face size halves; sagitta ∝ h²).
        assert!(worst < previous, "level {level}: {worst} after {previous}");
        previous = worst;
    }
    assert!(
        previous < 2e-3,
        "finest icosphere within 0.2 % of the diameter: {previous}"
    );

    // Cylinder of n sides, ray across the axis at offset d: between the chords of the
    // circles of radius R cos(π/n) and R.
    for n in [8, 32, 128, 512] {
        let o = object(&shapes::cylinder(radius, 40.0, n).unwrap(), DVec3::ZERO);
        let r_in = radius * (std::f64::consts::PI / n as f64).cos();
        for &d in &offsets {
            for a in [0.1f64, 0.7, 2.0] {
                let dir = DVec3::new(a.cos(), a.sin(), 0.0);
                let side = DVec3::new(-a.sin(), a.cos(), 0.0);
                let l = o.path_length(&through(side * d + DVec3::new(0.0, 0.0, 3.0), dir));
                let outer = 2.0 * (radius * radius - d * d).max(0.0).sqrt();
                let inner = 2.0 * (r_in * r_in - d * d).max(0.0).sqrt();
                assert!(
                    l <= outer + 1e-9 && l >= inner - 1e-9,
                    "n {n} d {d}: {inner} ≤ {l} ≤ {outer}"
                );
            }
        }
    }
    // UV spheres are inscribed too.
    let uv = object(&shapes::uv_sphere(radius, 64, 32).unwrap(), DVec3::ZERO);
    let l = uv.path_length(&through(DVec3::new(0.0, 3.0, 1.0), DVec3::X));
    let outer = 2.0 * (radius * radius - 10.0f64).sqrt();
    assert!(l <= outer && l > outer * 0.99, "{l} vs {outer}");
}

fn cube_mesh() -> TriMesh {
    shapes::cuboid(DVec3::splat(10.0)).unwrap()
}

#[test]
fn open_inconsistent_and_inside_out_meshes_are_refused_or_repaired() {
    // A hole.
    let mut m = cube_mesh();
    m.triangles.pop();
    let e = topology::check(&m).unwrap_err();
    assert!(matches!(e, MeshError::NotClosed { boundary: 3, .. }), "{e}");
    assert!(e.to_string().contains("3 boundary edges"), "{e}");
    assert!(repair(&m, 1e-6).is_err(), "a hole cannot be repaired");
    let err =
        MeshObject::new("holey", &m, &Placement::default(), "x", Some(0.1), false).unwrap_err();
    assert!(
        err.to_string().contains("holey") && err.to_string().contains("not closed"),
        "{err}"
    );

    // One triangle flipped: three inconsistent edges; repair flips it back.
    let mut m = cube_mesh();
    m.triangles[4].swap(1, 2);
    let e = topology::check(&m).unwrap_err();
    assert!(
        matches!(
            e,
            MeshError::NotClosed {
                inconsistent: 3,
                boundary: 0,
                ..
            }
        ),
        "{e}"
    );
    let (fixed, report) = repair(&m, 0.0).unwrap();
    assert_eq!(report.flipped_triangles, 1);
    assert!((fixed.signed_volume() - 1000.0).abs() < 1e-9);

    // Inside out: refused, repaired by flipping all.
    let m = cube_mesh().flipped();
    assert!(matches!(
        topology::check(&m),
        Err(MeshError::InsideOut { .. })
    ));
    let (fixed, report) = repair(&m, 0.0).unwrap();
    assert_eq!(report.flipped_triangles, 12);
    assert!(topology::check(&fixed).is_ok());

    // "Triangle soup" (as STL stores it): every triangle has its own vertices. Open
    // until vertices are merged.
    let c = cube_mesh();
    let soup = TriMesh {
        vertices: (0..c.triangles.len())
            .flat_map(|t| c.corners(t))
            .map(|v| v + DVec3::splat(1e-9))
            .collect(),
        triangles: (0..c.triangles.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
    };
    assert!(matches!(
        topology::check(&soup),
        Err(MeshError::NotClosed { boundary: 36, .. })
    ));
    let (fixed, report) = repair(&soup, 1e-6).unwrap();
    assert_eq!(fixed.vertices.len(), 8);
    assert_eq!(report.merged_vertices, 36 - 8);

    // An edge shared by three triangles.
    let mut m = cube_mesh();
    let extra = m.vertices.len() as u32;
    m.vertices.push(DVec3::new(0.0, 0.0, 40.0));
    let [a, b, _] = m.triangles[0];
    m.triangles.push([a, b, extra]);
    let e = topology::check(&m).unwrap_err();
    assert!(
        matches!(
            e,
            MeshError::NotClosed {
                non_manifold: 1,
                ..
            }
        ),
        "{e}"
    );

    // Bad indices and coordinates.
    let mut m = cube_mesh();
    m.triangles[0][1] = 99;
    assert!(
        topology::check(&m)
            .unwrap_err()
            .to_string()
            .contains("vertex index")
    );
    let mut m = cube_mesh();
    m.vertices[2].x = f64::NAN;
    assert!(
        topology::check(&m)
            .unwrap_err()
            .to_string()
            .contains("non-finite")
    );
}

#[test]
fn self_intersecting_meshes_are_refused() {
    // Two closed cubes that overlap, as one mesh: every edge is fine, the surfaces cross.
    let mut m = cube_mesh();
    let other = shapes::cuboid(DVec3::splat(10.0)).unwrap();
    let shifted = TriMesh {
        vertices: other
            .vertices
            .iter()
            .map(|&v| v + DVec3::new(4.0, 3.0, 2.0))
            .collect(),
        triangles: other.triangles.clone(),
    };
    m.append(&shifted);
    assert!(topology::check(&m).is_ok());
    let e =
        MeshObject::new("overlap", &m, &Placement::default(), "x", Some(0.1), true).unwrap_err();
    assert!(e.to_string().contains("intersects itself"), "{e}");
    // Two disjoint cubes are fine.
    let mut m = cube_mesh();
    let far = TriMesh {
        vertices: other
            .vertices
            .iter()
            .map(|&v| v + DVec3::new(30.0, 0.0, 0.0))
            .collect(),
        triangles: other.triangles,
    };
    m.append(&far);
    assert!(MeshObject::new("two", &m, &Placement::default(), "x", Some(0.1), true).is_ok());
    // The parametric devices are clean.
    for (name, mesh) in shapes::pacemaker(24).unwrap() {
        MeshObject::new(&name, &mesh, &Placement::default(), "x", Some(0.1), true).unwrap();
    }
    let table = shapes::table_top(450.0, 1900.0, 40.0).unwrap();
    MeshObject::new("table", &table, &Placement::default(), "x", Some(0.1), true).unwrap();
}

#[test]
fn obj_ply_and_stl_files_load() {
    let dir = std::env::temp_dir().join(format!("tomograf-mesh-io-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let c = cube_mesh();
    let mut obj = String::new();
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        c.vertices.len(),
        c.triangles.len()
    );
    for v in &c.vertices {
        obj += &format!("v {} {} {}\n", v.x, v.y, v.z);
        ply += &format!("{} {} {}\n", v.x, v.y, v.z);
    }
    for t in &c.triangles {
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        ply += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    let mut stl = String::from("solid cube\n");
    for t in 0..c.triangles.len() {
        let [a, b, cc] = c.corners(t);
        let n = (b - a).cross(cc - a).normalize();
        stl += &format!("facet normal {} {} {}\nouter loop\n", n.x, n.y, n.z);
        for v in [a, b, cc] {
            stl += &format!("vertex {} {} {}\n", v.x, v.y, v.z);
        }
        stl += "endloop\nendfacet\n";
    }
    stl += "endsolid cube\n";
    for (name, text) in [("cube.obj", obj), ("cube.PLY", ply), ("cube.stl", stl)] {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        let m = io::load(&p).unwrap();
        let (m, _) = repair(&m, 1e-6).unwrap();
        assert!((m.signed_volume() - 1000.0).abs() < 1e-6, "{name}");
    }
    let bad = dir.join("cube.xyz");
    std::fs::write(&bad, "nothing").unwrap();
    assert!(
        io::load(&bad)
            .unwrap_err()
            .to_string()
            .contains("unknown extension")
    );
    let broken = dir.join("broken.ply");
    std::fs::write(
        &broken,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
    )
    .unwrap();
    assert!(io::load(&broken).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn placement_rotates_scales_and_mirrors() {
    let m = shapes::cuboid(DVec3::new(1.0, 2.0, 3.0)).unwrap();
    let p = Placement::Pose {
        rotation_deg: [0.0, 0.0, 90.0],
        scale: [10.0, 10.0, 10.0],
        translation_mm: [5.0, 0.0, 0.0],
    };
    let w = m.placed(&p).unwrap();
    let (lo, hi) = w.bounds();
    assert!(
        (lo - DVec3::new(-5.0, -5.0, -15.0)).length() < 1e-9
            && (hi - DVec3::new(15.0, 5.0, 15.0)).length() < 1e-9,
        "{lo} {hi}"
    );
    let mirror = Placement::Matrix {
        matrix: [
            [-1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
    };
    assert!(
        topology::check(&m.placed(&mirror).unwrap()).is_ok(),
        "mirroring keeps normals outward"
    );
    let singular = Placement::Pose {
        rotation_deg: [0.0; 3],
        scale: [1.0, 0.0, 1.0],
        translation_mm: [0.0; 3],
    };
    assert!(
        m.placed(&singular)
            .unwrap_err()
            .to_string()
            .contains("singular")
    );
    let _ = rel_err(1.0, 1.0);
}

/// The rounded box (pacemaker can) is closed, does not intersect itself, and its volume
/// converges from below to the closed form of a box ⊕ ball (vertices lie on the surface,
/// so the mesh is inscribed), within 1 % at 32 × 17; an OBJ round trip keeps it to f32 rounding.
#[test]
fn rounded_box_is_closed_and_converges_to_its_volume() {
    let (half, r) = (DVec3::new(25.0, 4.0, 22.5), 3.5);
    let [a, b, c] = (half - DVec3::splat(r)).to_array();
    let pi = std::f64::consts::PI;
    let exact = 8.0 * a * b * c
        + 8.0 * r * (a * b + b * c + c * a)
        + 2.0 * pi * r * r * (a + b + c)
        + 4.0 / 3.0 * pi * r.powi(3);
    let mut previous = 0.0;
    for (segments, rings) in [(8, 5), (16, 9), (32, 17)] {
        let m = shapes::rounded_box(half, r, segments, rings).unwrap();
        topology::check(&m).unwrap();
        let v = m.signed_volume();
        assert!(v < exact && v > previous, "{segments}: {v} vs {exact}");
        previous = v;
        let o = MeshObject::new("can", &m, &Placement::default(), "titanium", None, true);
        assert!(o.is_ok(), "{o:?}");
    }
    assert!((exact - previous) / exact < 0.01, "{previous} vs {exact}");
    let m = shapes::rounded_box(half, r, 32, 17).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("can.obj");
    io::write_obj(&path, &m).unwrap();
    // OBJ files are read in f32 (tobj, which may also renumber vertices): the round trip
    // keeps a closed mesh of the same triangle count and volume to f32 rounding.
    let back = io::load(&path).unwrap();
    topology::check(&back).unwrap();
    assert_eq!(back.triangles.len(), m.triangles.len());
    let (v0, v1) = (m.signed_volume(), back.signed_volume());
    assert!(((v1 - v0) / v0).abs() < 1e-5, "{v1} vs {v0}");
    assert!(shapes::rounded_box(DVec3::splat(2.0), 3.0, 8, 5).is_err());
}

/// Axis-parallel rays whose zero direction components are −0 or +0 (a parallel beam's
/// rays can carry either): each must find the box, 1e-9 mm. Regression: the 8-wide BVH
/// culled every box for a −0 component.
#[test]
fn axis_parallel_rays_with_signed_zero_directions_hit() {
    let cube = shapes::cuboid(DVec3::new(10.0, 20.0, 30.0)).unwrap();
    let at = DVec3::new(1.0, -2.0, 3.0);
    let m = object(&cube, at);
    let (lo, hi) = m.bounds();
    let sides = hi - lo;
    for axis in 0..3 {
        for sign in [1.0, -1.0] {
            for zero in [0.0, -0.0] {
                let mut d = DVec3::splat(zero);
                d[axis] = sign;
                // Off-centre points inside the box's cross-section.
                for p in [at + DVec3::splat(1.3), at - DVec3::splat(2.1)] {
                    let ray = Ray {
                        origin: p - 500.0 * d,
                        direction: d,
                        t_min: 0.0,
                        t_max: 1000.0,
                    };
                    let got = m.path_length(&ray);
                    assert!(
                        (got - sides[axis]).abs() < 1e-9,
                        "axis {axis}, sign {sign}, zero {zero:?}: {got} vs {}",
                        sides[axis]
                    );
                }
            }
        }
    }
}

/// Found by the `scene` fuzz target: a table top 4.5·10³⁷ mm wide made the f32 BVH build
/// panic inside obvhs (its boxes overflow to infinity). Meshes reaching beyond 1 km are
/// refused by name, before any BVH is built; one just inside the bound builds.
#[test]
fn meshes_beyond_a_kilometre_are_refused_before_the_bvh() {
    let huge = shapes::cuboid(DVec3::new(4.5e37, 20.0, 1000.0)).unwrap();
    let e = MeshObject::new(
        "table",
        &huge,
        &Placement::default(),
        "x",
        Some(0.03),
        false,
    )
    .unwrap_err();
    assert!(matches!(e, MeshError::OutOfRange(_)), "{e:?}");
    assert!(
        e.to_string().contains("mesh table") && e.to_string().contains("beyond"),
        "{e}"
    );
    let far = shapes::cuboid(DVec3::splat(10.0)).unwrap();
    let e = MeshObject::new(
        "far",
        &far,
        &Placement::translation(DVec3::new(0.0, 2e6, 0.0)),
        "x",
        Some(0.03),
        false,
    )
    .unwrap_err();
    assert!(e.to_string().contains("mesh far"), "{e}");
    let big = shapes::cuboid(DVec3::new(1.9e6, 20.0, 1000.0)).unwrap();
    MeshObject::new("big", &big, &Placement::default(), "x", Some(0.03), false).unwrap();
}
