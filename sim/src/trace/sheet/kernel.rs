//! The sheet kernel's body, shared by every instruction set (`sheet_kernel!`).

/// The kernel body, instantiated per instruction set: `Kernel::integrate`'s and
/// `Kernel::integrate_materials`' operations, in the same order, on `LANES` rays at a time,
/// so the results are the same bits as the portable kernel's. The caller supplies the set's
/// lanes (`avx2_lanes!()` or `avx512_lanes!()`, `super::super::lanes`) and `pair_raw::<LOADS>`
/// (unsafe: the raw values at an index and the next one, each `index + 1` below
/// `field.len()` < 2³¹; `LOADS`: one 8-byte load per lane instead of a gather), all
/// `#[inline]` with the set's target `$features`.
#[cfg(target_arch = "x86_64")]
macro_rules! sheet_kernel {
    ($features:literal, { $($prims:item)* }) => {
        use super::{Kernel, MaterialSums, Pass, Rays, Segment};
        #[allow(unused_imports)]
        use std::arch::x86_64::*;

        $($prims)*

        /// As `Kernel::integrate` (`materials`: `None`) or `Kernel::integrate_materials`,
        /// `LANES` rays at a time.
        ///
        /// # Safety
        /// The CPU must have the instruction set's features, and `kernel.field` fewer
        /// than 2³¹ values.
        pub unsafe fn integrate(
            kernel: &Kernel,
            segments: &[Segment],
            rays: &Rays,
            acc: &mut [f64],
            materials: Option<&mut MaterialSums>,
        ) {
            // Pairs need two voxels per line inside the box.
            let pairs = kernel.stride == 1.0 && kernel.a_hi > kernel.a_lo;
            let loads = crate::trace::packet::scalar_voxel_loads();
            // SAFETY: the caller's guarantees.
            unsafe {
                match (pairs, loads) {
                    (true, true) => integrate_with::<true, true>(kernel, segments, rays, acc, materials),
                    (true, false) => integrate_with::<true, false>(kernel, segments, rays, acc, materials),
                    (false, true) => integrate_with::<false, true>(kernel, segments, rays, acc, materials),
                    (false, false) => {
                        integrate_with::<false, false>(kernel, segments, rays, acc, materials)
                    }
                }
            }
        }

        /// What a lane meets over one segment: the values (mu, or a composition's
        /// density) of the voxels at its entry (`v0`) and exit (`v1`) and, for
        /// compositions, their material indices.
        struct Voxels {
            v0: V,
            v1: V,
            m0: V,
            m1: V,
        }

        /// `integrate`, in blocks of [`super::BLOCK`] segments: per block and group of
        /// `LANES` rays, the rays and their sums are loaded once, and where the whole block
        /// lies inside every lane's range a segment's entry (`x0` and its floor) is the
        /// previous segment's exit, the same bits as computed anew (consecutive segments
        /// share their ends). Groups whose rays all miss the block (at a chest CT's AP
        /// view, 14 % of the groups of four), or meet only zeros in it
        /// (`super::Sheet::skip_zeros`), skip it; line integrals over a block where every
        /// lane moves one way within the box take `monotone_pieces` (`Pass`, decided per
        /// group and block by `Span::pass`). A lane's two voxels are read as one pair
        /// (`PAIRS`; lines contiguous and at least two voxels long in the box) or one by
        /// one, with scalar loads (`LOADS`) or gathers. With `materials`, `acc` is unused
        /// and each group's composition state lives there.
        #[target_feature(enable = $features)]
        unsafe fn integrate_with<const PAIRS: bool, const LOADS: bool>(
            kernel: &Kernel,
            segments: &[Segment],
            rays: &Rays,
            acc: &mut [f64],
            mut materials: Option<&mut MaterialSums>,
        ) {
            assert!(
                rays.len().is_multiple_of(LANES)
                    && match materials.as_ref() {
                        None => acc.len() == rays.len(),
                        Some(m) => m.rays() == rays.len(),
                    },
                "rays and sums disagree"
            );
            let packed = materials.is_some();
            let (a_lo, a_hi) = (splat(kernel.a_lo), splat(kernel.a_hi));
            let pair_hi = splat(kernel.a_hi - 1.0);
            let (stride, zero) = (splat(kernel.stride), zero());
            let field = kernel.field;
            let groups = rays.len() / LANES;
            let ld = |v: &[f64], r: usize| load(v[r..r + LANES].try_into().unwrap());
            let spans = rays.spans(LANES);
            // Where the shortest path applies (`Pass::Monotone`, `monotone_pieces`).
            let monotone = (!packed && PAIRS).then_some((kernel.a_lo, kernel.a_hi));
            let mut ahead = super::Ahead::new(kernel);
            for (n, block) in segments.chunks(super::BLOCK).enumerate() {
                ahead.list(segments, n);
                let mut asks = ahead.asks(groups);
                let range = super::Block::of(block);
                let first_b0 = range.b0;
                for g in 0..groups {
                    // Into L2 (`T1`), not L1: on an Intel Xeon with AVX-512 the chest CT's
                    // AP view renders 4–7 % faster so (one render per process; `T0`,
                    // into L1, was chosen before the monotone path made the arithmetic
                    // shorter; docs/projector.md, "Session 30").
                    for &at in asks.next().unwrap_or(&[]) {
                        // SAFETY: a prefetch reads nothing; the address stays inside the
                        // field.
                        unsafe { _mm_prefetch::<_MM_HINT_T1>(field.as_ptr().add(at).cast()) };
                    }
                    // Missed and all-zero blocks: each piece would be an exact 0 (±0),
                    // which leaves the sums' bits as they are.
                    let pass = spans[g].pass(&range, monotone);
                    if matches!(pass, Pass::Miss | Pass::Zeros) {
                        continue;
                    }
                    let r = LANES * g;
                    let (a0, slope, inv_slope) = (ld(&rays.a0, r), ld(&rays.slope, r), ld(&rays.inv_slope, r));
                    // The line integrals, or the sums of each material.
                    let mut sum = match materials.as_deref() {
                        None => ld(acc, r),
                        Some(_) => zero,
                    };
                    let k = materials.as_deref().map_or(0, MaterialSums::materials);
                    let mut mats = [zero; crate::composition::MAX_MATERIALS];
                    if let Some(m) = materials.as_deref() {
                        for (c, v) in mats[..k].iter_mut().enumerate() {
                            *v = ld(&m.sums[c * rays.len()..], r);
                        }
                    }
                    // The voxels of one segment, given its clipped ends' floors.
                    let voxels = |s: &Segment, f0: V, f1: V| {
                        let base = splat(s.base);
                        // SAFETY: indices are clamped into the box, so below
                        // field.len() < 2³¹ (`integrate`'s contract), and a pair's second
                        // voxel is still in the box.
                        let (raw0, raw1) = unsafe {
                            if PAIRS {
                                let first = min(max(min(f0, f1), a_lo), pair_hi);
                                let (lower, upper) = pair_raw::<LOADS>(field, add(first, base));
                                let (p0, p1) = (gt(f0, first), gt(f1, first));
                                if !packed {
                                    let (lower, upper) = (widen(lower), widen(upper));
                                    let pick = |p| select(p, upper, lower);
                                    return Voxels { v0: pick(p0), v1: pick(p1), m0: zero, m1: zero };
                                }
                                let ((dl, ml), (du, mu)) = (unpack(lower), unpack(upper));
                                return Voxels {
                                    v0: select(p0, du, dl),
                                    v1: select(p1, du, dl),
                                    m0: select(p0, mu, ml),
                                    m1: select(p1, mu, ml),
                                };
                            }
                            let i0 = min(max(f0, a_lo), a_hi);
                            let i1 = min(max(f1, a_lo), a_hi);
                            (
                                gather_raw::<LOADS>(field, fmadd(i0, stride, base)),
                                gather_raw::<LOADS>(field, fmadd(i1, stride, base)),
                            )
                        };
                        if !packed {
                            return Voxels { v0: widen(raw0), v1: widen(raw1), m0: zero, m1: zero };
                        }
                        let ((v0, m0), (v1, m1)) = (unpack(raw0), unpack(raw1));
                        Voxels { v0, v1, m0, m1 }
                    };
                    // ∫ over one segment, given the clipped ends and their positions.
                    let piece = |s: &Segment, x0: V, f0: V, f1: V, db: V, sum: &mut V, mats: &mut [V]| {
                        let v = voxels(s, f0, f1);
                        let w = mul(sub(max(f0, f1), x0), inv_slope);
                        let w = min(max(w, zero), db);
                        let whole = fmadd(w, sub(v.v0, v.v1), mul(db, v.v1));
                        if !packed {
                            *sum = add(*sum, whole);
                            return;
                        }
                        // As `Kernel::integrate_materials`: one material, or two.
                        let same = eq(v.m0, v.m1);
                        if all(same) {
                            add_material(mats, v.m1, whole);
                        } else {
                            add_material(mats, select(same, v.m1, v.m0), select(same, whole, mul(w, v.v0)));
                            add_material(mats, v.m1, select(same, zero, mul(sub(db, w), v.v1)));
                        }
                    };
                    if let Pass::Monotone { rising } = pass {
                        let ray = (a0, slope, inv_slope);
                        // SAFETY: as for `voxels`; the pass keeps every pair in the box.
                        sum = unsafe {
                            if rising {
                                monotone_pieces::<true, LOADS>(field, block, first_b0, ray, sum)
                            } else {
                                monotone_pieces::<false, LOADS>(field, block, first_b0, ray, sum)
                            }
                        };
                    } else if pass == Pass::Inside {
                        let mut x0 = fmadd(slope, splat(first_b0), a0);
                        let mut f0 = floor(x0);
                        for s in block.iter() {
                            let x1 = fmadd(slope, splat(s.b1), a0);
                            let f1 = floor(x1);
                            piece(s, x0, f0, f1, splat(s.db), &mut sum, &mut mats[..k]);
                            (x0, f0) = (x1, f1);
                        }
                    } else {
                        let (b_lo, b_hi) = (ld(&rays.b_lo, r), ld(&rays.b_hi, r));
                        for s in block.iter() {
                            let lo = max(splat(s.b0), b_lo);
                            let hi = min(splat(s.b1), b_hi);
                            let db = max(sub(hi, lo), zero);
                            let x0 = fmadd(slope, lo, a0);
                            let x1 = fmadd(slope, hi, a0);
                            piece(s, x0, floor(x0), floor(x1), db, &mut sum, &mut mats[..k]);
                        }
                    }
                    match materials.as_deref_mut() {
                        None => acc[r..r + LANES].copy_from_slice(&store(sum)),
                        Some(m) => {
                            let n = rays.len();
                            for (c, v) in mats[..k].iter().enumerate() {
                                m.sums[c * n + r..c * n + r + LANES].copy_from_slice(&store(*v));
                            }
                        }
                    }
                }
            }
        }

        /// The line integrals over `block` added to `sum`, for a group of rays inside the
        /// block whose positions along `a` rise (`RISING`; no slope negative) or fall (no
        /// slope positive) and stay within the box, leaving out the last voxel
        /// ([`super::rays::Span::pass`]): `piece`'s operations, less those that
        /// cannot change a bit there. Each segment's pair starts at the lower of its two
        /// floors, the entry's where positions rise and the exit's where they fall; both
        /// lie in the box, so `piece`'s clamps change nothing, its `max(f0, f1)` is the
        /// other end's floor, and the lower end's voxel is the pair's lower one. `piece`
        /// clamps `w` at 0 too: where the floors differ `w` is ≥ 0 already (at most −0
        /// for +0); where they agree it may be < 0 here, but is finite (every `inv_slope`
        /// is) and multiplies `v0 - v1` = +0. Either way the piece can differ from
        /// `piece`'s only in the sign of a zero, which leaves the sum's bits as they are
        /// (sums are ≥ +0).
        ///
        /// # Safety
        /// As `integrate_with`, and every lane's pairs lie in the box as said.
        #[inline]
        #[target_feature(enable = $features)]
        unsafe fn monotone_pieces<const RISING: bool, const LOADS: bool>(
            field: &[f32],
            block: &[Segment],
            first_b0: f64,
            (a0, slope, inv_slope): (V, V, V),
            mut sum: V,
        ) -> V {
            let mut x0 = fmadd(slope, splat(first_b0), a0);
            let mut f0 = floor(x0);
            for s in block {
                let x1 = fmadd(slope, splat(s.b1), a0);
                let f1 = floor(x1);
                let db = splat(s.db);
                let (low, high) = if RISING { (f0, f1) } else { (f1, f0) };
                // SAFETY: the caller's guarantee: `low` and `low + 1` are voxels of the box.
                let (lower, upper) = unsafe { pair_raw::<LOADS>(field, add(low, splat(s.base))) };
                let (lower, upper) = (widen(lower), widen(upper));
                let other = select(gt(high, low), upper, lower);
                let (v0, v1) = if RISING { (lower, other) } else { (other, lower) };
                let w = min(mul(sub(high, x0), inv_slope), db);
                sum = add(sum, fmadd(w, sub(v0, v1), mul(db, v1)));
                (x0, f0) = (x1, f1);
            }
            sum
        }

        /// Adds `w` to each lane's sum of its material `label` (a piece of 0 adds +0, which
        /// changes no bits: sums are ≥ +0).
        #[inline]
        #[target_feature(enable = $features)]
        fn add_material(mats: &mut [V], label: V, w: V) {
            for (m, sum) in mats.iter_mut().enumerate() {
                *sum = add_where(eq(label, splat(m as f64)), *sum, w);
            }
        }
    };
}
