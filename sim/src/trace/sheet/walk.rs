//! The shared line of a sheet cut into segments by the grid planes of `b` and `c`.

use super::Segment;
use crate::grid_box::GridBox;

/// The segments of the line `c = c0 + mc·b` for `b ∈ [lo, hi]` between consecutive planes
/// of `b` and `c`, each with the linear index of its voxel line's `a = 0` voxel.
#[allow(clippy::too_many_arguments)] // the line, its two axes, the box and the strides
pub(super) fn walk(
    lo: f64,
    hi: f64,
    c0: f64,
    mc: f64,
    b: usize,
    c: usize,
    bounds: &GridBox,
    strides: [usize; 3],
) -> Vec<Segment> {
    let mut segments = Vec::with_capacity((hi - lo).max(0.0) as usize + 16);
    let (jb_lo, jb_hi) = (bounds.lo[b] as f64, (bounds.hi[b] - 1) as f64);
    let (jc_lo, jc_hi) = (bounds.lo[c] as f64, (bounds.hi[c] - 1) as f64);
    // The planes ahead: of b at `next_b`, of c at `next_c` (the line's crossing of plane
    // `p`). Each is worked out from its plane alone, not from where the walk stands, so
    // the loop carries no division or floor from one segment to the next.
    let step = if mc > 0.0 { 1.0 } else { -1.0 };
    let mut p = if mc > 0.0 {
        (c0 + mc * lo).floor() + 1.0
    } else {
        (c0 + mc * lo).ceil() - 1.0
    };
    let cross = |p: f64| {
        if mc != 0.0 {
            (p - c0) / mc
        } else {
            f64::INFINITY
        }
    };
    let mut next_c = cross(p);
    let mut next_b = lo.floor() + 1.0;
    let mut b0 = lo;
    while b0 < hi {
        // The next plane of b, and the next plane of c if the line crosses one first. A
        // slab of b holds at most one plane of c (|mc| ≤ 1), and every step moves forward:
        // a crossing that rounding puts at or before b0 is behind the walk.
        while next_c <= b0 {
            p += step;
            next_c = cross(p);
        }
        let mut b1 = next_b.min(hi);
        if next_c < b1 {
            b1 = next_c;
            p += step;
            next_c = cross(p);
        } else {
            next_b += 1.0;
        }
        // The voxel from the segment's midpoint: half-open voxels [i, i+1), and a line
        // lying in a plane of c belongs to the voxel above it, as in the other tracers.
        // The bounds are whole numbers ≥ 0, so the truncating cast of the clamped value is
        // the clamped floor (NaN included), without `f64::floor`: on the default x86-64
        // target (no SSE4.1) that is a call into the maths library, two per segment.
        let mid = 0.5 * (b0 + b1);
        let jb = mid.clamp(jb_lo, jb_hi) as usize;
        let jc = (c0 + mc * mid).clamp(jc_lo, jc_hi) as usize;
        segments.push(Segment {
            b0,
            b1,
            db: b1 - b0,
            base: (jb * strides[b] + jc * strides[c]) as f64,
            nz_lo: f64::NEG_INFINITY,
            nz_hi: f64::INFINITY,
        });
        b0 = b1;
    }
    segments
}
