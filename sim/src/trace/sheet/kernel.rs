//! The sheet kernel's body, shared by every instruction set (`sheet_kernel!`).

/// The kernel body, instantiated per instruction set: `Kernel::integrate`'s operations, in
/// the same order, on `$lanes` rays at a time, so the results are the same bits as the
/// portable kernel's. The caller supplies the vector type and the primitives (all
/// `#[inline]` with the set's target features; the arithmetic and `gather` from
/// `avx2_lanes!` / `avx512_lanes!`, `super::super::lanes`): `splat`, `zero`, `min`, `max`,
/// `add`, `sub`, `mul`, `fmadd` (a·b + c), `floor`, `loadu`/`storeu` (`LANES` f64 at a pointer),
/// `pick(f, first, lower, upper)` (`upper` where `f > first`, else `lower`),
/// `gather::<LOADS>` (f32 values at f64-valued indices, widened to f64) and
/// `pair::<LOADS>` (the values at an index and the next one), with `LOADS` choosing scalar
/// loads over the set's gather ([`crate::trace::packet::scalar_voxel_loads`]).
#[cfg(target_arch = "x86_64")]
macro_rules! sheet_kernel {
    ($features:literal, $lanes:literal, $vec:ty, { $($prims:item)* }) => {
        use super::{Kernel, Rays, Segment};
        #[allow(unused_imports)]
        use std::arch::x86_64::*;

        type V = $vec;
        /// Rays per vector.
        const LANES: usize = $lanes;
        /// Groups of [`Rays::GROUP`] rays per vector.
        const QUADS: usize = LANES / Rays::GROUP;

        $($prims)*

        /// As `Kernel::integrate`, `LANES` rays at a time.
        ///
        /// # Safety
        /// The CPU must have the instruction set's features, and `kernel.field` fewer
        /// than 2³¹ values.
        pub unsafe fn integrate(
            kernel: &Kernel,
            segments: &[Segment],
            rays: &Rays,
            acc: &mut [f64],
        ) {
            // Pairs need two voxels per line inside the box.
            let pairs = kernel.stride == 1.0 && kernel.a_hi > kernel.a_lo;
            let loads = crate::trace::packet::scalar_voxel_loads();
            // SAFETY: the caller's guarantees.
            unsafe {
                match (pairs, loads) {
                    (true, true) => integrate_with::<true, true>(kernel, segments, rays, acc),
                    (true, false) => integrate_with::<true, false>(kernel, segments, rays, acc),
                    (false, true) => integrate_with::<false, true>(kernel, segments, rays, acc),
                    (false, false) => {
                        integrate_with::<false, false>(kernel, segments, rays, acc)
                    }
                }
            }
        }

        /// `integrate`, in blocks of [`super::BLOCK`] segments: per block and group of
        /// `LANES` rays, the rays and their sums are loaded once, and where the whole block
        /// lies inside every lane's range a segment's entry (`x0` and its floor) is the
        /// previous segment's exit, the same bits as computed anew (consecutive segments
        /// share their ends); groups whose rays all miss the block skip it (at a chest CT's
        /// AP view, 14 % of the groups of four). A lane's two voxels are read as one pair
        /// (`PAIRS`; lines contiguous and at least two voxels long in the box) or one by
        /// one, with scalar loads (`LOADS`) or gathers.
        #[target_feature(enable = $features)]
        unsafe fn integrate_with<const PAIRS: bool, const LOADS: bool>(
            kernel: &Kernel,
            segments: &[Segment],
            rays: &Rays,
            acc: &mut [f64],
        ) {
            assert!(
                rays.len().is_multiple_of(LANES) && acc.len() == rays.len(),
                "rays and sums disagree"
            );
            let (a_lo, a_hi) = (splat(kernel.a_lo), splat(kernel.a_hi));
            let pair_hi = splat(kernel.a_hi - 1.0);
            let (stride, zero) = (splat(kernel.stride), zero());
            let field = kernel.field;
            let groups = acc.len() / LANES;
            let mut ahead = super::Ahead::new(kernel);
            for (n, block) in segments.chunks(super::BLOCK).enumerate() {
                ahead.list(segments, n);
                let mut asks = ahead.asks(groups);
                let (first_b0, last_b1) = (block[0].b0, block[block.len() - 1].b1);
                let (nz_lo, nz_hi) = super::nonzero_range(block);
                let zeros = nz_lo > f64::NEG_INFINITY || nz_hi < f64::INFINITY;
                for (g, sums) in acc.chunks_exact_mut(LANES).enumerate() {
                    for &at in asks.next().unwrap_or(&[]) {
                        // SAFETY: a prefetch reads nothing; the address stays inside the
                        // field.
                        unsafe { _mm_prefetch::<_MM_HINT_T0>(field.as_ptr().add(at).cast()) };
                    }
                    let quads = g * QUADS..(g + 1) * QUADS;
                    let fold = |v: &[f64], f: fn(f64, f64) -> f64| {
                        v[quads.clone()].iter().copied().reduce(f).unwrap_or(0.0)
                    };
                    // No lane's range meets the block: each piece would be an exact 0
                    // (db = 0), which leaves the sums' bits as they are.
                    if last_b1 <= fold(&rays.reach_lo, f64::min)
                        || first_b0 >= fold(&rays.reach_hi, f64::max)
                    {
                        continue;
                    }
                    // Every voxel the group's rays can meet in the block is zero: each
                    // piece would be an exact 0 (±0), which leaves the sums' bits as they
                    // are.
                    if zeros && rays.outside(quads.clone(), first_b0, last_b1, nz_lo, nz_hi) {
                        continue;
                    }
                    let inside = first_b0 >= fold(&rays.group_lo, f64::max)
                        && last_b1 <= fold(&rays.group_hi, f64::min);
                    let r = LANES * g;
                    // SAFETY: r + LANES ≤ rays.len(), the length of every array (asserted
                    // above); indices are clamped into the box, so below field.len() < 2³¹.
                    unsafe {
                        let ld = |v: &[f64]| loadu(v[r..r + LANES].as_ptr());
                        let (a0, slope, inv_slope) =
                            (ld(&rays.a0), ld(&rays.slope), ld(&rays.inv_slope));
                        let mut sum = loadu(sums.as_ptr());
                        // ∫mu db over one segment, given the clipped ends and their positions.
                        let piece = |s: &Segment, x0: V, f0: V, f1: V, db: V| {
                            let base = splat(s.base);
                            let (mu0, mu1) = if PAIRS {
                                let first = min(max(min(f0, f1), a_lo), pair_hi);
                                let (lower, upper) = pair::<LOADS>(field, add(first, base));
                                (pick(f0, first, lower, upper), pick(f1, first, lower, upper))
                            } else {
                                let i0 = min(max(f0, a_lo), a_hi);
                                let i1 = min(max(f1, a_lo), a_hi);
                                (
                                    gather::<LOADS>(field, fmadd(i0, stride, base)),
                                    gather::<LOADS>(field, fmadd(i1, stride, base)),
                                )
                            };
                            let w = mul(sub(max(f0, f1), x0), inv_slope);
                            let w = min(max(w, zero), db);
                            fmadd(w, sub(mu0, mu1), mul(db, mu1))
                        };
                        if inside {
                            let mut x0 = fmadd(slope, splat(first_b0), a0);
                            let mut f0 = floor(x0);
                            for s in block.iter() {
                                let x1 = fmadd(slope, splat(s.b1), a0);
                                let f1 = floor(x1);
                                sum = add(sum, piece(s, x0, f0, f1, splat(s.db)));
                                (x0, f0) = (x1, f1);
                            }
                        } else {
                            let (b_lo, b_hi) = (ld(&rays.b_lo), ld(&rays.b_hi));
                            for s in block.iter() {
                                let lo = max(splat(s.b0), b_lo);
                                let hi = min(splat(s.b1), b_hi);
                                let db = max(sub(hi, lo), zero);
                                let x0 = fmadd(slope, lo, a0);
                                let x1 = fmadd(slope, hi, a0);
                                sum = add(sum, piece(s, x0, floor(x0), floor(x1), db));
                            }
                        }
                        storeu(sums.as_mut_ptr(), sum);
                    }
                }
            }
        }
    };
}
