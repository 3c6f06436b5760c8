//! Eight lanes of f64 (AVX-512F; its masks are bit masks).

packet_kernel!("avx512f,avx2,fma", {
    avx512_lanes!();
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
});
