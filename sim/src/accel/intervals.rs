//! Where a ray runs through occupied bricks: the sorted, merged list of parameter
//! intervals `[t0, t1]` (mm) of a clipped [`GridRay`] that lie inside occupied bricks of a
//! [`BrickMap`].
//!
//! Two ways to find them, with identical results:
//! * [`BrickBvh`] — a BVH (the `obvhs` crate, f32 boxes) over the occupied bricks' boxes
//!   finds the candidate bricks; each candidate's exact interval is then recomputed in f64
//!   with [`GridRay::clip_box`] and the intervals are sorted and merged.
//! * [`dda_intervals`] — a 3-D DDA (Amanatides & Woo) over the brick grid, visiting every
//!   brick the ray crosses in order.
//!
//! Either way every interval end is a grid-plane crossing computed with
//! [`crate::ray::plane_t`], the expression Siddon uses for the same plane, so a tracer
//! restarted at an interval start sees the same crossing times as the uninterrupted walk.

use super::bricks::BrickMap;
use crate::grid_box::GridBox;
use crate::ray::{GridRay, plane_t};
use crate::trace::siddon::agree_with_crossings;
use glam::Vec3A;
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::builder::build_bvh2;
use std::time::Duration;

/// A parameter interval `[t0, t1]` along a ray, mm, `t0 < t1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval {
    /// Start, mm.
    pub t0: f64,
    /// End, mm.
    pub t1: f64,
}

/// How much the f32 boxes given to the BVH are grown (grid units) so that f32 rounding in
/// its ray–box test never misses a brick the exact f64 test would hit. Rounding there is
/// below ~1e-4 grid units for grids up to a few thousand voxels and paths of a few metres.
const BVH_MARGIN: f32 = 1.0 / 64.0;

/// A BVH over the occupied bricks of a [`BrickMap`], in grid coordinates.
#[derive(Clone)]
pub struct BrickBvh {
    bvh: Bvh2,
    boxes: Vec<GridBox>,
}

impl std::fmt::Debug for BrickBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BrickBvh")
            .field("bricks", &self.boxes.len())
            .field("nodes", &self.bvh.nodes.len())
            .finish()
    }
}

impl BrickBvh {
    /// Builds the BVH over `map`'s occupied bricks.
    pub fn build(map: &BrickMap) -> Self {
        let boxes = map.occupied_boxes();
        let aabbs: Vec<Aabb> = boxes
            .iter()
            .map(|b| {
                let lo = Vec3A::new(b.lo[0] as f32, b.lo[1] as f32, b.lo[2] as f32);
                let hi = Vec3A::new(b.hi[0] as f32, b.hi[1] as f32, b.hi[2] as f32);
                Aabb::new(lo - BVH_MARGIN, hi + BVH_MARGIN)
            })
            .collect();
        let bvh = if aabbs.is_empty() {
            Bvh2::default()
        } else {
            build_bvh2(
                &aabbs,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            )
        };
        Self { bvh, boxes }
    }

    /// Number of occupied bricks in the BVH.
    pub fn len(&self) -> usize {
        self.boxes.len()
    }

    /// Whether no brick is occupied.
    pub fn is_empty(&self) -> bool {
        self.boxes.is_empty()
    }

    /// Heap bytes held (nodes, index map, brick boxes).
    pub fn memory_bytes(&self) -> usize {
        self.bvh.nodes.capacity() * std::mem::size_of::<obvhs::bvh2::node::Bvh2Node>()
            + self.bvh.primitive_indices.capacity() * 4
            + self.boxes.capacity() * std::mem::size_of::<GridBox>()
    }

    /// Fills `out` with the sorted, merged intervals of `ray` inside occupied bricks.
    pub fn intervals(&self, ray: &GridRay, out: &mut Vec<Interval>) {
        out.clear();
        if self.boxes.is_empty() {
            return;
        }
        // The f32 ray starts at the entry point, keeping coordinates small.
        let p = ray.at(ray.t_enter);
        let origin = Vec3A::new(p[0] as f32, p[1] as f32, p[2] as f32);
        let dir = Vec3A::new(ray.gd[0] as f32, ray.gd[1] as f32, ray.gd[2] as f32);
        let len = (ray.length() * (1.0 + 1e-6)) as f32 + 1e-3;
        let r = obvhs::ray::Ray::new(origin, dir, 0.0, len);
        self.bvh.ray_traverse_anyhit(r, |_, id| {
            let b = &self.boxes[self.bvh.primitive_indices[id] as usize];
            if let Some(c) = GridRay::clip_box(b, ray.g0, ray.gd, ray.t_enter, ray.t_exit) {
                out.push(Interval {
                    t0: c.t_enter,
                    t1: c.t_exit,
                });
            }
        });
        merge(out);
    }
}

/// Sorts `v` by start and merges overlapping or touching intervals.
fn merge(v: &mut Vec<Interval>) {
    if v.len() < 2 {
        return;
    }
    v.sort_unstable_by(|a, b| a.t0.total_cmp(&b.t0));
    let mut w = 0;
    for r in 1..v.len() {
        if v[r].t0 <= v[w].t1 {
            v[w].t1 = v[w].t1.max(v[r].t1);
        } else {
            w += 1;
            v[w] = v[r];
        }
    }
    v.truncate(w + 1);
}

/// Fills `out` with the sorted, merged intervals of `ray` inside occupied bricks of `map`,
/// walking the brick grid with a 3-D DDA ([`walk_bricks`]).
pub fn dda_intervals(map: &BrickMap, ray: &GridRay, out: &mut Vec<Interval>) {
    out.clear();
    let mut open: Option<f64> = None;
    let mut t_stop = ray.t_enter;
    walk_bricks(map.size(), map.brick_dims(), ray, |b, t0, t1| {
        if map.is_occupied(b) {
            open.get_or_insert(t0);
        } else if let Some(start) = open.take() {
            push(out, start, t0);
        }
        t_stop = t1;
        true
    });
    if let Some(t0) = open {
        push(out, t0, t_stop);
    }
}

/// Visits, in order along `ray`, every brick of `size³` voxels (a grid of `brick_dims`
/// bricks) that the ray crosses, as `visit(brick, t0, t1)` with the parameter interval
/// (mm) inside it; stops early when `visit` returns `false`. A 3-D DDA (Amanatides &
/// Woo) whose crossings are [`plane_t`] of the brick planes, as Siddon computes them.
pub fn walk_bricks(
    size: usize,
    brick_dims: [usize; 3],
    ray: &GridRay,
    mut visit: impl FnMut([usize; 3], f64, f64) -> bool,
) {
    let s = size as i64;
    let nb = brick_dims.map(|n| n as i64);
    let (g0, gd, inv) = (ray.g0, ray.gd, ray.inv);
    let mut b = [0i64; 3];
    let mut step = [0i64; 3];
    let mut next = [f64::INFINITY; 3];
    for a in 0..3 {
        let p = g0[a] + ray.t_enter * gd[a];
        b[a] = ((p.floor() as i64).div_euclid(s)).clamp(0, nb[a] - 1);
        if gd[a] != 0.0 {
            step[a] = if gd[a] > 0.0 { 1 } else { -1 };
            // The brick whose planes bracket t_enter, as Siddon decides its start voxel.
            b[a] = agree_with_crossings(b[a], step[a], ray.t_enter, g0[a], inv[a], s)
                .clamp(0, nb[a] - 1);
            next[a] = plane_t(brick_plane(b[a], step[a], s), g0[a], inv[a]);
        }
    }
    let mut t = ray.t_enter;
    loop {
        let a = if next[1] < next[0] { 1 } else { 0 };
        let a = if next[2] < next[a] { 2 } else { a };
        let end = next[a] >= ray.t_exit;
        let t_next = if end { ray.t_exit } else { next[a] };
        if !visit(b.map(|x| x as usize), t, t_next) || end {
            return;
        }
        t = t_next;
        b[a] += step[a];
        if b[a] < 0 || b[a] >= nb[a] {
            // Only rounding at the exit can get here: the walk has left the grid.
            return;
        }
        next[a] = plane_t(brick_plane(b[a], step[a], s), g0[a], inv[a]);
    }
}

/// Appends `[t0, t1]` if it has positive length.
#[inline]
fn push(out: &mut Vec<Interval>, t0: f64, t1: f64) {
    if t1 > t0 {
        out.push(Interval { t0, t1 });
    }
}

/// The grid plane a ray in brick `b` crosses next moving by `step` (±1), bricks of `s`.
#[inline(always)]
fn brick_plane(b: i64, step: i64, s: i64) -> f64 {
    (if step > 0 { (b + 1) * s } else { b * s }) as f64
}
