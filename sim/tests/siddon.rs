//! Exact Siddon tracing against an independent brute-force reference (all plane crossings
//! sorted in f64, each segment's midpoint looked up), on random and on degenerate rays.
//! Tolerance: 1e-9 relative — both compute the same exact sum in f64, and only the order
//! of additions (≈1e-16 each) and rounding of crossing parameters may differ.

#![allow(clippy::needless_range_loop)] // loops over the three grid axes read best with an index

mod common;

use common::*;
use glam::{DMat3, DVec3};
use rand::Rng;
use tomograf_sim::trace::accumulate::PathRecorder;
use tomograf_sim::trace::siddon;
use tomograf_sim::{GridRay, Projector, Ray, Renderer, Volume};

const TOL: f64 = 1e-9;

fn siddon(vol: &Volume, ray: &Ray) -> f64 {
    Renderer::new(vol, Projector::Siddon)
        .unwrap()
        .line_integral(ray)
}

fn check(vol: &Volume, ray: &Ray, what: &str) {
    let ours = siddon(vol, ray);
    let reference = brute_force(vol, ray);
    assert!(ours.is_finite());
    assert!(
        rel_err(ours, reference) <= TOL || (ours - reference).abs() < 1e-13,
        "{what}: siddon {ours} vs reference {reference} for {ray:?}"
    );
}

fn random_point_near(vol: &Volume, r: &mut rand_chacha::ChaCha8Rng, margin: f64) -> DVec3 {
    let d = vol.dims();
    let g = DVec3::new(
        r.random_range(-margin..d[0] as f64 + margin),
        r.random_range(-margin..d[1] as f64 + margin),
        r.random_range(-margin..d[2] as f64 + margin),
    );
    grid_to_world(vol, g)
}

#[test]
fn random_cone_rays_match_reference() {
    let mut r = rng(1);
    for case in 0..40 {
        let dims = [
            r.random_range(1..24),
            r.random_range(1..24),
            r.random_range(1..24),
        ];
        let vol = random_volume(&mut r, dims, case % 2 == 1);
        for _ in 0..50 {
            // Source far outside, end point far outside: the ray crosses the volume.
            let a = random_point_near(&vol, &mut r, 30.0);
            let b = random_point_near(&vol, &mut r, 30.0);
            if (a - b).length() < 1e-6 {
                continue;
            }
            check(&vol, &Ray::segment(a, b), "random");
        }
    }
}

#[test]
fn sources_and_ends_inside_the_volume() {
    let mut r = rng(2);
    for case in 0..20 {
        let vol = random_volume(&mut r, [16, 12, 9], case % 2 == 0);
        for _ in 0..50 {
            let a = random_point_near(&vol, &mut r, -1.0); // strictly inside
            let b = random_point_near(&vol, &mut r, 5.0);
            check(&vol, &Ray::segment(a, b), "source inside");
            check(&vol, &Ray::segment(b, a), "end inside");
        }
    }
}

#[test]
fn parallel_lines_of_infinite_extent() {
    let mut r = rng(3);
    let vol = random_volume(&mut r, [20, 17, 11], true);
    for _ in 0..200 {
        let p = random_point_near(&vol, &mut r, 2.0);
        let d = DVec3::new(
            r.random_range(-1.0..1.0),
            r.random_range(-1.0..1.0),
            r.random_range(-1.0..1.0),
        )
        .normalize();
        let ray = Ray {
            origin: p,
            direction: d,
            t_min: f64::NEG_INFINITY,
            t_max: f64::INFINITY,
        };
        check(&vol, &ray, "parallel");
    }
}

/// A grid whose world ↔ grid transform is exact in binary floating point, so rays can be
/// placed exactly on voxel faces, edges and corners.
fn exact_grid(dims: [usize; 3]) -> Volume {
    let spacing = DVec3::new(1.0, 0.5, 2.0);
    let n = dims[0] * dims[1] * dims[2];
    let data = (0..n)
        .map(|i| 0.001 * ((i * 7919) % 101) as f32 + 0.01)
        .collect();
    Volume::new(dims, spacing, 0.5 * spacing, DMat3::IDENTITY, data).unwrap()
}

#[test]
fn axis_parallel_rays_on_faces_edges_and_inside() {
    let vol = exact_grid([7, 6, 5]);
    let s = vol.spacing();
    // Grid coordinate g maps to world g·s exactly.
    let w = |g: [f64; 3]| DVec3::from(g) * s;
    let offsets = [0.0, 0.25, 1.0, 3.0, 3.5, 5.0, 6.0, 7.0];
    for axis in 0..3 {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        for &ob in &offsets {
            for &oc in &offsets {
                for sign in [1.0, -1.0] {
                    let mut from = [0.0; 3];
                    let mut to = [0.0; 3];
                    from[axis] = if sign > 0.0 { -3.0 } else { 12.0 };
                    to[axis] = if sign > 0.0 { 12.0 } else { -3.0 };
                    from[b] = ob;
                    to[b] = ob;
                    from[c] = oc;
                    to[c] = oc;
                    let ray = Ray::segment(w(from), w(to));
                    check(&vol, &ray, "axis-parallel");
                    // Half-open voxels: a ray in the far face plane g = n misses.
                    let n = vol.dims();
                    if ob >= n[b] as f64 || oc >= n[c] as f64 {
                        assert_eq!(siddon(&vol, &ray), 0.0);
                    }
                }
            }
        }
    }
}

#[test]
fn rays_through_voxel_corners_and_edges() {
    let vol = exact_grid([8, 8, 8]);
    let s = vol.spacing();
    let w = |g: [f64; 3]| DVec3::from(g) * s;
    let mut r = rng(4);
    for _ in 0..300 {
        // Two lattice points (integer grid coordinates) outside/on the box: the ray passes
        // through corners, and often along edges and faces.
        let mut p = || {
            [
                r.random_range(-3..12) as f64,
                r.random_range(-3..12) as f64,
                r.random_range(-3..12) as f64,
            ]
        };
        let (a, b) = (p(), p());
        if a == b {
            continue;
        }
        check(&vol, &Ray::segment(w(a), w(b)), "corner");
    }
    // The main diagonals and face diagonals exactly.
    for (a, b) in [
        ([0.0, 0.0, 0.0], [8.0, 8.0, 8.0]),
        ([8.0, 8.0, 8.0], [0.0, 0.0, 0.0]),
        ([0.0, 8.0, 0.0], [8.0, 0.0, 8.0]),
        ([-1.0, -1.0, 4.0], [9.0, 9.0, 4.0]),
        ([0.0, 0.0, 0.0], [8.0, 8.0, 0.0]),
    ] {
        check(&vol, &Ray::segment(w(a), w(b)), "diagonal");
    }
}

#[test]
fn grazing_and_missing_rays() {
    let vol = exact_grid([5, 5, 5]);
    let s = vol.spacing();
    let w = |g: [f64; 3]| DVec3::from(g) * s;
    // In the lower face plane g_z = 0: inside (half-open voxels), equals the reference.
    let ray = Ray::segment(w([-2.0, 1.5, 0.0]), w([7.0, 3.5, 0.0]));
    assert!(siddon(&vol, &ray) > 0.0);
    check(&vol, &ray, "grazing lower face");
    // Touching only an edge or a corner: zero length.
    for (a, b) in [
        ([-2.0, 5.0, 7.0], [7.0, 5.0, -2.0]),
        ([5.0, 5.0, 5.0], [9.0, 9.0, 9.0]),
        ([-1.0, 6.0, 0.0], [6.0, -1.0, 0.0]),
    ] {
        check(&vol, &Ray::segment(w(a), w(b)), "touching");
    }
    // Missing entirely, and ending before the volume.
    assert_eq!(
        siddon(
            &vol,
            &Ray::segment(w([-1.0, -1.0, -1.0]), w([-1.0, 9.0, 9.0]))
        ),
        0.0
    );
    assert_eq!(
        siddon(
            &vol,
            &Ray::segment(w([-9.0, 2.0, 2.0]), w([-0.5, 2.0, 2.0]))
        ),
        0.0
    );
}

#[test]
fn path_lengths_sum_to_the_clipped_length_and_visit_each_voxel_once() {
    let mut r = rng(5);
    for _ in 0..200 {
        let vol = random_volume(&mut r, [9, 13, 6], true);
        let a = random_point_near(&vol, &mut r, 20.0);
        let b = random_point_near(&vol, &mut r, 20.0);
        let ray = Ray::segment(a, b);
        let Some(g) = GridRay::clip(&vol, &ray) else {
            continue;
        };
        let mut rec = PathRecorder::default();
        siddon::trace(vol.dims(), &g, &mut rec);
        let total: f64 = rec.segments.iter().map(|s| s.1).sum();
        assert!(
            rel_err(total, g.length()) < 1e-12,
            "{total} vs {}",
            g.length()
        );
        // Consecutive positive-length voxels are face neighbours, never repeated.
        let visited: Vec<usize> = rec
            .segments
            .iter()
            .filter(|s| s.1 > 1e-12)
            .map(|s| s.0)
            .collect();
        let mut sorted = visited.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), visited.len(), "a voxel was visited twice");
        assert!(rec.segments.iter().all(|s| s.1 >= 0.0 && s.0 < vol.len()));
    }
}

#[test]
fn rays_clipped_to_the_occupied_box_match_the_whole_grid_reference() {
    // Random values inside a sub-box, exact zeros (air) around it: the renderer clips rays
    // to the sub-box, the reference walks the whole grid.
    let mut r = rng(6);
    for case in 0..20 {
        let mut vol = random_volume(&mut r, [18, 15, 12], case % 2 == 0);
        let [nx, ny, nz] = vol.dims();
        let (lo, hi) = ([3, 1, 4], [11, 15, 9]);
        let data: Vec<f32> = vol
            .data()
            .iter()
            .enumerate()
            .map(|(n, &v)| {
                let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
                let inside = (lo[0]..hi[0]).contains(&i)
                    && (lo[1]..hi[1]).contains(&j)
                    && (lo[2]..hi[2]).contains(&k);
                if inside { v + 0.001 } else { 0.0 }
            })
            .collect();
        vol = Volume::new(
            [nx, ny, nz],
            vol.spacing(),
            vol.origin(),
            vol.direction(),
            data,
        )
        .unwrap();
        assert_eq!(
            tomograf_sim::occupancy::occupied(&vol).unwrap(),
            tomograf_sim::grid_box::GridBox { lo, hi }
        );
        for _ in 0..100 {
            let a = random_point_near(&vol, &mut r, 10.0);
            let b = random_point_near(&vol, &mut r, 10.0);
            check(&vol, &Ray::segment(a, b), "occupied box");
        }
    }
    // All air: every line integral is zero.
    let air = Volume::centred([4, 4, 4], DVec3::ONE, DVec3::ZERO, vec![0.0; 64]).unwrap();
    assert_eq!(tomograf_sim::occupancy::occupied(&air), None);
    assert_eq!(
        siddon(&air, &Ray::segment(DVec3::splat(-9.0), DVec3::splat(9.0))),
        0.0
    );
}
