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
    /// Per group of [`Rays::GROUP`] rays: the ranges that let the kernels skip blocks.
    groups: Vec<Span>,
}

/// What a group of rays spans: the ranges a kernel tests per block of segments, without
/// looking at the rays one by one.
#[derive(Debug, Clone, Copy)]
pub(super) struct Span {
    /// The range along b where all of the rays are inside (`lo > hi`: nowhere).
    pub(super) inside_lo: f64,
    pub(super) inside_hi: f64,
    /// The range along b where any of them is inside.
    pub(super) reach_lo: f64,
    pub(super) reach_hi: f64,
    /// The least and greatest `a0` and slope of the rays (padding left out; an
    /// all-padding group has empty ranges).
    a0_lo: f64,
    a0_hi: f64,
    slope_lo: f64,
    slope_hi: f64,
    /// Whether every ray's `inv_slope` is finite (not so for a slope below ~1e-308).
    inv_finite: bool,
}

/// What the kernels test per block of segments: where along b it starts and ends, and
/// along `a` the range outside which its voxel lines are zero ([`nonzero_range`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Block {
    pub(super) b0: f64,
    pub(super) b1: f64,
    nz_lo: f64,
    nz_hi: f64,
}

impl Block {
    pub(super) fn of(block: &[Segment]) -> Self {
        let (nz_lo, nz_hi) = nonzero_range(block);
        Self {
            b0: block[0].b0,
            b1: block[block.len() - 1].b1,
            nz_lo,
            nz_hi,
        }
    }
}

/// How a SIMD kernel takes a group of rays over a block of segments ([`Span::pass`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Pass {
    /// Skipped: no ray's range meets the block (each piece would be an exact 0).
    Miss,
    /// Skipped: every voxel the rays can meet in the block is zero (each piece would be an
    /// exact ±0), after [`super::Sheet::skip_zeros`].
    Zeros,
    /// The block lies inside every ray's range, the positions along `a` move one way
    /// (`rising`: no slope negative; else no slope positive) and stay in the box: the
    /// kernels' shortest path ([`Span::pass`]).
    Monotone { rising: bool },
    /// The block lies inside every ray's range: a segment's entry is the previous one's
    /// exit.
    Inside,
    /// Some ray's range ends inside the block: each segment is clipped to each ray's.
    Clipped,
}

impl Span {
    /// The span of `a` and `b` together.
    fn merge(a: Self, b: Self) -> Self {
        Self {
            inside_lo: a.inside_lo.max(b.inside_lo),
            inside_hi: a.inside_hi.min(b.inside_hi),
            reach_lo: a.reach_lo.min(b.reach_lo),
            reach_hi: a.reach_hi.max(b.reach_hi),
            a0_lo: a.a0_lo.min(b.a0_lo),
            a0_hi: a.a0_hi.max(b.a0_hi),
            slope_lo: a.slope_lo.min(b.slope_lo),
            slope_hi: a.slope_hi.max(b.slope_hi),
            inv_finite: a.inv_finite && b.inv_finite,
        }
    }

    /// Bounds on every ray's position along `a` for all `b` in `[b0, b1]` (`b0 ≥ 0`, as
    /// every grid coordinate in the box), as (least, greatest).
    #[inline]
    fn positions(&self, b0: f64, b1: f64) -> (f64, f64) {
        // a0 + slope·b is linear in b, and 0 ≤ b0 ≤ b1: the extremes are at the ends, the
        // lower end's where the slope is ≥ 0 (the same as the least of the two products,
        // without a NaN-aware `min`: this runs per group and block).
        let x_lo = self.a0_lo + self.slope_lo * if self.slope_lo >= 0.0 { b0 } else { b1 };
        let x_hi = self.a0_hi + self.slope_hi * if self.slope_hi >= 0.0 { b1 } else { b0 };
        (x_lo, x_hi)
    }

    /// How a kernel takes this group over `block`; `monotone`: the box's first and last
    /// voxel along `a` where the kernel has a [`Pass::Monotone`] path (line integrals over
    /// pairs of voxels), else `None`.
    #[inline]
    pub(super) fn pass(&self, block: &Block, monotone: Option<(f64, f64)>) -> Pass {
        let (b0, b1) = (block.b0, block.b1);
        if b1 <= self.reach_lo || b0 >= self.reach_hi {
            return Pass::Miss;
        }
        // Finite: a group whose rays are all padding misses every block (its reach is
        // empty), and a real ray's slope is below 1. A block with no zeros to count on has
        // the range ±∞, which no position lies outside.
        let (x_lo, x_hi) = self.positions(b0, b1);
        if x_hi + Self::MARGIN < block.nz_lo || x_lo - Self::MARGIN >= block.nz_hi {
            return Pass::Zeros;
        }
        if !(b0 >= self.inside_lo && b1 <= self.inside_hi) {
            return Pass::Clipped;
        }
        // Positions moving one way and within voxels `a_lo..a_hi` (the box's first and
        // last along `a`; the last left out, so that a voxel's right neighbour is in the
        // box too), with finite `inv_slope`s: there a kernel knows which end of a segment
        // holds the lower voxel of its pair and needs no clamping.
        match monotone {
            Some((a_lo, a_hi))
                if self.inv_finite && x_lo - Self::MARGIN >= a_lo && x_hi + Self::MARGIN < a_hi =>
            {
                if self.slope_lo >= 0.0 {
                    Pass::Monotone { rising: true }
                } else if self.slope_hi <= 0.0 {
                    Pass::Monotone { rising: false }
                } else {
                    Pass::Inside
                }
            }
            _ => Pass::Inside,
        }
    }

    /// The kernels compute a position as one fused multiply-add of a ray's values; this
    /// covers its rounding against [`Span::positions`]' bounds.
    const MARGIN: f64 = 1e-6;
}

impl Rays {
    /// Rays are padded to a multiple of this (the widest kernel's lanes).
    pub(super) const PAD: usize = 8;
    /// Rays per group of the per-group ranges (the narrowest kernel's lanes; wider
    /// kernels combine groups, [`Rays::spans`]).
    pub(super) const GROUP: usize = 4;

    pub(super) fn new(rays: &[SheetRay]) -> Self {
        let n = rays.len().div_ceil(Self::PAD) * Self::PAD;
        let column = |f: fn(&SheetRay) -> f64, pad: f64| -> Vec<f64> {
            let mut v: Vec<f64> = rays.iter().map(f).collect();
            v.resize(n, pad);
            v
        };
        let (b_lo, b_hi) = (column(|r| r.b_lo, -1.0), column(|r| r.b_hi, -1.0));
        let (a0, slope) = (column(|r| r.a0, 0.0), column(|r| r.slope, 0.0));
        let inv_slope = column(|r| r.inv_slope, 0.0);
        let groups = (0..n / Self::GROUP)
            .map(|g| {
                let one = |r: usize| {
                    // Padding rays widen no group's range of positions.
                    let real = r < rays.len();
                    let (a0, slope, inv) = (a0[r], slope[r], inv_slope[r]);
                    Span {
                        inside_lo: b_lo[r],
                        inside_hi: b_hi[r],
                        reach_lo: b_lo[r],
                        reach_hi: b_hi[r],
                        a0_lo: if real { a0 } else { f64::INFINITY },
                        a0_hi: if real { a0 } else { f64::NEG_INFINITY },
                        slope_lo: if real { slope } else { f64::INFINITY },
                        slope_hi: if real { slope } else { f64::NEG_INFINITY },
                        inv_finite: inv.is_finite(),
                    }
                };
                (g * Self::GROUP..(g + 1) * Self::GROUP)
                    .map(one)
                    .reduce(Span::merge)
                    .expect("GROUP > 0")
            })
            .collect();
        Self {
            a0,
            slope,
            inv_slope,
            b_lo,
            b_hi,
            groups,
        }
    }

    pub(super) fn len(&self) -> usize {
        self.a0.len()
    }

    /// The spans of the groups of `lanes` rays (a multiple of [`Rays::GROUP`] dividing
    /// [`Rays::PAD`]), in order: computed once per sheet and kernel, not per block.
    pub(super) fn spans(&self, lanes: usize) -> Vec<Span> {
        self.groups
            .chunks(lanes / Self::GROUP)
            .map(|c| {
                c.iter()
                    .copied()
                    .reduce(Span::merge)
                    .expect("lanes ≥ GROUP")
            })
            .collect()
    }
}

/// The range along `a` outside which every voxel of `block`'s lines is zero (see
/// [`Segment::nz_lo`]).
fn nonzero_range(block: &[Segment]) -> (f64, f64) {
    block
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s.nz_lo), hi.max(s.nz_hi))
        })
}
