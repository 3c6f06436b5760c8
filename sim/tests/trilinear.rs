//! The trilinear marcher against the exact integral of the trilinearly interpolated field.
//!
//! Reference: along a ray the clamped trilinear field is a polynomial of degree ≤ 3
//! between consecutive crossings of the dual-grid planes (through voxel centres) and the
//! box faces, so 3-point Gauss–Legendre on each such piece integrates it exactly.

#![allow(clippy::needless_range_loop)] // loops over the three grid axes read best with an index

mod common;

use common::*;
use rand::Rng;
use tomograf_sim::trace::trilinear;
use tomograf_sim::{GridRay, Projector, Ray, Renderer, Volume};

fn exact_trilinear(vol: &Volume, g: &GridRay) -> f64 {
    let dims = vol.dims();
    let mut ts = vec![g.t_enter, g.t_exit];
    for a in 0..3 {
        if g.gd[a] == 0.0 {
            continue;
        }
        for i in 0..dims[a] {
            let t = (i as f64 + 0.5 - g.g0[a]) / g.gd[a];
            if t > g.t_enter && t < g.t_exit {
                ts.push(t);
            }
        }
    }
    ts.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let nodes = [-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()];
    let weights = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    let mut sum = 0.0;
    for w in ts.windows(2) {
        let (mid, half) = (0.5 * (w[0] + w[1]), 0.5 * (w[1] - w[0]));
        for (x, wt) in nodes.iter().zip(weights) {
            sum += wt * half * trilinear::sample(vol.data(), dims, g.at(mid + x * half));
        }
    }
    sum
}

#[test]
fn sampler_hits_voxel_values_at_centres_and_is_linear_between() {
    let mut r = rng(10);
    let vol = random_volume(&mut r, [5, 4, 3], false);
    let d = vol.dims();
    for k in 0..3 {
        for j in 0..4 {
            for i in 0..5 {
                let g = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
                assert_eq!(
                    trilinear::sample(vol.data(), d, g),
                    f64::from(vol.get(i, j, k))
                );
            }
        }
    }
    // Halfway between two centres along x: the mean. In the outer half voxel: clamped.
    let mid = trilinear::sample(vol.data(), d, [1.0 + 0.5 + 0.5, 1.5, 1.5]);
    let expect = 0.5 * (f64::from(vol.get(1, 1, 1)) + f64::from(vol.get(2, 1, 1)));
    assert!((mid - expect).abs() < 1e-12);
    assert_eq!(
        trilinear::sample(vol.data(), d, [0.1, 1.5, 1.5]),
        f64::from(vol.get(0, 1, 1))
    );
}

#[test]
fn uniform_volume_gives_the_siddon_value_at_any_step() {
    let n = 20 * 15 * 10;
    let vol = Volume::centred(
        [20, 15, 10],
        glam::DVec3::new(0.7, 1.1, 2.5),
        glam::DVec3::ZERO,
        vec![0.02; n],
    )
    .unwrap();
    let mut r = rng(11);
    for _ in 0..100 {
        let a = grid_to_world(
            &vol,
            glam::DVec3::new(
                r.random_range(-10.0..30.0),
                -5.0,
                r.random_range(-5.0..15.0),
            ),
        );
        let b = grid_to_world(
            &vol,
            glam::DVec3::new(
                r.random_range(-10.0..30.0),
                25.0,
                r.random_range(-5.0..15.0),
            ),
        );
        let ray = Ray::segment(a, b);
        let s = Renderer::new(&vol, Projector::Siddon)
            .unwrap()
            .line_integral(&ray);
        for step in [0.3, 1.0, 2.0] {
            let t = Renderer::new(&vol, Projector::Trilinear { step_voxels: step })
                .unwrap()
                .line_integral(&ray);
            assert!((s - t).abs() <= 1e-12 * s.abs().max(1e-12), "{s} vs {t}");
        }
    }
}

/// RMS relative error of the marcher at several steps over random rays; returns the errors.
fn errors(steps: &[f64]) -> Vec<f64> {
    let mut r = rng(12);
    let vol = random_volume(&mut r, [24, 20, 16], true);
    let mut sq = vec![0.0; steps.len()];
    let mut count = 0;
    while count < 300 {
        let p = |r: &mut rand_chacha::ChaCha8Rng| {
            grid_to_world(
                &vol,
                glam::DVec3::new(
                    r.random_range(-20.0..44.0),
                    r.random_range(-20.0..40.0),
                    r.random_range(-20.0..36.0),
                ),
            )
        };
        let (a, b) = (p(&mut r), p(&mut r));
        let Some(g) = GridRay::clip(&vol, &Ray::segment(a, b)) else {
            continue;
        };
        if g.length() < 5.0 {
            continue;
        }
        let exact = exact_trilinear(&vol, &g);
        for (e, &h) in sq.iter_mut().zip(steps) {
            let m = trilinear::march(vol.data(), vol.dims(), &g, h);
            *e += ((m - exact) / exact).powi(2);
        }
        count += 1;
    }
    sq.iter().map(|e| (e / count as f64).sqrt()).collect()
}

#[test]
fn marcher_converges_to_the_exact_trilinear_integral_at_second_order() {
    let steps = [2.0, 1.0, 0.5, 0.25, 0.125];
    let e = errors(&steps);
    for w in e.windows(2) {
        let order = (w[0] / w[1]).log2();
        // Midpoint rule on a C0 piecewise cubic: order 2 in the limit; allow 1.6 for the
        // kinks at voxel centres at coarse steps.
        assert!(
            order > 1.6,
            "observed order {order:.2} between errors {w:?}"
        );
    }
    assert!(e[4] < 1e-3, "relative RMS error at step 0.125: {}", e[4]);
}
