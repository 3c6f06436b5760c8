//! Eight lanes of f64 (AVX-512F; its comparisons give bit masks). Reads voxels as the AVX2
//! kernel does (`super::avx2`), eight lanes at a time; a pair's index is converted to 64
//! bits by one instruction (AVX-512DQ's `vcvttpd2qq`, where the conversion to 32 bits takes
//! two) and the pairs gathered by it (`vpgatherqq`): 3–4 % faster (docs/projector.md,
//! "Session 30"). Every CPU with AVX-512 that renders here has DQ ([`crate::trace::packet::kernel`]).

sheet_kernel!("avx512f,avx512dq,avx2,fma", {
    avx512_lanes!();
    /// The raw values at `index` and `index + 1` of each lane (whole numbers in f64).
    ///
    /// # Safety
    /// Every `index + 1` is below `field.len()` < 2³¹.
    #[inline]
    #[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
    unsafe fn pair_raw<const LOADS: bool>(field: &[f32], index: V) -> (H, H) {
        // SAFETY: the caller's guarantee; 8 i32 into a local array of that size.
        let both = unsafe {
            if LOADS {
                let index = _mm512_cvtpd_epi32(index);
                let mut idx = [0i32; 8];
                _mm256_storeu_si256(idx.as_mut_ptr().cast(), index);
                let v = |l: usize| {
                    field
                        .as_ptr()
                        .add(idx[l] as usize)
                        .cast::<i64>()
                        .read_unaligned()
                };
                _mm512_setr_epi64(v(0), v(1), v(2), v(3), v(4), v(5), v(6), v(7))
            } else {
                // The indices are whole numbers, so truncation is exact.
                _mm512_i64gather_epi64::<4>(_mm512_cvttpd_epi64(index), field.as_ptr().cast())
            }
        };
        // [l0 u0 l1 u1 … l7 u7] → [l0 … l7 | u0 … u7], by one `vpermps`, written out:
        // given `_mm512_permutexvar_ps`, LLVM may split the shuffle into its two halves
        // (`vpmovqd` for the evens, `vshufps` and `vpermpd` for the odds), three more
        // instructions on the two ports that execute 512-bit operations (docs/projector.md,
        // "Session 30").
        let order = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 1, 3, 5, 7, 9, 11, 13, 15);
        let split: __m512d;
        // SAFETY: a register-to-register permutation; AVX-512F is enabled (the function's
        // target features).
        unsafe {
            std::arch::asm!(
                "vpermps {split}, {order}, {both}",
                split = lateout(zmm_reg) split,
                order = in(zmm_reg) order,
                both = in(zmm_reg) both,
                options(pure, nomem, nostack, preserves_flags),
            );
        }
        (
            _mm256_castpd_ps(_mm512_castpd512_pd256(split)),
            _mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(split)),
        )
    }
});
