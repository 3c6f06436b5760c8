//! Empty-space skipping: tracers visit only the parts of a ray that run through bricks
//! where the integrated field may be non-zero.
//!
//! * [`bricks`] — the brick occupancy map (brick size, occupancy predicate, dilation).
//! * [`intervals`] — per ray, the sorted and merged parameter intervals inside occupied
//!   bricks, found with a BVH over the bricks ([`intervals::BrickBvh`], `obvhs`) or a
//!   3-D DDA over the brick grid ([`intervals::dda_intervals`]).
//! * [`EmptySpace`] — the two together, and the Siddon and trilinear integrals restricted
//!   to those intervals.
//!
//! # Exactness
//! * **Siddon** — every voxel outside the intervals holds 0 and would add `0 · length`.
//!   Each interval end is a grid-plane crossing computed exactly as Siddon computes it, so
//!   the voxels and their lengths are those of the full walk; what changes is how the sum
//!   is grouped (whole-slab runs are summed first, then multiplied by the slab length, and
//!   runs now break at interval ends). The result therefore agrees with the full trace to
//!   rounding (≤ ~1e-12 relative), not always to the last bit.
//! * **Trilinear** — the samples are the full march's (same count `N`, same step `h`,
//!   same positions, summed in the same order); a sample is skipped only when it lies in an
//!   unoccupied brick of the one-voxel-dilated map, where the field is exactly 0, and
//!   `x + 0 = x`. The result is bit-identical.

pub mod bricks;
pub mod intervals;

use crate::error::Result;
use crate::ray::GridRay;
use crate::trace::{PathAccumulator, siddon, trilinear};
use crate::volume::Volume;
use bricks::BrickMap;
use intervals::{BrickBvh, Interval, dda_intervals};
use serde::{Deserialize, Serialize};

/// How the intervals are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Finder {
    /// 3-D DDA over the brick grid.
    Dda,
    /// BVH over the occupied bricks (`obvhs`).
    Bvh,
}

/// Empty-space skipping settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SkipOptions {
    /// Brick edge, voxels (≥ 1).
    pub brick: usize,
    /// How intervals are found.
    pub finder: Finder,
    /// Values with `|v| ≤ threshold` count as empty (mm⁻¹, ≥ 0). 0 (the default) is exact.
    /// Above 0 the result is no longer exact: a ray loses at most `threshold ×` the length
    /// it spends in skipped bricks (e.g. 1e-5 mm⁻¹ × 500 mm = 5e-3 in the line integral).
    /// For CTs whose air is noise rather than exact zeros.
    pub threshold: f32,
}

impl Default for SkipOptions {
    /// 8³-voxel bricks walked with the DDA: the fastest combination measured by
    /// `tomograf bench` (docs/benchmarks.md, "Empty-space skipping").
    fn default() -> Self {
        Self {
            brick: 8,
            finder: Finder::Dda,
            threshold: 0.0,
        }
    }
}

/// A brick map with its interval finder.
#[derive(Debug, Clone)]
pub struct EmptySpace {
    map: BrickMap,
    bvh: Option<BrickBvh>,
}

impl EmptySpace {
    /// Skipping for exact Siddon over `mu`: bricks holding a value with
    /// `|v| > threshold` (any non-zero value for the default threshold 0).
    pub fn for_siddon(mu: &Volume, options: SkipOptions) -> Result<Self> {
        let t = check_threshold(options.threshold)?;
        let map = BrickMap::build(mu, options.brick, 0, |v| v.abs() > t)?;
        Ok(Self::from_map(map, options.finder))
    }

    /// Skipping for the trilinear field of `mu`: voxels with `|v| > threshold`, dilated
    /// by one voxel.
    pub fn for_trilinear(mu: &Volume, options: SkipOptions) -> Result<Self> {
        let t = check_threshold(options.threshold)?;
        let map = BrickMap::build(mu, options.brick, 1, |v| v.abs() > t)?;
        Ok(Self::from_map(map, options.finder))
    }

    /// Skipping over a given map (e.g. one built with a per-material predicate).
    pub fn from_map(map: BrickMap, finder: Finder) -> Self {
        let bvh = (finder == Finder::Bvh).then(|| BrickBvh::build(&map));
        Self { map, bvh }
    }

    /// The brick map.
    pub fn map(&self) -> &BrickMap {
        &self.map
    }

    /// Heap bytes of the map and (if used) the BVH.
    pub fn memory_bytes(&self) -> usize {
        self.map.memory_bytes() + self.bvh.as_ref().map_or(0, BrickBvh::memory_bytes)
    }

    /// Fills `out` with the sorted, merged intervals of `ray` inside occupied bricks.
    pub fn intervals(&self, ray: &GridRay, out: &mut Vec<Interval>) {
        match &self.bvh {
            Some(b) => b.intervals(ray, out),
            None => dda_intervals(&self.map, ray, out),
        }
    }

    /// `ray` narrowed to run from its first to its last occupied interval (`None`: it
    /// crosses no occupied brick). Tracers that need one contiguous range use this.
    pub fn trim(&self, ray: &GridRay) -> Option<GridRay> {
        let mut v = Vec::new();
        self.intervals(ray, &mut v);
        let (first, last) = (v.first()?, v.last()?);
        Some(GridRay {
            t_enter: first.t0,
            t_exit: last.t1,
            ..*ray
        })
    }

    /// Siddon over the occupied intervals of `ray` only (grid of `dims`).
    pub fn siddon<A: PathAccumulator>(&self, dims: [usize; 3], ray: &GridRay, acc: &mut A) {
        let mut v = Vec::new();
        self.intervals(ray, &mut v);
        siddon_over(dims, ray, &v, acc);
    }

    /// The trilinear midpoint march of `ray`, evaluating only samples in occupied
    /// intervals (bit-identical to [`trilinear::march`] for a map built with
    /// [`EmptySpace::for_trilinear`]).
    pub fn trilinear(&self, values: &[f32], dims: [usize; 3], ray: &GridRay, step: f64) -> f64 {
        let mut v = Vec::new();
        self.intervals(ray, &mut v);
        trilinear_over(values, dims, ray, step, &v)
    }
}

fn check_threshold(t: f32) -> Result<f32> {
    if t.is_finite() && t >= 0.0 {
        Ok(t)
    } else {
        Err(crate::error::SimError::OutOfRange(format!(
            "empty-space threshold is {t} mm⁻¹; it must be finite and ≥ 0"
        )))
    }
}

/// Siddon over the given sorted, disjoint sub-intervals of `ray`.
pub fn siddon_over<A: PathAccumulator>(
    dims: [usize; 3],
    ray: &GridRay,
    intervals: &[Interval],
    acc: &mut A,
) {
    for iv in intervals {
        let sub = GridRay {
            t_enter: iv.t0,
            t_exit: iv.t1,
            ..*ray
        };
        siddon::trace(dims, &sub, acc);
    }
}

/// [`trilinear::march`] of `ray` evaluating only the samples that lie in (or within one
/// sample of) the given sorted intervals; every other sample is taken as 0.
pub fn trilinear_over(
    values: &[f32],
    dims: [usize; 3],
    ray: &GridRay,
    step_voxels: f64,
    intervals: &[Interval],
) -> f64 {
    let (steps, h) = trilinear::quadrature(ray, step_voxels);
    let mut sum = 0.0;
    let mut done = 0usize;
    for iv in intervals {
        // Samples s with t_enter + (s + ½)h in [t0, t1], widened by one on each side
        // against rounding (an extra sample is computed exactly as the full march does).
        let lo = (((iv.t0 - ray.t_enter) / h - 0.5).floor() - 1.0).max(0.0) as usize;
        let hi = (((iv.t1 - ray.t_enter) / h - 0.5).ceil() + 2.0).max(0.0) as usize;
        for s in lo.max(done)..hi.min(steps) {
            let t = ray.t_enter + (s as f64 + 0.5) * h;
            sum += trilinear::sample(values, dims, ray.at(t));
        }
        done = done.max(hi.min(steps));
    }
    sum * h
}

/// [`trilinear::march`] of `ray` counting only the samples whose parameter lies in one of
/// the sorted, disjoint `intervals` (`t0 ≤ t < t1`); the others are taken as 0. Used to
/// leave out the voxels inside mesh objects (the midpoint rule then has an O(h) error at
/// each mesh boundary, as at any discontinuity).
pub fn trilinear_in(
    values: &[f32],
    dims: [usize; 3],
    ray: &GridRay,
    step_voxels: f64,
    intervals: &[Interval],
) -> f64 {
    let (steps, h) = trilinear::quadrature(ray, step_voxels);
    let mut sum = 0.0;
    let mut k = 0;
    for s in 0..steps {
        let t = ray.t_enter + (s as f64 + 0.5) * h;
        while k < intervals.len() && intervals[k].t1 <= t {
            k += 1;
        }
        if k < intervals.len() && intervals[k].t0 <= t {
            sum += trilinear::sample(values, dims, ray.at(t));
        }
    }
    sum * h
}

/// [`trilinear::march_materials`] of `ray` counting only the samples whose parameter lies
/// in one of the sorted, disjoint `intervals` (`t0 ≤ t < t1`), added to `sums`
/// (g/cm³ · mm): the per-material twin of [`trilinear_in`].
pub fn trilinear_materials_in(
    packed: &[f32],
    dims: [usize; 3],
    ray: &GridRay,
    step_voxels: f64,
    intervals: &[Interval],
    sums: &mut [f64],
) {
    let (steps, h) = trilinear::quadrature(ray, step_voxels);
    let mut k = 0;
    for s in 0..steps {
        let t = ray.t_enter + (s as f64 + 0.5) * h;
        while k < intervals.len() && intervals[k].t1 <= t {
            k += 1;
        }
        if k < intervals.len() && intervals[k].t0 <= t {
            trilinear::sample_materials(packed, dims, ray.at(t), h, sums);
        }
    }
}
