//! Extreme inputs: one voxel, very long paths, huge attenuation.

#![allow(clippy::needless_range_loop)] // loops over the three grid axes read best with an index

mod common;

use common::*;
use glam::{DMat3, DVec3};
use rand::Rng;
use tomograf_sim::{Projector, Quantity, Ray, Renderer, Volume};

fn siddon(vol: &Volume, ray: &Ray) -> f64 {
    Renderer::new(vol, Projector::Siddon)
        .unwrap()
        .line_integral(ray)
}

#[test]
fn one_voxel_volume() {
    let vol = Volume::new(
        [1, 1, 1],
        DVec3::new(2.0, 3.0, 4.0),
        DVec3::new(1.0, 1.0, 1.0),
        DMat3::IDENTITY,
        vec![0.5],
    )
    .unwrap();
    let l = siddon(
        &vol,
        &Ray::segment(DVec3::new(-10.0, 1.0, 1.0), DVec3::new(10.0, 1.0, 1.0)),
    );
    assert!((l - 1.0).abs() < 1e-15);
    let mut r = rng(20);
    for _ in 0..500 {
        let p = |r: &mut rand_chacha::ChaCha8Rng| {
            DVec3::new(
                r.random_range(-3.0..5.0),
                r.random_range(-3.0..5.0),
                r.random_range(-3.0..5.0),
            )
        };
        let ray = Ray::segment(p(&mut r), p(&mut r));
        let (a, b) = (siddon(&vol, &ray), brute_force(&vol, &ray));
        assert!(rel_err(a, b) < 1e-9 || (a - b).abs() < 1e-14, "{a} vs {b}");
        let t = Renderer::new(&vol, Projector::Trilinear { step_voxels: 0.5 })
            .unwrap()
            .line_integral(&ray);
        assert!(
            (t - a).abs() < 1e-12,
            "uniform field: trilinear {t} vs siddon {a}"
        );
    }
}

#[test]
fn wide_thin_slab_1024_by_1024_by_8() {
    let (nx, ny, nz) = (1024, 1024, 8);
    let mut r = rng(21);
    let data: Vec<f32> = (0..nx * ny * nz)
        .map(|_| r.random_range(0.01f32..0.03))
        .collect();
    let vol = Volume::centred([nx, ny, nz], DVec3::new(0.5, 0.5, 2.0), DVec3::ZERO, data).unwrap();
    for _ in 0..40 {
        // Long rays almost in the slab's plane, and steep ones through it.
        let a = DVec3::new(
            r.random_range(-400.0..-300.0),
            r.random_range(-300.0..300.0),
            r.random_range(-7.0..7.0),
        );
        let b = DVec3::new(
            r.random_range(300.0..400.0),
            r.random_range(-300.0..300.0),
            r.random_range(-7.0..7.0),
        );
        let ray = Ray::segment(a, b);
        let (s, e) = (siddon(&vol, &ray), brute_force(&vol, &ray));
        assert!(rel_err(s, e) < 1e-9, "{s} vs {e}");
    }
}

#[test]
fn long_paths_keep_full_precision() {
    // 20 000 voxels of 0.1 mm with values that f32 accumulation would smear: the f64
    // reference sum is matched to 1e-12.
    let n = 20_000;
    let data: Vec<f32> = (0..n).map(|i| 0.01 + 1e-7 * (i % 7) as f32).collect();
    let exact: f64 = data.iter().map(|&v| f64::from(v) * 0.1).sum();
    let vol = Volume::new(
        [n, 1, 1],
        DVec3::new(0.1, 1.0, 1.0),
        DVec3::ZERO,
        DMat3::IDENTITY,
        data,
    )
    .unwrap();
    let l = siddon(
        &vol,
        &Ray::segment(DVec3::new(-10.0, 0.0, 0.0), DVec3::new(3000.0, 0.0, 0.0)),
    );
    assert!(rel_err(l, exact) < 1e-12, "{l} vs {exact}");
}

#[test]
fn huge_attenuation_underflows_to_zero_never_nan() {
    // mu = 1 mm⁻¹ over 800 mm: L = 800, exp(−800) underflows even f64.
    let vol = Volume::new(
        [800, 1, 1],
        DVec3::ONE,
        DVec3::ZERO,
        DMat3::IDENTITY,
        vec![1.0; 800],
    )
    .unwrap();
    let ray = Ray::segment(DVec3::new(-5.0, 0.0, 0.0), DVec3::new(900.0, 0.0, 0.0));
    let l = siddon(&vol, &ray);
    assert!(rel_err(l, 800.0) < 1e-12);
    for q in [Quantity::Transmission, Quantity::Intensity { i0: 1e6 }] {
        let v = q.from_line_integral(l);
        assert_eq!(v, 0.0);
        assert_eq!(
            q.from_line_integral(120.0) as f32,
            0.0,
            "f32 output underflows to 0 too"
        );
        assert!(!q.from_line_integral(120.0).is_nan());
    }
}
