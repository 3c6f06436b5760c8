//! Shared helpers for the sim integration tests: random volumes and rays, and an
//! independent brute-force exact reference for line integrals.
#![allow(dead_code)]
#![allow(clippy::needless_range_loop)] // loops over the three grid axes read best with an index

use glam::{DMat3, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tomograf_sim::{Ray, Volume};

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A volume with random positive values, random anisotropic spacing, a random origin
/// and (optionally) a random rotation with or without reflection.
pub fn random_volume(r: &mut ChaCha8Rng, dims: [usize; 3], rotate: bool) -> Volume {
    let n = dims[0] * dims[1] * dims[2];
    let data = (0..n).map(|_| r.random_range(0.0f32..0.05)).collect();
    let spacing = DVec3::new(
        r.random_range(0.3..3.0),
        r.random_range(0.3..3.0),
        r.random_range(0.3..3.0),
    );
    let origin = DVec3::new(
        r.random_range(-50.0..50.0),
        r.random_range(-50.0..50.0),
        r.random_range(-50.0..50.0),
    );
    let dir = if rotate {
        let q = glam::DQuat::from_euler(
            glam::EulerRot::ZYX,
            r.random_range(-3.0..3.0),
            r.random_range(-3.0..3.0),
            r.random_range(-3.0..3.0),
        );
        let m = DMat3::from_quat(q);
        if r.random_bool(0.5) {
            m * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0))
        } else {
            m
        }
    } else {
        DMat3::IDENTITY
    };
    Volume::new(dims, spacing, origin, dir, data).unwrap()
}

/// Independent exact reference: every plane crossing of every axis within the ray's
/// range is collected in f64, sorted, and each sub-segment is attributed to the voxel
/// holding its midpoint (grid coordinates, half-open voxels).
pub fn brute_force(vol: &Volume, ray: &Ray) -> f64 {
    let g0 = vol.world_to_grid(ray.origin).to_array();
    let gd = vol.world_dir_to_grid(ray.direction).to_array();
    let dims = vol.dims();
    // Parameter range where the ray is inside the box, by plain interval intersection.
    let (mut lo, mut hi) = (ray.t_min, ray.t_max);
    for a in 0..3 {
        let n = dims[a] as f64;
        if gd[a] == 0.0 {
            if !(g0[a] >= 0.0 && g0[a] < n) {
                return 0.0;
            }
        } else {
            let (t1, t2) = ((0.0 - g0[a]) / gd[a], (n - g0[a]) / gd[a]);
            lo = lo.max(t1.min(t2));
            hi = hi.min(t1.max(t2));
        }
    }
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return 0.0;
    }
    let mut ts = vec![lo, hi];
    for a in 0..3 {
        if gd[a] == 0.0 {
            continue;
        }
        for p in 0..=dims[a] {
            let t = (p as f64 - g0[a]) / gd[a];
            if t > lo && t < hi {
                ts.push(t);
            }
        }
    }
    ts.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let mut sum = 0.0;
    for w in ts.windows(2) {
        let mid = 0.5 * (w[0] + w[1]);
        let mut idx = [0usize; 3];
        let mut inside = true;
        for a in 0..3 {
            let c = (g0[a] + mid * gd[a]).floor();
            if c < 0.0 || c >= dims[a] as f64 {
                inside = false;
            }
            idx[a] = c.max(0.0) as usize;
        }
        if inside {
            sum += f64::from(vol.get(idx[0], idx[1], idx[2])) * (w[1] - w[0]);
        }
    }
    sum
}

/// World point of grid coordinates `g` (grid = index + 0.5).
pub fn grid_to_world(vol: &Volume, g: DVec3) -> DVec3 {
    vol.index_to_world(g - 0.5)
}

pub fn rel_err(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}
