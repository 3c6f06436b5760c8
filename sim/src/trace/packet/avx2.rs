//! Four lanes of f64 (AVX2 + FMA).

packet_kernel!("avx2,fma", {
    avx2_lanes!();
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
});
