//! Ray marching through the trilinearly interpolated attenuation field.
//!
//! # The field
//! Voxel values sit at voxel **centres** (grid coordinates `i + 0.5`). Between centres the
//! field is trilinear; in the outer half-voxel next to each face it is **clamped** (the
//! edge value is held constant up to the face), and it is zero outside the grid box
//! `[0, n]³`. The support is the same box the exact Siddon tracer uses, so a uniform
//! volume gives identical line integrals with both.
//!
//! # The quadrature
//! The clipped ray `[t_enter, t_exit]` is divided into `N = ⌈L / h⌉` equal sub-intervals,
//! where `h` is the requested step converted to mm along this ray (`step_voxels / |gd|`,
//! i.e. `step_voxels` grid units between samples). One sample sits at the midpoint of
//! each sub-interval (midpoint rule), so the whole clipped length is always integrated
//! and the step actually used is ≤ the one asked for. The midpoint rule's error falls as
//! h²; `cargo run --release -- bench` reports the observed order.

use crate::ray::GridRay;

/// The interpolation cell around grid point `g` (clamped edges): the lower and upper
/// voxel index and the fraction towards the upper one, per axis.
#[inline(always)]
fn cell(dims: [usize; 3], g: [f64; 3]) -> ([usize; 3], [usize; 3], [f64; 3]) {
    let mut base = [0usize; 3];
    let mut next = [0usize; 3];
    let mut frac = [0.0f64; 3];
    for a in 0..3 {
        let last = (dims[a] - 1) as f64;
        let q = (g[a] - 0.5).clamp(0.0, last);
        let i0 = (q.floor() as usize).min(dims[a].saturating_sub(2));
        base[a] = i0;
        next[a] = (i0 + 1).min(dims[a] - 1);
        frac[a] = q - i0 as f64;
    }
    (base, next, frac)
}

/// The trilinearly interpolated field of `values` (grid of `dims`) at grid point `g`,
/// with clamped edges. `g` must lie in the grid box.
#[inline(always)]
pub fn sample(values: &[f32], dims: [usize; 3], g: [f64; 3]) -> f64 {
    let (base, next, frac) = cell(dims, g);
    let (nx, nxy) = (dims[0], dims[0] * dims[1]);
    let at = |i: usize, j: usize, k: usize| f64::from(values[i + nx * j + nxy * k]);
    let [x0, y0, z0] = base;
    let [x1, y1, z1] = next;
    let [fx, fy, fz] = frac;
    let c00 = at(x0, y0, z0) + fx * (at(x1, y0, z0) - at(x0, y0, z0));
    let c10 = at(x0, y1, z0) + fx * (at(x1, y1, z0) - at(x0, y1, z0));
    let c01 = at(x0, y0, z1) + fx * (at(x1, y0, z1) - at(x0, y0, z1));
    let c11 = at(x0, y1, z1) + fx * (at(x1, y1, z1) - at(x0, y1, z1));
    let c0 = c00 + fy * (c10 - c00);
    let c1 = c01 + fy * (c11 - c01);
    c0 + fz * (c1 - c0)
}

/// Adds `scale` × the trilinearly interpolated partial density of each material at grid
/// point `g` to `sums` (a packed composition, [`crate::composition`]): each material's
/// density field (ρ where the voxel is that material, 0 elsewhere) is interpolated on its
/// own, with the same clamped, cell-centred convention as [`sample`].
#[inline(always)]
pub fn sample_materials(
    packed: &[f32],
    dims: [usize; 3],
    g: [f64; 3],
    scale: f64,
    sums: &mut [f64],
) {
    let (base, next, frac) = cell(dims, g);
    let (nx, nxy) = (dims[0], dims[0] * dims[1]);
    for corner in 0..8 {
        let pick = |a: usize| corner >> a & 1 == 1;
        let mut w = scale;
        let mut ijk = [0usize; 3];
        for a in 0..3 {
            (ijk[a], w) = if pick(a) {
                (next[a], w * frac[a])
            } else {
                (base[a], w * (1.0 - frac[a]))
            };
        }
        let (rho, m) = crate::composition::unpack(packed[ijk[0] + nx * ijk[1] + nxy * ijk[2]]);
        sums[m] += w * f64::from(rho);
    }
}

/// Midpoint-rule integral of the trilinear field along `ray`, with samples
/// `step_voxels` grid units apart (at most). Result in the field's units × mm.
pub fn march(values: &[f32], dims: [usize; 3], ray: &GridRay, step_voxels: f64) -> f64 {
    let (steps, h) = quadrature(ray, step_voxels);
    let mut sum = 0.0;
    for s in 0..steps {
        let t = ray.t_enter + (s as f64 + 0.5) * h;
        sum += sample(values, dims, ray.at(t));
    }
    sum * h
}

/// Per-material midpoint-rule integrals of the trilinearly interpolated partial densities
/// of a packed composition along `ray` (same samples as [`march`]): Σρ_m·ℓ added to `sums`
/// (g/cm³ · mm).
pub fn march_materials(
    packed: &[f32],
    dims: [usize; 3],
    ray: &GridRay,
    step_voxels: f64,
    sums: &mut [f64],
) {
    let (steps, h) = quadrature(ray, step_voxels);
    for s in 0..steps {
        let t = ray.t_enter + (s as f64 + 0.5) * h;
        sample_materials(packed, dims, ray.at(t), h, sums);
    }
}

/// The midpoint rule [`march`] uses on `ray`: `(N, h)`, sample `s` at
/// `t_enter + (s + ½)·h` for `s = 0..N`, `h` in mm.
#[inline]
pub fn quadrature(ray: &GridRay, step_voxels: f64) -> (usize, f64) {
    let length = ray.length();
    let grid_per_mm =
        (ray.gd[0] * ray.gd[0] + ray.gd[1] * ray.gd[1] + ray.gd[2] * ray.gd[2]).sqrt();
    let steps = ((length * grid_per_mm / step_voxels).ceil() as usize).max(1);
    (steps, length / steps as f64)
}
