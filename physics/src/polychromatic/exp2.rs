//! The Taylor series of 2^f that both exponential kernels (portable and AVX-512) use.

/// Coefficients of the Taylor series of 2^f = e^(f·ln 2) to degree 7: (ln 2)ⁿ/n!.
/// Truncation on f ∈ [−½, ½]: < 6e-9 relative, below f32 rounding.
pub(super) const EXP2_TAYLOR: [f32; 8] = {
    let mut c = [0.0f32; 8];
    let (mut term, mut n) = (1.0f64, 0);
    while n < 8 {
        c[n] = term as f32;
        n += 1;
        term *= std::f64::consts::LN_2 / n as f64;
    }
    c
};
