//! Empty-space skipping changes no result: renders and single rays traced with and
//! without skipping are compared on the chest phantom and on sparse random volumes, with
//! random, axis-parallel (lying in brick planes) and brick-corner rays.
//!
//! Tolerances: trilinear — bit-identical (the same samples in the same order; skipped
//! samples are exact zeros). Siddon — 1e-12 relative: the same voxels and lengths, but
//! runs are grouped differently at interval ends, so additions are re-associated
//! (~1e-16 each over ≤ a few hundred terms).

mod common;

use common::*;
use glam::DVec3;
use rand::Rng;
use tomograf_sim::accel::bricks::BrickMap;
use tomograf_sim::accel::intervals::{BrickBvh, Interval, dda_intervals};
use tomograf_sim::accel::{EmptySpace, Finder, SkipOptions};
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::{Beam, Detector, Geometry, GridRay, Pose, Projector, Ray, Renderer, Volume};

const SIDDON_TOL: f64 = 1e-12;

fn chest() -> Volume {
    let hu = Phantom::thorax()
        .voxelize([72, 60, 20], DVec3::new(6.0, 6.0, 12.0), DVec3::ZERO)
        .unwrap();
    Attenuation::hounsfield_at_kev(60.0)
        .unwrap()
        .to_mu(hu)
        .unwrap()
}

/// A random volume with non-zero values only in a few random blobs.
fn sparse(r: &mut rand_chacha::ChaCha8Rng, dims: [usize; 3], rotate: bool) -> Volume {
    let base = random_volume(r, dims, rotate);
    let blobs: Vec<([f64; 3], f64)> = (0..4)
        .map(|_| {
            let c = dims.map(|d| r.random_range(0.0..d as f64));
            (c, r.random_range(0.5..4.0))
        })
        .collect();
    let mut data = base.data().to_vec();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
                let inside = blobs
                    .iter()
                    .any(|(c, rad)| (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>() < rad * rad);
                if !inside {
                    data[i + dims[0] * (j + dims[1] * k)] = 0.0;
                }
            }
        }
    }
    Volume::new(dims, base.spacing(), base.origin(), base.direction(), data).unwrap()
}

fn world(vol: &Volume, g: [f64; 3]) -> DVec3 {
    grid_to_world(vol, DVec3::from(g))
}

/// Random rays, axis-parallel rays in brick planes and rays through brick corners.
fn rays(vol: &Volume, r: &mut rand_chacha::ChaCha8Rng, brick: f64) -> Vec<Ray> {
    let d = vol.dims().map(|n| n as f64);
    let mut out = Vec::new();
    for _ in 0..150 {
        let a = world(vol, d.map(|n| r.random_range(-10.0..n + 10.0)));
        let b = world(vol, d.map(|n| r.random_range(-10.0..n + 10.0)));
        if (a - b).length() > 1e-3 {
            out.push(Ray::segment(a, b));
        }
    }
    for axis in 0..3 {
        let (o1, o2) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut p1 = 0.0;
        while p1 <= d[o1] {
            let mut p2 = 0.0;
            while p2 <= d[o2] {
                for (q1, q2) in [(p1, p2), (p1 + 0.5, p2), (p1 + 0.37, p2 + 0.61)] {
                    let mut a = [0.0; 3];
                    a[o1] = q1;
                    a[o2] = q2;
                    let mut b = a;
                    a[axis] = -5.0;
                    b[axis] = d[axis] + 5.0;
                    out.push(Ray::segment(world(vol, a), world(vol, b)));
                    out.push(Ray::segment(world(vol, b), world(vol, a)));
                }
                p2 += brick;
            }
            p1 += brick;
        }
    }
    // Diagonals through brick corners, all eight directions.
    for s in 0..8 {
        let sign = [s & 1, s & 2, s & 4].map(|b| if b == 0 { 1.0 } else { -1.0 });
        let c = [brick, brick, brick];
        let a = std::array::from_fn(|i| c[i] - 40.0 * sign[i]);
        let b = std::array::from_fn(|i| c[i] + 40.0 * sign[i]);
        out.push(Ray::segment(world(vol, a), world(vol, b)));
    }
    out
}

fn check_rays(vol: &Volume, rays: &[Ray], what: &str) {
    for projector in [
        Projector::Siddon,
        Projector::Trilinear { step_voxels: 0.37 },
    ] {
        let plain = Renderer::new(vol, projector).unwrap();
        for brick in [1, 4, 8, 16] {
            for finder in [Finder::Dda, Finder::Bvh] {
                let o = SkipOptions {
                    brick,
                    finder,
                    ..SkipOptions::default()
                };
                let fast = plain.clone().with_skipping(Some(o)).unwrap();
                for ray in rays {
                    let (a, b) = (plain.line_integral(ray), fast.line_integral(ray));
                    let ok = match projector {
                        Projector::Siddon => rel_err(a, b) <= SIDDON_TOL,
                        Projector::Trilinear { .. } => a.to_bits() == b.to_bits(),
                    };
                    assert!(
                        ok,
                        "{what} {projector:?} {o:?}: {a} without, {b} with skipping, {ray:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn chest_phantom_rays_unchanged() {
    let vol = chest();
    let rays = rays(&vol, &mut rng(7), 8.0);
    check_rays(&vol, &rays, "chest");
}

#[test]
fn sparse_random_volumes_rays_unchanged() {
    let mut r = rng(11);
    for case in 0..6 {
        let dims = [
            r.random_range(5..40),
            r.random_range(5..40),
            r.random_range(5..40),
        ];
        let vol = sparse(&mut r, dims, case % 2 == 1);
        let rays = rays(&vol, &mut r, 4.0);
        check_rays(&vol, &rays, &format!("sparse {dims:?}"));
    }
}

#[test]
fn chest_renders_unchanged() {
    let vol = chest();
    let view = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(48, 40, 12.0),
        isocentre: DVec3::ZERO,
    };
    for pose in [
        Pose {
            theta_deg: 0.0,
            phi_deg: 0.0,
        },
        Pose {
            theta_deg: 90.0,
            phi_deg: 0.0,
        },
        Pose {
            theta_deg: 33.0,
            phi_deg: 21.0,
        },
    ] {
        let view = view.view(pose).unwrap();
        for projector in [Projector::Siddon, Projector::Trilinear { step_voxels: 0.5 }] {
            let plain = Renderer::new(&vol, projector).unwrap();
            let a = plain.render(&view).unwrap();
            for finder in [Finder::Dda, Finder::Bvh] {
                let o = SkipOptions {
                    brick: 8,
                    finder,
                    ..SkipOptions::default()
                };
                let b = plain
                    .clone()
                    .with_skipping(Some(o))
                    .unwrap()
                    .render(&view)
                    .unwrap();
                for (x, y) in a.data.iter().zip(&b.data) {
                    let ok = match projector {
                        // f32 pixels of values equal to 1e-12: equal, or one f32 ulp apart
                        // when the f64 value sits on a rounding boundary.
                        Projector::Siddon => {
                            rel_err(f64::from(*x), f64::from(*y)) <= f64::from(f32::EPSILON)
                        }
                        Projector::Trilinear { .. } => x.to_bits() == y.to_bits(),
                    };
                    assert!(ok, "{projector:?} {pose:?} {finder:?}: {x} vs {y}");
                }
                assert!(a.data.iter().any(|&v| v > 1.0), "the view sees the phantom");
            }
        }
    }
}

/// The DDA and the BVH find the same intervals (ends equal to 1e-9 mm: both are exact
/// plane crossings, computed through different but equivalent expressions at corners).
#[test]
fn dda_and_bvh_agree() {
    let mut r = rng(3);
    let vol = sparse(&mut r, [37, 29, 23], true);
    for brick in [2, 5, 8] {
        let map = BrickMap::nonzero(&vol, brick).unwrap();
        let bvh = BrickBvh::build(&map);
        let (mut a, mut b) = (Vec::<Interval>::new(), Vec::<Interval>::new());
        let mut nonempty = 0;
        for ray in rays(&vol, &mut r, brick as f64) {
            let Some(g) = GridRay::clip(&vol, &ray) else {
                continue;
            };
            dda_intervals(&map, &g, &mut a);
            bvh.intervals(&g, &mut b);
            // Sub-1e-9 slivers can appear in one and not the other at brick corners.
            a.retain(|i| i.t1 - i.t0 > 1e-9);
            b.retain(|i| i.t1 - i.t0 > 1e-9);
            assert_eq!(a.len(), b.len(), "{a:?} vs {b:?}");
            for (x, y) in a.iter().zip(&b) {
                assert!((x.t0 - y.t0).abs() < 1e-9 && (x.t1 - y.t1).abs() < 1e-9);
            }
            nonempty += usize::from(!a.is_empty());
        }
        assert!(nonempty > 20, "the rays hit occupied bricks");
    }
}

/// The dilation matters: a map built without it skips non-zero trilinear samples next to
/// an occupied brick, so the check above could fail.
#[test]
fn trilinear_needs_the_dilated_map() {
    let dims = [16, 8, 8];
    let mut data = vec![0.0f32; 16 * 8 * 8];
    data[8 + 16 * (4 + 8 * 4)] = 1.0; // voxel (8, 4, 4): first voxel of brick 1 along i
    let vol = Volume::centred(dims, DVec3::ONE, DVec3::ZERO, data).unwrap();
    let ray = GridRay::clip(
        &vol,
        &Ray::segment(world(&vol, [-1.0, 4.5, 4.5]), world(&vol, [17.0, 4.5, 4.5])),
    )
    .unwrap();
    let step = 0.05;
    let full = tomograf_sim::trace::trilinear::march(vol.data(), dims, &ray, step);
    let opts = SkipOptions {
        brick: 8,
        finder: Finder::Dda,
        threshold: 0.0,
    };
    let dilated = EmptySpace::for_trilinear(&vol, opts).unwrap();
    let undilated = EmptySpace::from_map(BrickMap::nonzero(&vol, 8).unwrap(), Finder::Dda);
    assert_eq!(dilated.trilinear(vol.data(), dims, &ray, step), full);
    assert!(undilated.trilinear(vol.data(), dims, &ray, step) < full);
    assert!(full > 0.9, "{full}");
}

/// A CT whose air is not exactly zero (1e-6 mm⁻¹ everywhere, like noise around −1000 HU):
/// with a skipping threshold of 1e-5 mm⁻¹ rays are clipped to the box of occupied bricks
/// (the SIMD packets see only that) and the scalar tracer also skips the empty bricks
/// inside it. Both errors are bounded by threshold × the ray's length in the grid.
#[test]
fn noisy_air_with_a_threshold_errs_by_at_most_threshold_times_length() {
    let exact = chest();
    let noisy = exact.map(|v| v + 1e-6).unwrap();
    let threshold = 1e-5f32;
    let view = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(48, 40, 12.0),
        isocentre: DVec3::ZERO,
    }
    .view(Pose::new(20.0, 10.0))
    .unwrap();
    let o = SkipOptions {
        threshold,
        ..SkipOptions::default()
    };
    let plain = Renderer::new(&noisy, Projector::Siddon).unwrap();
    let fast = plain.clone().with_skipping(Some(o)).unwrap();
    let scalar = fast.clone().with_packet_threshold(f64::INFINITY);
    let (a, b, c) = (
        plain.render(&view).unwrap(),
        fast.render(&view).unwrap(),
        scalar.render(&view).unwrap(),
    );
    let mut skipped_some = false;
    for r in 0..view.rows {
        for col in 0..view.cols {
            let i = r * view.cols + col;
            let ray = view.ray(r as f64, col as f64);
            let length = GridRay::clip(&noisy, &ray).map_or(0.0, |g| g.t_exit - g.t_enter);
            let (x, y, z) = (
                f64::from(a.data[i]),
                f64::from(b.data[i]),
                f64::from(c.data[i]),
            );
            // f32 pixels: one ulp of slack on top of the bound.
            let bound = f64::from(threshold) * length + f64::from(f32::EPSILON) * x.abs();
            for (what, v) in [("packets", y), ("scalar", z)] {
                assert!(
                    (x - v).abs() <= bound && v <= x + f64::from(f32::EPSILON) * x.abs(),
                    "pixel ({r}, {col}): {x} without, {v} with skipping ({what}, bound {bound})"
                );
            }
            skipped_some |= x - y > 1e-6 * length * 0.5;
        }
    }
    assert!(skipped_some, "the threshold skipped some noisy air");
}
