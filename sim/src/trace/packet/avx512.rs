//! Eight lanes of f64 (AVX-512F; its masks are bit masks).

packet_kernel!("avx512f,avx2,fma", 8, __m512d, __mmask8, {
    avx512_lanes!();
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn gt(a: V, b: V) -> M {
        _mm512_cmp_pd_mask::<_CMP_GT_OQ>(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn le(a: V, b: V) -> M {
        _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a, b)
    }
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
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn add_where(m: M, s: V, w: V) -> V {
        _mm512_mask_add_pd(s, m, s, w)
    }
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn and(a: M, b: M) -> M {
        a & b
    }
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn all(m: M) -> bool {
        m == 0xFF
    }
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
    // Lanes 0, 2, 4, 6: the first column of a 4-row × 2-column tile, one per row (the
    // second column's voxels mostly share those cache lines).
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn prefetch(field: &[f32], index: V) {
        let mut idx = [0i32; 8];
        // SAFETY: 8 i32 into a local array of that size.
        unsafe { _mm256_storeu_si256(idx.as_mut_ptr().cast(), _mm512_cvtpd_epi32(index)) };
        for l in [0, 2, 4, 6] {
            prefetch_at(field, idx[l]);
        }
    }
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn gather_packed(field: &[f32], index: V) -> (V, V) {
        // SAFETY: as for `gather`.
        let g = unsafe {
            _mm256_i32gather_epi32::<4>(field.as_ptr().cast(), _mm512_cvtpd_epi32(index))
        };
        let mask = _mm256_set1_epi32(LABEL_MASK);
        let rho = _mm256_castsi256_ps(_mm256_andnot_si256(mask, g));
        (
            _mm512_cvtps_pd(rho),
            _mm512_cvtepi32_pd(_mm256_and_si256(mask, g)),
        )
    }
});
