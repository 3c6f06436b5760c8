//! Four lanes of f64 (AVX2 + FMA).

packet_kernel!("avx2,fma", 4, __m256d, __m256d, {
    avx2_lanes!();
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn gt(a: V, b: V) -> M {
        _mm256_cmp_pd::<_CMP_GT_OQ>(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn le(a: V, b: V) -> M {
        _mm256_cmp_pd::<_CMP_LE_OQ>(a, b)
    }
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
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn add_where(m: M, s: V, w: V) -> V {
        _mm256_add_pd(s, _mm256_and_pd(m, w))
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn and(a: M, b: M) -> M {
        _mm256_and_pd(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn all(m: M) -> bool {
        _mm256_movemask_pd(m) == 0xF
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn none(m: M) -> bool {
        _mm256_movemask_pd(m) == 0
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
    // Every lane: a tile of 4 rows × 1 column.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn prefetch(field: &[f32], index: V) {
        let mut idx = [0i32; 4];
        // SAFETY: 4 i32 into a local array of that size.
        unsafe { _mm_storeu_si128(idx.as_mut_ptr().cast(), _mm256_cvtpd_epi32(index)) };
        for i in idx {
            prefetch_at(field, i);
        }
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn gather_packed(field: &[f32], index: V) -> (V, V) {
        // SAFETY: as for `gather`.
        let g =
            unsafe { _mm_i32gather_epi32::<4>(field.as_ptr().cast(), _mm256_cvtpd_epi32(index)) };
        let mask = _mm_set1_epi32(LABEL_MASK);
        let rho = _mm_castsi128_ps(_mm_andnot_si128(mask, g));
        (
            _mm256_cvtps_pd(rho),
            _mm256_cvtepi32_pd(_mm_and_si128(mask, g)),
        )
    }
});
