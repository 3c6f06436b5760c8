//! Exact ray tracing through a voxel grid: Siddon's method in the incremental form of
//! Jacobs et al. (1998), organised in runs along the dominant axis.
//!
//! R. L. Siddon, "Fast calculation of the exact radiological path for a three-dimensional
//! CT array", Med. Phys. 12 (1985) 252. F. Jacobs, E. Sundermann, B. De Sutter,
//! M. Christiaens, I. Lemahieu, "A fast algorithm to calculate the exact radiological path
//! through a pixel or voxel space", J. Comput. Inf. Technol. 6 (1998) 89.
//!
//! The ray crosses the grid planes of each axis at `t = (plane − g0)·inv`. Jacobs' method
//! walks those crossings in increasing `t`, one voxel per crossing. Along the *dominant*
//! axis (largest |gd|, so at most one crossing of each other axis per slab) most voxels
//! are whole slabs of identical length `1/|gd|`; when several such slabs follow each other
//! before the next crossing of another axis, they are reported as one run
//! ([`PathAccumulator::run`]) and summed without per-voxel branching. The voxels and
//! lengths are those of the plain incremental walk; only the order of floating-point
//! additions differs.
//!
//! # Robustness
//! * Every crossing `t` comes from [`plane_t`], the same expression that defines the box
//!   exit, so no crossing is taken at or after the exit: the walk cannot leave the grid.
//! * The start voxel is `floor` of the entry point, clamped into the grid. If rounding
//!   puts the entry a hair on the wrong side of a plane, the walk first reports a
//!   zero-length segment and then crosses that plane: errors stay at rounding level.
//! * Axes with `gd = 0` never cross a plane; a ray lying exactly in a grid plane belongs
//!   to the voxel on the plane's upper side (half-open voxels `[i, i+1)`).

use crate::ray::{GridRay, plane_t};
use crate::trace::PathAccumulator;

/// Walks `ray` through a grid of `dims` voxels stored with the native layout
/// (`i + nx·(j + ny·k)`), reporting every crossed voxel with its path length (mm) to `acc`.
pub fn trace<A: PathAccumulator>(dims: [usize; 3], ray: &GridRay, acc: &mut A) {
    let n = dims.map(|d| d as i64);
    let strides = [1, n[0], n[0] * n[1]];
    let (g0, gd, inv) = (ray.g0, ray.gd, ray.inv);
    let t_end = ray.t_exit;

    // Start voxel and the next plane crossing of each axis.
    let mut ijk = [0i64; 3];
    let mut step = [0i64; 3];
    let mut next = [f64::INFINITY; 3];
    for a in 0..3 {
        let p = g0[a] + ray.t_enter * gd[a];
        ijk[a] = (p.floor() as i64).clamp(0, n[a] - 1);
        if gd[a] != 0.0 {
            step[a] = if gd[a] > 0.0 { 1 } else { -1 };
            ijk[a] = agree_with_crossings(ijk[a], step[a], ray.t_enter, g0[a], inv[a], 1)
                .clamp(0, n[a] - 1);
            next[a] = plane_t(next_plane(ijk[a], step[a]), g0[a], inv[a]);
        }
    }
    let mut st = Walk {
        ijk,
        next,
        voxel: ijk[0] * strides[0] + ijk[1] * strides[1] + ijk[2] * strides[2],
        t: ray.t_enter,
    };
    let fixed = Fixed {
        g0,
        inv,
        step,
        strides,
        t_end,
    };

    // Dominant axis m (largest |gd|: at most one crossing of each other axis per slab).
    let m = ray.dominant_axis();
    let (o1, o2) = ((m + 1) % 3, (m + 2) % 3);

    // 1. Plain incremental steps up to the first m-plane (the partial first slab).
    loop {
        match st.plain_step(&fixed, acc) {
            None => return,
            Some(a) if a == m => break,
            Some(_) => {}
        }
    }

    // 2. Whole slabs along m. Invariant: t is the m-plane where the slab starts, `voxel`
    //    the voxel there, next_m the plane where it ends; next_1, next_2 ≥ t (up to
    //    rounding). Plane indices are carried as (exact, integer-valued) f64 so that no
    //    crossing needs an integer-to-float conversion; crossing times are bit-identical
    //    to `plane_t` of the integer plane.
    let slab = inv[m].abs();
    let grid_per_mm = gd[m].abs();
    let (dm, d1, d2) = (
        step[m] * strides[m],
        step[o1] * strides[o1],
        step[o2] * strides[o2],
    );
    let (fm, f1, f2) = (step[m] as f64, step[o1] as f64, step[o2] as f64);
    let (g0m, g01, g02) = (g0[m], g0[o1], g0[o2]);
    let (im, i1, i2) = (inv[m], inv[o1], inv[o2]);
    let mut plane_m = next_plane(st.ijk[m], step[m]);
    let mut plane_1 = next_plane(st.ijk[o1], step[o1]);
    let mut plane_2 = next_plane(st.ijk[o2], step[o2]);
    let (mut next_m, mut next_1, mut next_2) = (st.next[m], st.next[o1], st.next[o2]);
    // Planes of m strictly inside the grid still ahead.
    let mut inside = if step[m] > 0 {
        n[m] - 1 - st.ijk[m]
    } else {
        st.ijk[m]
    };
    while next_m < t_end {
        // Whole slabs before the next crossing of another axis (or the exit): counted from
        // the distance; rounding may count one slab too many or too few, which only moves
        // a rounding-sized sliver between neighbours (the slab code below absorbs a
        // crossing that lies a hair before the slab start). `inside` keeps the walk in
        // the grid whatever the rounding.
        let gap = next_1.min(next_2).min(t_end);
        let k = (((gap - st.t) * grid_per_mm) as i64).min(inside);
        if k >= 2 {
            let lowest = if step[m] > 0 {
                st.voxel
            } else {
                st.voxel - (k - 1) * strides[m]
            };
            acc.run(lowest as usize, strides[m] as usize, k as usize, slab);
            st.voxel += k * dm;
            inside -= k;
            plane_m += (k - 1) as f64 * fm;
            st.t = plane_t(plane_m, g0m, im);
            plane_m += fm;
            next_m = plane_t(plane_m, g0m, im);
            if next_m >= t_end {
                break;
            }
        }
        // One slab, crossing at most one o1-plane and one o2-plane, without branches:
        // three segments (zero-length where a crossing does not happen).
        let t_slab_end = next_m;
        let (c1, c2) = (next_1, next_2);
        let (x1, x2) = (c1 < t_slab_end, c2 < t_slab_end);
        let ca = c1.min(c2).max(st.t).min(t_slab_end);
        let cb = c1.max(c2).max(st.t).min(t_slab_end);
        let after_1 = st.voxel + if x1 { d1 } else { 0 };
        let after_2 = st.voxel + if x2 { d2 } else { 0 };
        let va = if c1 <= c2 { after_1 } else { after_2 };
        let vb = after_1 + after_2 - st.voxel;
        acc.segments3(
            [st.voxel as usize, va as usize, vb as usize],
            [ca - st.t, cb - ca, t_slab_end - cb],
        );
        plane_1 += if x1 { f1 } else { 0.0 };
        plane_2 += if x2 { f2 } else { 0.0 };
        next_1 = if x1 { plane_t(plane_1, g01, i1) } else { c1 };
        next_2 = if x2 { plane_t(plane_2, g02, i2) } else { c2 };
        st.t = t_slab_end;
        st.voxel = vb + dm;
        inside -= 1;
        plane_m += fm;
        next_m = plane_t(plane_m, g0m, im);
    }
    // Back to integer indices for the last partial slab.
    st.ijk[m] = plane_m as i64 - if step[m] > 0 { 1 } else { 0 };
    st.ijk[o1] = index_before(plane_1, step[o1], st.ijk[o1]);
    st.ijk[o2] = index_before(plane_2, step[o2], st.ijk[o2]);
    (st.next[m], st.next[o1], st.next[o2]) = (next_m, next_1, next_2);

    // 3. The partial last slab: plain incremental steps to the exit.
    while st.plain_step(&fixed, acc).is_some() {}
}

/// Per-ray constants of the walk.
struct Fixed {
    g0: [f64; 3],
    inv: [f64; 3],
    step: [i64; 3],
    strides: [i64; 3],
    t_end: f64,
}

/// Where the walk stands: voxel indices, next plane crossing per axis, linear voxel index
/// and the parameter reached.
struct Walk {
    ijk: [i64; 3],
    next: [f64; 3],
    voxel: i64,
    t: f64,
}

impl Walk {
    /// One plain incremental step: reports the segment up to the next plane crossing (or
    /// to the exit) and crosses that plane. Returns the axis crossed, `None` at the exit.
    #[inline(always)]
    fn plain_step<A: PathAccumulator>(&mut self, f: &Fixed, acc: &mut A) -> Option<usize> {
        let a = first_crossing(&self.next);
        if self.next[a] >= f.t_end {
            acc.segment(self.voxel as usize, (f.t_end - self.t).max(0.0));
            return None;
        }
        acc.segment(self.voxel as usize, (self.next[a] - self.t).max(0.0));
        self.t = self.next[a];
        self.ijk[a] += f.step[a];
        self.voxel += f.step[a] * f.strides[a];
        self.next[a] = plane_t(next_plane(self.ijk[a], f.step[a]), f.g0[a], f.inv[a]);
        Some(a)
    }
}

/// The voxel index whose next plane (moving by `step`) is `plane`; `current` when the
/// axis does not move.
#[inline(always)]
fn index_before(plane: f64, step: i64, current: i64) -> i64 {
    match step {
        1 => plane as i64 - 1,
        -1 => plane as i64,
        _ => current,
    }
}

/// Corrects a start index `i` (from `floor` of the start point, cells of `cell` grid
/// units) so that it agrees with the crossing times: the cell whose entry plane is crossed
/// at or before `t` and whose exit plane after it. `floor` and [`plane_t`] round
/// independently; for a ray nearly parallel to an axis (|gd| ~ 1e-17) they can disagree
/// by a cell over a long stretch of `t`, which matters when a walk starts inside the grid
/// (e.g. at an empty-space interval, [`crate::accel`]).
#[inline(always)]
pub fn agree_with_crossings(i: i64, step: i64, t: f64, g0: f64, inv: f64, cell: i64) -> i64 {
    let (entry, exit) = if step > 0 { (i, i + 1) } else { (i + 1, i) };
    if plane_t((entry * cell) as f64, g0, inv) > t {
        i - step
    } else if plane_t((exit * cell) as f64, g0, inv) <= t {
        i + step
    } else {
        i
    }
}

/// The axis whose next plane crossing comes first.
#[inline(always)]
fn first_crossing(next: &[f64; 3]) -> usize {
    let a01 = if next[1] < next[0] { 1 } else { 0 };
    if next[2] < next[a01] { 2 } else { a01 }
}

/// The plane a ray in voxel `i` crosses next when moving in direction `step` (±1).
#[inline(always)]
fn next_plane_index(i: i64, step: i64) -> i64 {
    if step > 0 { i + 1 } else { i }
}

#[inline(always)]
fn next_plane(i: i64, step: i64) -> f64 {
    next_plane_index(i, step) as f64
}
