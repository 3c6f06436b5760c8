//! The f64 vector arithmetic and voxel reads the SIMD kernels share ([`super::packet`],
//! [`super::sheet`]), one macro per instruction set (`avx2_lanes!`, `avx512_lanes!`), each
//! expanded inside a kernel's module, where `V` is its vector type.

/// Defines `splat`, `zero`, `min`, `max`, `add`, `sub`, `mul`, `fmadd` (a·b + c) and
/// `floor` (towards −∞, exceptions suppressed) on the kernel's vector type `V`, each
/// `#[inline]` with the instruction set's `$features`, from that set's intrinsics.
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

/// `f64_lanes!` with AVX2 + FMA on four lanes (`__m256d`), and `gather::<LOADS>`: the f32
/// values at f64-valued voxel indices, widened to f64, read with four scalar loads
/// (`LOADS`) or one `vgatherdps` ([`super::packet::scalar_voxel_loads`]).
#[cfg(target_arch = "x86_64")]
macro_rules! avx2_lanes {
    () => {
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
        /// # Safety
        /// Every index is below `field.len()` < 2³¹.
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn gather<const LOADS: bool>(field: &[f32], index: V) -> V {
            let index = _mm256_cvtpd_epi32(index);
            // SAFETY: the caller's guarantee; 4 i32 into a local array of that size.
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
    };
}

/// `f64_lanes!` with AVX-512F on eight lanes (`__m512d`), and `gather::<LOADS>` as for
/// `avx2_lanes!`, with eight scalar loads or one eight-lane `vgatherdps`.
#[cfg(target_arch = "x86_64")]
macro_rules! avx512_lanes {
    () => {
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
        /// # Safety
        /// Every index is below `field.len()` < 2³¹.
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        unsafe fn gather<const LOADS: bool>(field: &[f32], index: V) -> V {
            let index = _mm512_cvtpd_epi32(index);
            // SAFETY: the caller's guarantee; 8 i32 into a local array of that size.
            unsafe {
                let g = if LOADS {
                    let mut idx = [0i32; 8];
                    _mm256_storeu_si256(idx.as_mut_ptr().cast(), index);
                    let v = |l: usize| *field.get_unchecked(idx[l] as usize);
                    _mm256_setr_ps(v(0), v(1), v(2), v(3), v(4), v(5), v(6), v(7))
                } else {
                    _mm256_i32gather_ps::<4>(field.as_ptr(), index)
                };
                _mm512_cvtps_pd(g)
            }
        }
    };
}
