//! The sheet kernel on four lanes of f64 (AVX2 + FMA): the operations of
//! `Kernel::piece`, in the same order, so the results are the same bits.
//!
//! A ray meets at most two voxels of a line per segment, and they are neighbours. Where the
//! lines are contiguous in memory (the sheet fans out along the grid's fastest axis, as in
//! AP views), each lane reads both with one 8-byte load at the lower of the two
//! (`PAIRS`); otherwise it reads each voxel on its own.

use super::{Kernel, Rays, Segment};
use std::arch::x86_64::*;

/// Whether this CPU has AVX2 and FMA (read once).
pub fn available() -> bool {
    static AVX2: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX2.get_or_init(|| {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    })
}

/// As `Kernel::integrate`, four rays at a time.
///
/// # Safety
/// The CPU must have AVX2 and FMA, and `kernel.field` fewer than 2³¹ values.
pub unsafe fn integrate(kernel: &Kernel, segments: &[Segment], rays: &Rays, acc: &mut [f64]) {
    // Pairs need two voxels per line inside the box.
    let pairs = kernel.stride == 1.0 && kernel.a_hi > kernel.a_lo;
    let loads = crate::trace::packet::scalar_voxel_loads();
    // SAFETY: the caller's guarantees.
    unsafe {
        match (pairs, loads) {
            (true, true) => integrate_with::<true, true>(kernel, segments, rays, acc),
            (true, false) => integrate_with::<true, false>(kernel, segments, rays, acc),
            (false, true) => integrate_with::<false, true>(kernel, segments, rays, acc),
            (false, false) => integrate_with::<false, false>(kernel, segments, rays, acc),
        }
    }
}

/// Segments handled together per group of rays: the group's rays stay in registers over
/// the block, and inside the group's range each segment's exit is the next one's entry.
const BLOCK: usize = 8;

/// `integrate`, in blocks of [`BLOCK`] segments: per block and group of four rays, the
/// rays and their sums are loaded once, and where the whole block lies inside every lane's
/// range a segment's entry (`x0` and its floor) is the previous segment's exit, the same
/// bits as computed anew (consecutive segments share their ends); groups whose rays all
/// miss the block skip it (at a chest CT's AP view, 14 % of the group-blocks). A lane's
/// two voxels are read as one pair (`PAIRS`; lines contiguous and at least two voxels long
/// in the box) or one by one, with scalar loads (`LOADS`) or gathers.
#[target_feature(enable = "avx2,fma")]
unsafe fn integrate_with<const PAIRS: bool, const LOADS: bool>(
    kernel: &Kernel,
    segments: &[Segment],
    rays: &Rays,
    acc: &mut [f64],
) {
    assert!(
        rays.len().is_multiple_of(4) && acc.len() == rays.len(),
        "rays and sums disagree"
    );
    let (a_lo, a_hi) = (_mm256_set1_pd(kernel.a_lo), _mm256_set1_pd(kernel.a_hi));
    let pair_hi = _mm256_set1_pd(kernel.a_hi - 1.0);
    let (stride, zero) = (_mm256_set1_pd(kernel.stride), _mm256_setzero_pd());
    let field = kernel.field;
    let span = (kernel.a_lo * kernel.stride) as usize..=(kernel.a_hi * kernel.stride) as usize;
    let step = if kernel.stride == 1.0 {
        16
    } else {
        kernel.stride as usize
    };
    let groups = acc.len() / 4;
    let lines = span.clone().step_by(step).count();
    // The cache lines of the next block's voxel lines over the box's extent, asked for a
    // few per group so that few are in flight at once: the kernel waits on memory without
    // them (a block's lines lie a line of the grid apart). Listed once per block, as
    // working out each address per group cost more than the kernel saved.
    let mut ahead: Vec<usize> = Vec::with_capacity(BLOCK * lines);
    for (n, block) in segments.chunks(BLOCK).enumerate() {
        let next = segments.get((n + 1) * BLOCK..).unwrap_or(&[]);
        ahead.clear();
        for s in &next[..next.len().min(BLOCK)] {
            let from = s.base as usize + *span.start();
            ahead.extend((0..lines).map(|l| from + l * step));
        }
        let mut asks = ahead.chunks(ahead.len().div_ceil(groups.max(1)).max(1));
        let (first_b0, last_b1) = (block[0].b0, block[block.len() - 1].b1);
        for (g, sums) in acc.chunks_exact_mut(4).enumerate() {
            for &at in asks.next().unwrap_or(&[]) {
                // SAFETY: a prefetch reads nothing; the address stays inside the field.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(field.as_ptr().add(at).cast()) };
            }
            // No lane's range meets the block: each piece would be an exact 0 (db = 0),
            // which leaves the sums' bits as they are.
            if last_b1 <= rays.reach_lo[g] || first_b0 >= rays.reach_hi[g] {
                continue;
            }
            let r = 4 * g;
            // SAFETY: r + 4 ≤ rays.len(), the length of every array (asserted above);
            // indices are clamped into the box, so below field.len() < 2³¹.
            unsafe {
                let ld = |v: &[f64]| _mm256_loadu_pd(v[r..r + 4].as_ptr());
                let (a0, slope, inv_slope) = (ld(&rays.a0), ld(&rays.slope), ld(&rays.inv_slope));
                let mut sum = _mm256_loadu_pd(sums.as_ptr());
                // ∫mu db over one segment, given the clipped ends and their positions.
                let piece = |s: &Segment, x0: __m256d, f0: __m256d, f1: __m256d, db: __m256d| {
                    let base = _mm256_set1_pd(s.base);
                    let (mu0, mu1) = if PAIRS {
                        let first =
                            _mm256_min_pd(_mm256_max_pd(_mm256_min_pd(f0, f1), a_lo), pair_hi);
                        let (lower, upper) = pair::<LOADS>(field, _mm256_add_pd(first, base));
                        let pick = |f| {
                            _mm256_blendv_pd(lower, upper, _mm256_cmp_pd::<_CMP_GT_OQ>(f, first))
                        };
                        (pick(f0), pick(f1))
                    } else {
                        let i0 = _mm256_min_pd(_mm256_max_pd(f0, a_lo), a_hi);
                        let i1 = _mm256_min_pd(_mm256_max_pd(f1, a_lo), a_hi);
                        (
                            gather::<LOADS>(field, _mm256_fmadd_pd(i0, stride, base)),
                            gather::<LOADS>(field, _mm256_fmadd_pd(i1, stride, base)),
                        )
                    };
                    let w = _mm256_mul_pd(_mm256_sub_pd(_mm256_max_pd(f0, f1), x0), inv_slope);
                    let w = _mm256_min_pd(_mm256_max_pd(w, zero), db);
                    _mm256_fmadd_pd(w, _mm256_sub_pd(mu0, mu1), _mm256_mul_pd(db, mu1))
                };
                if first_b0 >= rays.group_lo[g] && last_b1 <= rays.group_hi[g] {
                    let mut x0 = _mm256_fmadd_pd(slope, _mm256_set1_pd(first_b0), a0);
                    let mut f0 = _mm256_floor_pd(x0);
                    for s in block.iter() {
                        let x1 = _mm256_fmadd_pd(slope, _mm256_set1_pd(s.b1), a0);
                        let f1 = _mm256_floor_pd(x1);
                        sum = _mm256_add_pd(sum, piece(s, x0, f0, f1, _mm256_set1_pd(s.db)));
                        (x0, f0) = (x1, f1);
                    }
                } else {
                    let (b_lo, b_hi) = (ld(&rays.b_lo), ld(&rays.b_hi));
                    for s in block.iter() {
                        let lo = _mm256_max_pd(_mm256_set1_pd(s.b0), b_lo);
                        let hi = _mm256_min_pd(_mm256_set1_pd(s.b1), b_hi);
                        let db = _mm256_max_pd(_mm256_sub_pd(hi, lo), zero);
                        let x0 = _mm256_fmadd_pd(slope, lo, a0);
                        let x1 = _mm256_fmadd_pd(slope, hi, a0);
                        let (f0, f1) = (_mm256_floor_pd(x0), _mm256_floor_pd(x1));
                        sum = _mm256_add_pd(sum, piece(s, x0, f0, f1, db));
                    }
                }
                _mm256_storeu_pd(sums.as_mut_ptr(), sum);
            }
        }
    }
}

/// The four voxels at `index` (whole numbers in f64, each < field.len()), as f64.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn gather<const LOADS: bool>(field: &[f32], index: __m256d) -> __m256d {
    let index = _mm256_cvtpd_epi32(index);
    // SAFETY: the caller's indices are in bounds and below 2³¹; 4 i32 into a local array
    // of that size.
    unsafe {
        let g = if LOADS {
            let mut idx = [0i32; 4];
            _mm_storeu_si128(idx.as_mut_ptr().cast(), index);
            let v = |l: usize| *field.get_unchecked(idx[l] as usize);
            _mm_setr_ps(v(0), v(1), v(2), v(3))
        } else {
            _mm_i32gather_ps::<4>(field.as_ptr(), index)
        };
        _mm256_cvtps_pd(g)
    }
}

/// The voxels at `index` and `index + 1` of each lane (whole numbers in f64, `index + 1 <
/// field.len()`), as two vectors of f64.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn pair<const LOADS: bool>(field: &[f32], index: __m256d) -> (__m256d, __m256d) {
    let index = _mm256_cvtpd_epi32(index);
    // SAFETY: the caller's indices and their successors are in bounds and below 2³¹; 4 i32
    // into a local array of that size.
    let both = unsafe {
        if LOADS {
            let mut idx = [0i32; 4];
            _mm_storeu_si128(idx.as_mut_ptr().cast(), index);
            let v = |l: usize| {
                field
                    .as_ptr()
                    .add(idx[l] as usize)
                    .cast::<i64>()
                    .read_unaligned()
            };
            _mm256_setr_epi64x(v(0), v(1), v(2), v(3))
        } else {
            _mm256_i32gather_epi64::<4>(field.as_ptr().cast(), index)
        }
    };
    // [l0 u0 l1 u1 l2 u2 l3 u3] → [l0 l1 l2 l3 | u0 u1 u2 u3].
    let split = _mm256_permutevar8x32_ps(
        _mm256_castsi256_ps(both),
        _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7),
    );
    (
        _mm256_cvtps_pd(_mm256_castps256_ps128(split)),
        _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(split)),
    )
}
