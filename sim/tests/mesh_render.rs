//! Mesh objects combined with voxels: a mesh against the same shape voxelised, a mesh
//! across the volume border (closed forms), overlap priority, and `render` against the
//! per-ray integrals. Tolerances are stated on each test.

mod common;

use common::*;
use glam::DVec3;
use rand::Rng;
use std::sync::Arc;
use tomograf_sim::mesh::{MeshObject, MeshScene, Placement, TriMesh, shapes};
use tomograf_sim::{Projector, Ray, Renderer, Volume};

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

fn through(p: DVec3, d: DVec3) -> Ray {
    let d = d.normalize();
    Ray::segment(p - 500.0 * d, p + 500.0 * d)
}

/// A sphere mesh against the same sphere voxelised (voxel value = fraction of the voxel
/// inside, 4³ sub-samples): the mean |chord difference| falls as voxels shrink.
#[test]
fn mesh_and_voxelised_shape_agree_as_voxels_shrink() {
    let radius = 20.0;
    let sphere = object(&shapes::icosphere(radius, 6).unwrap(), DVec3::ZERO);
    let mut r = rng(9);
    let rays: Vec<Ray> = (0..200)
        .map(|_| {
            let p = DVec3::new(
                r.random_range(-15.0..15.0),
                r.random_range(-15.0..15.0),
                r.random_range(-15.0..15.0),
            );
            let d = DVec3::new(
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
            );
            through(p, d + DVec3::splat(1e-3))
        })
        .collect();
    let mut previous = f64::INFINITY;
    for voxel in [4.0, 2.0, 1.0] {
        let n = (2.0 * (radius + 2.0) / voxel) as usize;
        let vol = voxelised_sphere(radius, n, voxel);
        let renderer = Renderer::new(&vol, Projector::Siddon).unwrap();
        let err: f64 = rays
            .iter()
            .map(|ray| (renderer.line_integral(ray) - sphere.path_length(ray)).abs())
            .sum::<f64>()
            / rays.len() as f64;
        assert!(
            err < previous,
            "voxel {voxel}: mean error {err} after {previous}"
        );
        previous = err;
    }
    assert!(
        previous < 0.2,
        "1 mm voxels: mean chord error {previous} mm"
    );
}

fn voxelised_sphere(radius: f64, n: usize, voxel: f64) -> Volume {
    let half = n as f64 * voxel / 2.0;
    let mut data = vec![0.0f32; n * n * n];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let mut inside = 0;
                for s in 0..64 {
                    let f = |q: usize| (q as f64 + 0.5) / 4.0;
                    let p = DVec3::new(
                        (i as f64 + f(s % 4)) * voxel - half,
                        (j as f64 + f((s / 4) % 4)) * voxel - half,
                        (k as f64 + f(s / 16)) * voxel - half,
                    );
                    inside += usize::from(p.length() < radius);
                }
                data[i + n * (j + n * k)] = inside as f32 / 64.0;
            }
        }
    }
    Volume::centred([n; 3], DVec3::splat(voxel), DVec3::ZERO, data).unwrap()
}

/// A box mesh straddling the volume's border: inside the box its mu replaces the voxels';
/// outside the grid it still counts. Axis-parallel rays have closed-form integrals.
#[test]
fn mesh_overlapping_the_volume_border() {
    let (mu_vox, mu_mesh) = (0.02f32, 0.5);
    let vol = Volume::centred(
        [20, 20, 20],
        DVec3::splat(2.0),
        DVec3::ZERO,
        vec![mu_vox; 8000],
    )
    .unwrap();
    // Grid spans [-20, 20] mm. Box: x in [10, 40], y in [-5, 5], z in [-5, 5].
    let mesh = shapes::cuboid(DVec3::new(30.0, 10.0, 10.0)).unwrap();
    let o = MeshObject::new(
        "implant",
        &mesh,
        &Placement::translation(DVec3::new(25.0, 0.0, 0.0)),
        "ti",
        Some(mu_mesh),
        true,
    )
    .unwrap();
    let scene = Arc::new(MeshScene::new(vec![o]));
    for projector in [
        Projector::Siddon,
        Projector::Trilinear { step_voxels: 0.25 },
    ] {
        for skip in [None, Some(Default::default())] {
            let r = Renderer::new(&vol, projector)
                .unwrap()
                .with_skipping(skip)
                .unwrap()
                .with_meshes(scene.clone())
                .unwrap();
            // Along x through the box: 30 mm of voxels (−20..10), 30 mm of mesh (10..40).
            let ray = Ray::segment(DVec3::new(-100.0, 1.3, -2.1), DVec3::new(100.0, 1.3, -2.1));
            let expect = f64::from(mu_vox) * 30.0 + mu_mesh * 30.0;
            let got = r.line_integral(&ray);
            // Siddon: exact to rounding; trilinear: the clamped field is exact for a
            // uniform volume, the midpoint rule cuts the mesh boundary within one step.
            let tol = if projector == Projector::Siddon {
                1e-9
            } else {
                f64::from(mu_vox) * 0.5
            };
            assert!(
                (got - expect).abs() < tol,
                "{projector:?}: {got} vs {expect}"
            );
            // Missing the box: voxels only.
            let ray = Ray::segment(DVec3::new(-100.0, 8.0, 0.0), DVec3::new(100.0, 8.0, 0.0));
            assert!((r.line_integral(&ray) - f64::from(mu_vox) * 40.0).abs() < 1e-9);
            // Outside the grid entirely, through the box: mesh only.
            let ray = Ray::segment(DVec3::new(30.0, -100.0, 0.0), DVec3::new(30.0, 100.0, 0.0));
            assert!((r.line_integral(&ray) - mu_mesh * 10.0).abs() < 1e-9);
        }
    }
    // Overlapping meshes: the later one holds the overlap.
    let a = MeshObject::new(
        "a",
        &shapes::cuboid(DVec3::splat(10.0)).unwrap(),
        &Placement::default(),
        "a",
        Some(1.0),
        true,
    )
    .unwrap();
    let b = MeshObject::new(
        "b",
        &shapes::cuboid(DVec3::splat(10.0)).unwrap(),
        &Placement::translation(DVec3::new(6.0, 0.0, 0.0)),
        "b",
        Some(2.0),
        true,
    )
    .unwrap();
    let scene = MeshScene::new(vec![a, b]);
    let ray = Ray::segment(DVec3::new(-50.0, 0.5, 0.5), DVec3::new(50.0, 0.5, 0.5));
    let l = scene.path_lengths(&ray);
    assert!(
        (l[0] - 6.0).abs() < 1e-12 && (l[1] - 10.0).abs() < 1e-12,
        "{l:?}"
    );
}

/// `render` (row packets for rays whose voxel part no mesh overlaps, scalar otherwise)
/// agrees with the per-ray `line_integral` for every pixel, with a mesh inside the grid,
/// one outside it and one across its border. Tolerance: f32 rounding of the pixel
/// (plus ~1e-12 relative between the packet and scalar tracers).
#[test]
fn rendered_images_match_per_ray_integrals() {
    let mut r = rng(2);
    let vol = random_volume(&mut r, [30, 26, 20], false);
    let c = vol.centre();
    let objects = vec![
        MeshObject::new(
            "in",
            &shapes::icosphere(8.0, 2).unwrap(),
            &Placement::translation(c),
            "a",
            Some(0.3),
            true,
        )
        .unwrap(),
        MeshObject::new(
            "out",
            &shapes::cuboid(DVec3::new(300.0, 10.0, 300.0)).unwrap(),
            &Placement::translation(c + DVec3::new(0.0, 200.0, 0.0)),
            "b",
            Some(0.01),
            true,
        )
        .unwrap(),
        MeshObject::new(
            "border",
            &shapes::cylinder(5.0, 400.0, 16).unwrap(),
            &Placement::translation(c + DVec3::new(20.0, 0.0, 0.0)),
            "c",
            Some(0.2),
            true,
        )
        .unwrap(),
    ];
    let scene = Arc::new(MeshScene::new(objects));
    let geometry = tomograf_sim::Geometry {
        beam: tomograf_sim::Beam::Cone {
            sad_mm: 600.0,
            sid_mm: 900.0,
        },
        detector: tomograf_sim::Detector::new(40, 48, 3.0),
        isocentre: c,
    };
    for pose in [
        tomograf_sim::Pose {
            theta_deg: 0.0,
            phi_deg: 0.0,
        },
        tomograf_sim::Pose {
            theta_deg: 35.0,
            phi_deg: 15.0,
        },
    ] {
        let view = geometry.view(pose).unwrap();
        for projector in [Projector::Siddon, Projector::Trilinear { step_voxels: 0.5 }] {
            let renderer = Renderer::new(&vol, projector)
                .unwrap()
                .with_meshes(scene.clone())
                .unwrap();
            let img = renderer.render(&view).unwrap();
            let plain = Renderer::new(&vol, projector)
                .unwrap()
                .render(&view)
                .unwrap();
            let mut differ = 0;
            for row in 0..view.rows {
                for col in 0..view.cols {
                    let l = renderer.line_integral(&view.ray(row as f64, col as f64));
                    let px = f64::from(img.at(row, col));
                    assert!(
                        (px - l).abs() <= 1e-6 * l.abs().max(1.0),
                        "{projector:?} ({row}, {col}): {px} vs {l}"
                    );
                    differ += usize::from(img.at(row, col) != plain.at(row, col));
                }
            }
            assert!(
                differ > 100,
                "the meshes change the image ({differ} pixels)"
            );
        }
    }
}
