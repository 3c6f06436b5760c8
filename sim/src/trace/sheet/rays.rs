//! A sheet's rays as the kernels read them: arrays of their positions and ranges, and
//! per group of rays the ranges that let the kernels skip blocks of segments.

use super::{Segment, SheetRay};

/// The sheet's rays as arrays, padded to a multiple of [`Rays::PAD`] with rays that add
/// nothing (an empty range below the grid, so that every value stays finite).
#[derive(Debug, Clone)]
pub(super) struct Rays {
    pub(super) a0: Vec<f64>,
    pub(super) slope: Vec<f64>,
    pub(super) inv_slope: Vec<f64>,
    pub(super) b_lo: Vec<f64>,
    pub(super) b_hi: Vec<f64>,
    /// Per group of [`Rays::GROUP`] rays: the range along b where all of them are inside.
    pub(super) group_lo: Vec<f64>,
    pub(super) group_hi: Vec<f64>,
    /// Per group of [`Rays::GROUP`] rays: the range along b where any of them is inside.
    pub(super) reach_lo: Vec<f64>,
    pub(super) reach_hi: Vec<f64>,
    /// Per group of [`Rays::GROUP`] rays: the least and greatest `a0` and slope of its
    /// rays (padding left out; an all-padding group has an empty range).
    pub(super) a0_lo: Vec<f64>,
    pub(super) a0_hi: Vec<f64>,
    pub(super) slope_lo: Vec<f64>,
    pub(super) slope_hi: Vec<f64>,
}

impl Rays {
    /// Rays are padded to a multiple of this (the widest kernel's lanes).
    pub(super) const PAD: usize = 8;
    /// Rays per group of the per-group ranges (the narrowest kernel's lanes; wider
    /// kernels combine groups).
    pub(super) const GROUP: usize = 4;

    pub(super) fn new(rays: &[SheetRay]) -> Self {
        let n = rays.len().div_ceil(Self::PAD) * Self::PAD;
        let column = |f: fn(&SheetRay) -> f64, pad: f64| -> Vec<f64> {
            let mut v: Vec<f64> = rays.iter().map(f).collect();
            v.resize(n, pad);
            v
        };
        let (b_lo, b_hi) = (column(|r| r.b_lo, -1.0), column(|r| r.b_hi, -1.0));
        let group = |v: &[f64], f: fn(f64, f64) -> f64| -> Vec<f64> {
            v.chunks(Self::GROUP)
                .map(|c| c.iter().copied().reduce(f).unwrap())
                .collect()
        };
        // Padding rays widen no group's range of positions.
        let (a0_lo, a0_hi) = (
            column(|r| r.a0, f64::INFINITY),
            column(|r| r.a0, f64::NEG_INFINITY),
        );
        let (slope_lo, slope_hi) = (
            column(|r| r.slope, f64::INFINITY),
            column(|r| r.slope, f64::NEG_INFINITY),
        );
        Self {
            a0: column(|r| r.a0, 0.0),
            slope: column(|r| r.slope, 0.0),
            inv_slope: column(|r| r.inv_slope, 0.0),
            group_lo: group(&b_lo, f64::max),
            group_hi: group(&b_hi, f64::min),
            reach_lo: group(&b_lo, f64::min),
            reach_hi: group(&b_hi, f64::max),
            a0_lo: group(&a0_lo, f64::min),
            a0_hi: group(&a0_hi, f64::max),
            slope_lo: group(&slope_lo, f64::min),
            slope_hi: group(&slope_hi, f64::max),
            b_lo,
            b_hi,
        }
    }

    pub(super) fn len(&self) -> usize {
        self.a0.len()
    }

    /// Whether every ray of groups `quads` stays below `lo` or from `hi` on along `a`
    /// for all `b` in `[b0, b1]` (`b0 ≥ 0`, as every grid coordinate in the box). The
    /// kernels compute a position as one fused multiply-add of these values; the
    /// margin covers its rounding.
    pub(super) fn outside(
        &self,
        quads: std::ops::Range<usize>,
        b0: f64,
        b1: f64,
        lo: f64,
        hi: f64,
    ) -> bool {
        const MARGIN: f64 = 1e-6;
        let fold = |v: &[f64], f: fn(f64, f64) -> f64| {
            v[quads.clone()]
                .iter()
                .copied()
                .reduce(f)
                .unwrap_or(f64::NAN)
        };
        let (s_lo, s_hi) = (
            fold(&self.slope_lo, f64::min),
            fold(&self.slope_hi, f64::max),
        );
        // a0 + slope·b is linear in b, and b ≥ 0: the extremes are at the ends.
        let x_lo = fold(&self.a0_lo, f64::min) + (s_lo * b0).min(s_lo * b1);
        let x_hi = fold(&self.a0_hi, f64::max) + (s_hi * b0).max(s_hi * b1);
        x_hi + MARGIN < lo || x_lo - MARGIN >= hi
    }
}

/// The range along `a` outside which every voxel of `block`'s lines is zero (see
/// [`Segment::nz_lo`]).
pub(super) fn nonzero_range(block: &[Segment]) -> (f64, f64) {
    block
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s.nz_lo), hi.max(s.nz_hi))
        })
}
