//! Analytic solids (`MeshObject::analytic`): chords against closed forms and against an
//! independent point-membership integration, the degenerate rays (tangent, axis-parallel,
//! starting inside), and a DRR of a sphere in a volume against the chord formula per pixel.
//! Tolerances are stated on each test.

mod common;

use common::*;
use glam::DVec3;
use rand::Rng;
use std::sync::Arc;
use tomograf_sim::mesh::{MeshObject, MeshScene, Placement, Solid, shapes};
use tomograf_sim::{Projector, Ray, Renderer, Volume};

fn solid(p: Solid, placement: Placement) -> MeshObject {
    MeshObject::analytic("s", p, &placement, "test", Some(0.1)).unwrap()
}

fn sphere(r: f64) -> Solid {
    Solid::Ellipsoid {
        radii: DVec3::splat(r),
    }
}

/// A line through `p` along `d`, 1 m either side.
fn through(p: DVec3, d: DVec3) -> Ray {
    let d = d.normalize();
    Ray::segment(p - 1000.0 * d, p + 1000.0 * d)
}

/// The sphere chord at distance `b` from the centre, `2√(r² − b²)`.
fn sphere_chord(centre: DVec3, r: f64, ray: &Ray) -> f64 {
    let b = (centre - ray.origin).cross(ray.direction).length();
    if b >= r {
        0.0
    } else {
        2.0 * (r * r - b * b).sqrt()
    }
}

/// Sphere chords at random offsets against `2√(r² − b²)`, to 1e-9 mm (f64 rounding of
/// coordinates ~1e3 mm is ~1e-13; the margin covers the subtraction of two roots).
#[test]
fn sphere_chords_match_the_closed_form() {
    let (c, r) = (DVec3::new(12.0, -40.0, 7.5), 35.0);
    let s = solid(sphere(r), Placement::translation(c));
    let mut g = rng(1);
    for _ in 0..2000 {
        let p = c + DVec3::new(
            g.random_range(-40.0..40.0),
            g.random_range(-40.0..40.0),
            g.random_range(-40.0..40.0),
        );
        let d = DVec3::new(
            g.random_range(-1.0..1.0),
            g.random_range(-1.0..1.0),
            g.random_range(-1.0..1.0),
        );
        let ray = through(p, d);
        let (got, want) = (s.path_length(&ray), sphere_chord(c, r, &ray));
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }
    // Through the centre along an axis: exactly the diameter.
    let ray = through(c, DVec3::X);
    assert!((s.path_length(&ray) - 2.0 * r).abs() < 1e-12);
    // Tangent and missing: nothing.
    let ray = through(c + DVec3::new(0.0, r, 0.0), DVec3::X);
    assert_eq!(s.path_length(&ray), 0.0);
    let ray = through(c + DVec3::new(0.0, r + 1e-9, 0.0), DVec3::X);
    assert_eq!(s.path_length(&ray), 0.0);
    // Volume.
    let v = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    assert!((s.volume_mm3() - v).abs() < 1e-9 * v);
}

/// Length of `ray` inside `inside(p)`, by the midpoint rule over `n` steps of its
/// `[t_min, t_max]` — independent of the closed forms; its error is below one step per
/// boundary crossing.
fn integrate(ray: &Ray, n: usize, inside: impl Fn(DVec3) -> bool) -> (f64, f64) {
    let step = (ray.t_max - ray.t_min) / n as f64;
    let len = (0..n)
        .filter(|&i| inside(ray.origin + ray.direction * (ray.t_min + (i as f64 + 0.5) * step)))
        .count() as f64
        * step;
    (len, step)
}

/// Rotated, scaled and sheared placements of an ellipsoid, a cylinder and a box: the
/// exact interval against a point-membership integration through the inverse placement
/// (2·10⁵ steps over 2 m: 0.01 mm; tolerance two steps, for the two crossings).
#[test]
fn placed_solids_match_point_membership_integration() {
    let mut g = rng(7);
    let primitives = [
        Solid::Ellipsoid {
            radii: DVec3::new(30.0, 12.0, 20.0),
        },
        Solid::circular_cylinder(15.0, 50.0),
        Solid::Cylinder {
            radii: [18.0, 7.0],
            height: 40.0,
        },
        Solid::Box {
            size: DVec3::new(40.0, 10.0, 25.0),
        },
    ];
    let placements = [
        Placement::Pose {
            rotation_deg: [20.0, -35.0, 70.0],
            scale: [1.0, 1.0, 1.0],
            translation_mm: [5.0, -10.0, 30.0],
        },
        Placement::Pose {
            rotation_deg: [0.0, 90.0, 10.0],
            scale: [1.5, 0.7, 1.2],
            translation_mm: [-20.0, 0.0, 0.0],
        },
        // A shear.
        Placement::Matrix {
            matrix: [
                [1.0, 0.4, 0.0, 3.0],
                [0.0, 1.0, 0.2, -4.0],
                [0.1, 0.0, 1.0, 8.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
        },
    ];
    for p in primitives {
        for placement in placements {
            let s = solid(p, placement);
            let m = placement.matrix().unwrap();
            let to_local = m.inverse();
            let inside = |w: DVec3| {
                let q = to_local.transform_point3(w);
                match p {
                    Solid::Ellipsoid { radii } => (q / radii).length_squared() < 1.0,
                    Solid::Cylinder { radii, height } => {
                        (q.x / radii[0]).powi(2) + (q.y / radii[1]).powi(2) < 1.0
                            && q.z.abs() < height / 2.0
                    }
                    Solid::Box { size } => (q.abs() - size / 2.0).max_element() < 0.0,
                }
            };
            let (lo, hi) = s.bounds();
            let centre = m.transform_point3(DVec3::ZERO);
            let mut hit = 0;
            for _ in 0..40 {
                let at = centre
                    + DVec3::new(
                        g.random_range(-25.0..25.0),
                        g.random_range(-25.0..25.0),
                        g.random_range(-25.0..25.0),
                    );
                let d = DVec3::new(
                    g.random_range(-1.0..1.0),
                    g.random_range(-1.0..1.0),
                    g.random_range(-1.0..1.0),
                );
                let ray = through(at, d);
                let (want, step) = integrate(&ray, 200_000, inside);
                let got = s.path_length(&ray);
                assert!(
                    (got - want).abs() <= 2.0 * step,
                    "{} under {placement:?}: {got} vs {want} (step {step})",
                    p.kind()
                );
                hit += usize::from(got > 0.0);
                // The bounds hold the solid: points inside are inside the box.
                if got > 0.0 {
                    let mut iv = Vec::new();
                    s.inside(&ray, &mut iv);
                    for i in &iv {
                        let q = ray.origin + ray.direction * (0.5 * (i.t0 + i.t1));
                        assert!(
                            q.cmpge(lo).all() && q.cmple(hi).all(),
                            "{q} outside {lo}..{hi}"
                        );
                    }
                }
            }
            assert!(hit > 10, "{}: only {hit} of 40 rays hit", p.kind());
        }
    }
}

/// Rays parallel to a cylinder's axis (inside: the height; outside: nothing), along a
/// box's face planes (outside by a hair: nothing), and a ray that starts inside a solid
/// (only the part after `t_min` counts).
#[test]
fn axis_parallel_face_and_inside_rays() {
    let cyl = solid(Solid::circular_cylinder(10.0, 30.0), Placement::default());
    assert!((cyl.path_length(&through(DVec3::new(3.0, -4.0, 0.0), DVec3::Z)) - 30.0).abs() < 1e-12);
    assert_eq!(
        cyl.path_length(&through(DVec3::new(10.5, 0.0, 0.0), DVec3::Z)),
        0.0
    );
    // Perpendicular through the axis: the diameter, exactly (a 64-sided mesh is short).
    // At π/64 from x the line crosses the 64-gon's edges at their midpoints.
    let a = std::f64::consts::PI / 64.0;
    let across = through(DVec3::ZERO, DVec3::new(a.cos(), a.sin(), 0.0));
    assert!((cyl.path_length(&across) - 20.0).abs() < 1e-12);
    let facets = MeshObject::new(
        "facets",
        &shapes::cylinder(10.0, 30.0, 64).unwrap(),
        &Placement::default(),
        "test",
        Some(0.1),
        true,
    )
    .unwrap();
    let short = 1.0 - facets.path_length(&across) / 20.0;
    assert!(
        (short - (1.0 - a.cos())).abs() < 1e-12,
        "the 64-sided mesh is short by {short}"
    );

    let boxed = solid(
        Solid::Box {
            size: DVec3::new(20.0, 20.0, 20.0),
        },
        Placement::default(),
    );
    assert!(
        (boxed.path_length(&through(DVec3::new(9.999, 0.0, 0.0), DVec3::Y)) - 20.0).abs() < 1e-12
    );
    assert_eq!(
        boxed.path_length(&through(DVec3::new(10.0, 0.0, 0.0), DVec3::Y)),
        0.0
    );
    assert_eq!(
        boxed.path_length(&through(DVec3::new(10.0, 10.0, 0.0), DVec3::Z)),
        0.0
    );

    // Starting inside: from the centre outwards, the radius.
    let s = solid(sphere(25.0), Placement::default());
    let ray = Ray::segment(DVec3::ZERO, DVec3::new(0.0, 0.0, 100.0));
    assert!((s.path_length(&ray) - 25.0).abs() < 1e-12);
    // Wholly inside: the whole segment.
    let ray = Ray::segment(DVec3::new(-5.0, 0.0, 0.0), DVec3::new(5.0, 0.0, 0.0));
    assert!((s.path_length(&ray) - 10.0).abs() < 1e-12);
}

/// Bad sizes and placements are refused with the solid and the size named.
#[test]
fn bad_solids_are_refused() {
    for (p, words) in [
        (sphere(0.0), "radius x is 0"),
        (Solid::circular_cylinder(5.0, f64::NAN), "height is NaN"),
        (
            Solid::Box {
                size: DVec3::new(1.0, -1.0, 1.0),
            },
            "box size y is -1",
        ),
    ] {
        let e = MeshObject::analytic("lesion", p, &Placement::default(), "x", Some(0.1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("lesion") && e.contains(words), "{e}");
    }
    let singular = Placement::Pose {
        rotation_deg: [0.0; 3],
        scale: [1.0, 0.0, 1.0],
        translation_mm: [0.0; 3],
    };
    let e = MeshObject::analytic("s", sphere(1.0), &singular, "x", Some(0.1)).unwrap_err();
    assert!(e.to_string().contains("singular"), "{e}");
    let e = MeshObject::analytic("s", sphere(1.0), &Placement::default(), "x", Some(f64::NAN))
        .unwrap_err();
    assert!(e.to_string().contains("mu"), "{e}");
}

/// A sphere of mu_s inside a uniform volume of mu_v, rendered in cone beam through the
/// whole pipeline (packets and the scalar mesh path): every pixel equals
/// `mu_v·(chord through the grid) + (mu_s − mu_v)·(sphere chord)` (the sphere replaces
/// the voxels) with the chords in closed form. Tolerance 1e-5 relative: the image is f32.
#[test]
fn a_rendered_sphere_matches_the_chord_formula() {
    let (mu_v, mu_s, r) = (0.02f32, 0.3, 30.0);
    let n = 40;
    let vol = Volume::centred(
        [n; 3],
        DVec3::splat(2.5),
        DVec3::ZERO,
        vec![mu_v; n * n * n],
    )
    .unwrap();
    let c = DVec3::new(4.0, -3.0, 2.0);
    let scene = Arc::new(MeshScene::new(vec![
        MeshObject::analytic(
            "ball",
            sphere(r),
            &Placement::translation(c),
            "b",
            Some(mu_s),
        )
        .unwrap(),
    ]));
    let geometry = tomograf_sim::Geometry {
        beam: tomograf_sim::Beam::Cone {
            sad_mm: 500.0,
            sid_mm: 800.0,
        },
        detector: tomograf_sim::Detector::new(48, 40, 4.0),
        isocentre: DVec3::ZERO,
    };
    let half = 50.0; // the grid spans ±50 mm
    for projector in [Projector::Siddon, Projector::Trilinear { step_voxels: 0.5 }] {
        let renderer = Renderer::new(&vol, projector)
            .unwrap()
            .with_meshes(scene.clone())
            .unwrap();
        for theta in [0.0, 33.0] {
            let view = geometry
                .view(tomograf_sim::Pose {
                    theta_deg: theta,
                    phi_deg: 10.0,
                })
                .unwrap();
            let img = renderer.render(&view).unwrap();
            let mut inside = 0;
            for row in 0..view.rows {
                for col in 0..view.cols {
                    let ray = view.ray(row as f64, col as f64);
                    let grid = box_chord(ray, half);
                    let chord = sphere_chord(c, r, &ray);
                    let want = f64::from(mu_v) * grid + (mu_s - f64::from(mu_v)) * chord;
                    let got = f64::from(img.at(row, col));
                    // Trilinear: exact on a uniform field, but its steps cut the voxels'
                    // intervals at the grid and sphere boundaries within a step (1.25 mm ×
                    // mu_v = 0.025 each).
                    let tol = match projector {
                        Projector::Siddon => 1e-5 * want.max(1.0),
                        Projector::Trilinear { .. } => 0.06,
                    };
                    assert!(
                        (got - want).abs() < tol,
                        "{projector:?} θ {theta} ({row}, {col}): {got} vs {want}"
                    );
                    inside += usize::from(chord > 0.0);
                }
            }
            assert!(inside > 100, "the sphere covers {inside} pixels");
        }
    }
}

/// The chord of `ray` through the axis-aligned cube `[-h, h]³`.
fn box_chord(ray: Ray, h: f64) -> f64 {
    let (mut t0, mut t1) = (ray.t_min, ray.t_max);
    for a in 0..3 {
        let (o, d) = (ray.origin[a], ray.direction[a]);
        if d == 0.0 {
            if o.abs() >= h {
                return 0.0;
            }
            continue;
        }
        let (p, q) = ((-h - o) / d, (h - o) / d);
        t0 = t0.max(p.min(q));
        t1 = t1.min(p.max(q));
    }
    (t1 - t0).max(0.0)
}

/// Analytic and triangle solids mix by the meshes' rule: the later entry holds the overlap.
#[test]
fn solids_and_meshes_share_the_overlap_rule() {
    let a = MeshObject::new(
        "a",
        &shapes::cuboid(DVec3::splat(10.0)).unwrap(),
        &Placement::default(),
        "a",
        Some(1.0),
        true,
    )
    .unwrap();
    let b = solid(
        sphere(5.0),
        Placement::translation(DVec3::new(6.0, 0.0, 0.0)),
    );
    let scene = MeshScene::new(vec![a, b]);
    let ray = Ray::segment(DVec3::new(-50.0, 0.0, 0.0), DVec3::new(50.0, 0.0, 0.0));
    let l = scene.path_lengths(&ray);
    // Box x ∈ [−5, 5], sphere x ∈ [1, 11]: box holds [−5, 1], sphere [1, 11].
    assert!(
        (l[0] - 6.0).abs() < 1e-12 && (l[1] - 10.0).abs() < 1e-12,
        "{l:?}"
    );
}
