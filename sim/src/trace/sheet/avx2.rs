//! Four lanes of f64 (AVX2 + FMA).
//!
//! A ray meets at most two voxels of a line per segment, and they are neighbours. Where the
//! lines are contiguous in memory (the sheet fans out along the grid's fastest axis, as in
//! AP views), each lane reads both with one 8-byte load at the lower of the two
//! (`pair_raw`); otherwise it reads each voxel on its own (`gather_raw`).

sheet_kernel!("avx2,fma", {
    avx2_lanes!();
    /// The raw values at `index` and `index + 1` of each lane (whole numbers in f64).
    ///
    /// # Safety
    /// Every `index + 1` is below `field.len()` < 2³¹.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn pair_raw<const LOADS: bool>(field: &[f32], index: V) -> (H, H) {
        let index = _mm256_cvtpd_epi32(index);
        // SAFETY: the caller's guarantee; 4 i32 into a local array of that size.
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
            _mm256_castps256_ps128(split),
            _mm256_extractf128_ps::<1>(split),
        )
    }
});
