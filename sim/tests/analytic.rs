//! Siddon against closed-form chord lengths through uniform boxes and slabs.
//! Tolerance 1e-12 relative: the exact answer is a single product, and the tracer's
//! f64 sum over ≤ 10³ voxels cannot drift further.

#![allow(clippy::needless_range_loop)] // loops over the three grid axes read best with an index

mod common;

use common::rel_err;
use glam::{DMat3, DVec3};
use tomograf_sim::{Projector, Ray, Renderer, Volume};

fn uniform(dims: [usize; 3], spacing: DVec3, direction: DMat3, mu: f32) -> Volume {
    let n = dims[0] * dims[1] * dims[2];
    let half = (DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) - 1.0) * 0.5;
    // Centre the box on the world origin whatever its orientation.
    let origin = -(direction * (half * spacing));
    Volume::new(dims, spacing, origin, direction, vec![mu; n]).unwrap()
}

fn siddon(vol: &Volume, ray: &Ray) -> f64 {
    Renderer::new(vol, Projector::Siddon)
        .unwrap()
        .line_integral(ray)
}

#[test]
fn straight_through_a_box() {
    let mu = 0.02f32;
    let vol = uniform([40, 30, 20], DVec3::new(0.7, 0.9, 2.5), DMat3::IDENTITY, mu);
    let m = f64::from(mu);
    // Along each axis through the centre (through a voxel face for even sizes).
    let l = siddon(
        &vol,
        &Ray::segment(DVec3::new(-500.0, 0.1, 0.2), DVec3::new(500.0, 0.1, 0.2)),
    );
    assert!(rel_err(l, m * 40.0 * 0.7) < 1e-12, "{l}");
    let l = siddon(
        &vol,
        &Ray::segment(DVec3::new(0.1, 0.1, 500.0), DVec3::new(0.1, 0.1, -500.0)),
    );
    assert!(rel_err(l, m * 20.0 * 2.5) < 1e-12, "{l}");
    // The space diagonal.
    let h = DVec3::new(40.0 * 0.7, 30.0 * 0.9, 20.0 * 2.5) * 0.5;
    let l = siddon(&vol, &Ray::segment(-2.0 * h, 2.0 * h));
    assert!(rel_err(l, m * (2.0 * h).length()) < 1e-12, "{l}");
}

#[test]
fn oblique_rays_through_a_slab() {
    // A 200 × 200 × 10 mm slab; rays through its centre at angle α to the normal cross
    // it over 10 / cos α mm (they leave through the big faces for α < 84°).
    let mu = 0.05f32;
    let vol = uniform(
        [100, 100, 5],
        DVec3::new(2.0, 2.0, 2.0),
        DMat3::IDENTITY,
        mu,
    );
    for deg in [0.0f64, 1.0, 10.0, 33.3, 45.0, 60.0, 80.0] {
        for az in [0.0f64, 0.4, 1.3, 2.9] {
            let a = deg.to_radians();
            let d = DVec3::new(a.sin() * az.cos(), a.sin() * az.sin(), a.cos());
            let ray = Ray::segment(
                -800.0 * d + DVec3::new(0.3, -0.2, 0.0),
                800.0 * d + DVec3::new(0.3, -0.2, 0.0),
            );
            let l = siddon(&vol, &ray);
            let exact = f64::from(mu) * 10.0 / a.cos();
            assert!(rel_err(l, exact) < 1e-12, "α={deg}: {l} vs {exact}");
        }
    }
}

#[test]
fn rotated_box_chord() {
    // A cube of side 32 mm rotated 45° about z: a ray along x through its centre crosses
    // the diagonal of the square cross-section, 32·√2 mm.
    let mu = 0.03f32;
    let vol = uniform(
        [32, 32, 8],
        DVec3::new(1.0, 1.0, 4.0),
        DMat3::from_rotation_z(std::f64::consts::FRAC_PI_4),
        mu,
    );
    let l = siddon(
        &vol,
        &Ray::segment(DVec3::new(-100.0, 0.0, 1.0), DVec3::new(100.0, 0.0, 1.0)),
    );
    assert!(
        rel_err(l, f64::from(mu) * 32.0 * 2f64.sqrt()) < 1e-12,
        "{l}"
    );
}
