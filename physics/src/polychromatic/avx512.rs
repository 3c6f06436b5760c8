//! The kernel's inner loops in AVX-512 instructions ([`super::kernel`] picks them where the
//! CPU has AVX-512): the same arithmetic in the same order as the portable forms, but with
//! `vrndscaleps` and `vscalefps` in the exponential (one instruction each where the
//! portable form needs five) and the optical depth of a block of 16 bins kept in a
//! register from the first material to its exponential.

use super::exp2::EXP2_TAYLOR;
use std::arch::x86_64::*;

/// Lanes of one register of f32.
const LANES: usize = 16;
/// Most materials [`transmission`] holds in registers; more go the portable way.
pub(super) const MAX_MATERIALS: usize = 16;

/// e^(−x) per lane: [`super::kernel::exp_neg`]'s polynomial and range reduction. Equal
/// to it where the result is a normal f32 (x ≤ 87.3); below 2^−126 this keeps subnormal
/// results where the portable form flushes them to 0. Never NaN for x ≥ 0, +∞ included.
#[inline]
#[target_feature(enable = "avx512f")]
fn exp_neg(x: __m512) -> __m512 {
    let x = _mm512_min_ps(_mm512_max_ps(x, _mm512_setzero_ps()), _mm512_set1_ps(200.0));
    let y = _mm512_mul_ps(x, _mm512_set1_ps(-std::f32::consts::LOG2_E));
    let k = _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(y);
    let f = _mm512_sub_ps(y, k);
    let mut p = _mm512_set1_ps(EXP2_TAYLOR[7]);
    for &c in EXP2_TAYLOR[..7].iter().rev() {
        p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(c));
    }
    _mm512_scalef_ps(p, k)
}

/// [`exp_neg`] of every value of `x` (a multiple of 16 long), in place.
#[cfg(test)]
#[target_feature(enable = "avx512f")]
pub(super) fn exp_neg_in_place(x: &mut [f32]) {
    for v in x.chunks_exact_mut(LANES) {
        // SAFETY: 16 f32 read from and written to a chunk of 16.
        unsafe { _mm512_storeu_ps(v.as_mut_ptr(), exp_neg(_mm512_loadu_ps(v.as_ptr()))) };
    }
}

/// The transmission per bin behind thicknesses `t` (g/cm², at most [`MAX_MATERIALS`])
/// into `att` (`bins` values, a multiple of 16), `mass_att` material-major: per block of
/// 16 bins, Σ_m t_m·μ_m fused in material order, then its exponential.
#[target_feature(enable = "avx512f")]
pub(super) fn transmission(mass_att: &[f32], bins: usize, t: &[f64], att: &mut [f32]) {
    assert!(t.len() <= MAX_MATERIALS && mass_att.len() >= t.len() * bins && att.len() == bins);
    assert!(bins.is_multiple_of(LANES));
    let mut tm = [_mm512_setzero_ps(); MAX_MATERIALS];
    for (v, &x) in tm.iter_mut().zip(t) {
        *v = _mm512_set1_ps(x as f32);
    }
    let tm = &tm[..t.len()];
    for (b, out) in att.chunks_exact_mut(LANES).enumerate() {
        let mut tau = _mm512_setzero_ps();
        for (m, &tv) in tm.iter().enumerate() {
            // SAFETY: m·bins + 16·b + 15 < t.len()·bins ≤ mass_att.len() (asserted above).
            let mu = unsafe { _mm512_loadu_ps(mass_att.as_ptr().add(m * bins + b * LANES)) };
            tau = _mm512_fmadd_ps(tv, mu, tau);
        }
        // SAFETY: 16 f32 written to a chunk of 16.
        unsafe { _mm512_storeu_ps(out.as_mut_ptr(), exp_neg(tau)) };
    }
}

/// (Σ a·x, Σ b·x) over whole blocks of 16, one f32 partial sum per lane, the lanes added
/// in f64 as [`super::kernel::lane_sum`]'s tree.
#[target_feature(enable = "avx512f")]
pub(super) fn dots(a: &[f32], b: &[f32], x: &[f32]) -> (f64, f64) {
    let (mut sa, mut sb) = (_mm512_setzero_ps(), _mm512_setzero_ps());
    for ((a, b), x) in a
        .chunks_exact(LANES)
        .zip(b.chunks_exact(LANES))
        .zip(x.chunks_exact(LANES))
    {
        // SAFETY: 16 f32 read from each chunk of 16.
        let (a, b, x) = unsafe {
            (
                _mm512_loadu_ps(a.as_ptr()),
                _mm512_loadu_ps(b.as_ptr()),
                _mm512_loadu_ps(x.as_ptr()),
            )
        };
        sa = _mm512_fmadd_ps(a, x, sa);
        sb = _mm512_fmadd_ps(b, x, sb);
    }
    (lane_sum(sa), lane_sum(sb))
}

/// Lanes l and l + 8 widened and added, then halves added down to one value: the same
/// tree as the portable `lane_sum`.
#[inline]
#[target_feature(enable = "avx512f")]
fn lane_sum(s: __m512) -> f64 {
    let lo = _mm512_cvtps_pd(_mm512_castps512_ps256(s));
    let hi = _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(
        _mm512_castps_pd(s),
    )));
    let h = _mm512_add_pd(lo, hi);
    let h = _mm256_add_pd(_mm512_castpd512_pd256(h), _mm512_extractf64x4_pd::<1>(h));
    let h = _mm_add_pd(_mm256_castpd256_pd128(h), _mm256_extractf128_pd::<1>(h));
    _mm_cvtsd_f64(_mm_add_sd(h, _mm_unpackhi_pd(h, h)))
}
