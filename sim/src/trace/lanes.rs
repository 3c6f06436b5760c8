//! The lanes of the SIMD kernels ([`super::packet`], [`super::sheet`]): one macro per
//! instruction set (`avx2_lanes!`, `avx512_lanes!`), expanded inside a kernel's module,
//! defines its vector types and every primitive the kernels share, once:
//!
//! * `V` (`LANES` f64), `M` (a lane mask), `H` (`LANES` f32 values or raw bits);
//! * `splat`, `zero`, `min`, `max`, `add`, `sub`, `mul`, `fmadd` (a·b + c), `floor`
//!   (towards −∞, exceptions suppressed);
//! * `gt`, `le`, `ne`, `eq` (lane masks), `and` (of masks), `all`, `none`, `bits` (one bit
//!   per lane, lane 0 lowest), `select` (mask ? a : b), `add_where` (s + w where the mask is
//!   set);
//! * `load`/`store` (from/to `[f64; LANES]`);
//! * voxel reads (unsafe: every index below `field.len()` < 2³¹): `gather_raw::<LOADS>`
//!   (the f32 values at f64-valued indices, read with `LANES` scalar loads (`LOADS`) or one
//!   `vgatherdps`, see [`super::packet::scalar_voxel_loads`]), `gather::<LOADS>` (the same,
//!   widened to f64); `widen` (f32 → f64) and `unpack` (a composition's packed values →
//!   density and material index, both as f64; [`crate::composition`]).

/// Defines the arithmetic (`splat` … `floor`) on `V` from an instruction set's intrinsics,
/// each `#[inline]` with its `$features`.
#[cfg(target_arch = "x86_64")]
macro_rules! f64_lanes {
    ($features:literal, splat $splat:ident, zero $zero:ident, min $min:ident, max $max:ident,
     add $add:ident, sub $sub:ident, mul $mul:ident, fmadd $fmadd:ident,
     floor $floor:expr) => {
        #[inline]
        #[target_feature(enable = $features)]
        fn splat(x: f64) -> V {
            $splat(x)
        }
        #[inline]
        #[target_feature(enable = $features)]
        fn zero() -> V {
            $zero()
        }
        #[inline]
        #[target_feature(enable = $features)]
        fn min(a: V, b: V) -> V {
            $min(a, b)
        }
        #[inline]
        #[target_feature(enable = $features)]
        fn max(a: V, b: V) -> V {
            $max(a, b)
        }
        #[inline]
        #[target_feature(enable = $features)]
        fn add(a: V, b: V) -> V {
            $add(a, b)
        }
        #[inline]
        #[target_feature(enable = $features)]
        fn sub(a: V, b: V) -> V {
            $sub(a, b)
        }
        #[inline]
        #[target_feature(enable = $features)]
        fn mul(a: V, b: V) -> V {
            $mul(a, b)
        }
        #[inline]
        #[target_feature(enable = $features)]
        fn fmadd(a: V, b: V, c: V) -> V {
            $fmadd(a, b, c)
        }
        #[inline]
        #[target_feature(enable = $features)]
        fn floor(a: V) -> V {
            ($floor)(a)
        }
    };
}

/// Four lanes with AVX2 + FMA: masks are vectors of all-ones or all-zeros lanes.
#[cfg(target_arch = "x86_64")]
macro_rules! avx2_lanes {
    () => {
        type V = __m256d;
        type M = __m256d;
        type H = __m128;
        const LANES: usize = 4;
        f64_lanes!(
            "avx2,fma",
            splat _mm256_set1_pd,
            zero _mm256_setzero_pd,
            min _mm256_min_pd,
            max _mm256_max_pd,
            add _mm256_add_pd,
            sub _mm256_sub_pd,
            mul _mm256_mul_pd,
            fmadd _mm256_fmadd_pd,
            floor _mm256_floor_pd
        );
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn gt(a: V, b: V) -> M {
            _mm256_cmp_pd::<_CMP_GT_OQ>(a, b)
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn le(a: V, b: V) -> M {
            _mm256_cmp_pd::<_CMP_LE_OQ>(a, b)
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn ne(a: V, b: V) -> M {
            _mm256_cmp_pd::<_CMP_NEQ_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn eq(a: V, b: V) -> M {
            _mm256_cmp_pd::<_CMP_EQ_OQ>(a, b)
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn add_where(m: M, s: V, w: V) -> V {
            _mm256_add_pd(s, _mm256_and_pd(m, w))
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn and(a: M, b: M) -> M {
            _mm256_and_pd(a, b)
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn bits(m: M) -> u32 {
            _mm256_movemask_pd(m) as u32
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn all(m: M) -> bool {
            bits(m) == 0xF
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn none(m: M) -> bool {
            bits(m) == 0
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn select(m: M, a: V, b: V) -> V {
            _mm256_blendv_pd(b, a, m)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn load(v: [f64; LANES]) -> V {
            _mm256_setr_pd(v[0], v[1], v[2], v[3])
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn store(a: V) -> [f64; LANES] {
            let mut v = [0.0; LANES];
            // SAFETY: LANES f64 into a local array of that size.
            unsafe { _mm256_storeu_pd(v.as_mut_ptr(), a) };
            v
        }
        /// # Safety
        /// Every index is below `field.len()` < 2³¹.
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn gather_raw<const LOADS: bool>(field: &[f32], index: V) -> H {
            let index = _mm256_cvtpd_epi32(index);
            // SAFETY: the caller's guarantee; 4 i32 into a local array of that size.
            unsafe {
                if LOADS {
                    let mut idx = [0i32; 4];
                    _mm_storeu_si128(idx.as_mut_ptr().cast(), index);
                    let v = |l: usize| *field.get_unchecked(idx[l] as usize);
                    _mm_setr_ps(v(0), v(1), v(2), v(3))
                } else {
                    _mm_i32gather_ps::<4>(field.as_ptr(), index)
                }
            }
        }
        /// # Safety
        /// Every index is below `field.len()` < 2³¹.
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn gather<const LOADS: bool>(field: &[f32], index: V) -> V {
            // SAFETY: the caller's guarantee.
            widen(unsafe { gather_raw::<LOADS>(field, index) })
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn widen(h: H) -> V {
            _mm256_cvtps_pd(h)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn unpack(h: H) -> (V, V) {
            let mask = _mm_set1_epi32(crate::composition::MAX_MATERIALS as i32 - 1);
            let bits = _mm_castps_si128(h);
            (
                _mm256_cvtps_pd(_mm_castsi128_ps(_mm_andnot_si128(mask, bits))),
                _mm256_cvtepi32_pd(_mm_and_si128(mask, bits)),
            )
        }
    };
}

/// Eight lanes with AVX-512F: masks are bit masks.
#[cfg(target_arch = "x86_64")]
macro_rules! avx512_lanes {
    () => {
        type V = __m512d;
        type M = __mmask8;
        type H = __m256;
        const LANES: usize = 8;
        f64_lanes!(
            "avx512f,avx2,fma",
            splat _mm512_set1_pd,
            zero _mm512_setzero_pd,
            min _mm512_min_pd,
            max _mm512_max_pd,
            add _mm512_add_pd,
            sub _mm512_sub_pd,
            mul _mm512_mul_pd,
            fmadd _mm512_fmadd_pd,
            floor _mm512_roundscale_pd::<0x09>
        );
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn gt(a: V, b: V) -> M {
            _mm512_cmp_pd_mask::<_CMP_GT_OQ>(a, b)
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn le(a: V, b: V) -> M {
            _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a, b)
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn ne(a: V, b: V) -> M {
            _mm512_cmp_pd_mask::<_CMP_NEQ_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn eq(a: V, b: V) -> M {
            _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a, b)
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn add_where(m: M, s: V, w: V) -> V {
            _mm512_mask_add_pd(s, m, s, w)
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn and(a: M, b: M) -> M {
            a & b
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn bits(m: M) -> u32 {
            u32::from(m)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn all(m: M) -> bool {
            m == 0xFF
        }
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn none(m: M) -> bool {
            m == 0
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn select(m: M, a: V, b: V) -> V {
            _mm512_mask_blend_pd(m, b, a)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn load(v: [f64; LANES]) -> V {
            // SAFETY: LANES f64 from a local array of that size.
            unsafe { _mm512_loadu_pd(v.as_ptr()) }
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn store(a: V) -> [f64; LANES] {
            let mut v = [0.0; LANES];
            // SAFETY: LANES f64 into a local array of that size.
            unsafe { _mm512_storeu_pd(v.as_mut_ptr(), a) };
            v
        }
        /// # Safety
        /// Every index is below `field.len()` < 2³¹.
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        unsafe fn gather_raw<const LOADS: bool>(field: &[f32], index: V) -> H {
            let index = _mm512_cvtpd_epi32(index);
            // SAFETY: the caller's guarantee; 8 i32 into a local array of that size.
            unsafe {
                if LOADS {
                    let mut idx = [0i32; 8];
                    _mm256_storeu_si256(idx.as_mut_ptr().cast(), index);
                    let v = |l: usize| *field.get_unchecked(idx[l] as usize);
                    _mm256_setr_ps(v(0), v(1), v(2), v(3), v(4), v(5), v(6), v(7))
                } else {
                    _mm256_i32gather_ps::<4>(field.as_ptr(), index)
                }
            }
        }
        /// # Safety
        /// Every index is below `field.len()` < 2³¹.
        #[allow(dead_code)] // not every kernel uses it
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        unsafe fn gather<const LOADS: bool>(field: &[f32], index: V) -> V {
            // SAFETY: the caller's guarantee.
            widen(unsafe { gather_raw::<LOADS>(field, index) })
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn widen(h: H) -> V {
            _mm512_cvtps_pd(h)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn unpack(h: H) -> (V, V) {
            let mask = _mm256_set1_epi32(crate::composition::MAX_MATERIALS as i32 - 1);
            let bits = _mm256_castps_si256(h);
            (
                _mm512_cvtps_pd(_mm256_castsi256_ps(_mm256_andnot_si256(mask, bits))),
                _mm512_cvtepi32_pd(_mm256_and_si256(mask, bits)),
            )
        }
    };
}
