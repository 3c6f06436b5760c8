//! The per-pixel arithmetic of [`super::SpectralIntegrator`]: optical depth per energy
//! bin, transmission, and each detector channel's two moments, a row of pixels at a time.
//! One body compiled per instruction set (AVX-512, AVX2 + FMA, baseline x86-64), chosen at
//! run time; AVX-512 has its own forms of the inner loops ([`super::avx512`]).

#[cfg(target_arch = "x86_64")]
use super::avx512;
use super::exp2::EXP2_TAYLOR;
use super::{BIN_BLOCK, SpectralIntegrator};

/// One image row being filled: per channel, the row of means and of second moments.
pub(super) struct RowOut<'a> {
    pub(super) mean: Vec<&'a mut [f64]>,
    pub(super) second: Vec<&'a mut [f64]>,
}

impl RowOut<'_> {
    /// Pixel `c` sees the open field: each channel's unattenuated moments `open[ch]`
    /// (mean, second) times the pixel's exposure factor `f`.
    pub(super) fn set_open(&mut self, c: usize, open: &[(f64, f64)], f: f64) {
        for (ch, &(m1, m2)) in open.iter().enumerate() {
            self.mean[ch][c] = m1 * f;
            self.second[ch][c] = m2 * f;
        }
    }
}

/// A row of pixels: for pixel `c`, the transmission per bin behind thicknesses
/// `t[c·k..(c+1)·k]` (g/cm², k materials), each channel's two dot products with it, times
/// `factors[c]`, into `out`; pixels with nothing in the way get the open field. One body
/// compiled for AVX-512, AVX2 and baseline x86-64, chosen at run time once per row (results
/// agree to rounding). Where the CPU has FMA, every multiply-add is fused. `att`: scratch
/// of `padded_bins` values.
///
/// Precision: optical depths, exponentials and per-lane partial sums are f32 (16 bins per
/// AVX-512 register, twice the f64 rate), the lanes' sums are added in f64. An optical
/// depth τ is then known to ≈ τ·2⁻²⁴ and its transmission to ≈ (τ + 1)·2⁻²³ relative:
/// ≈ 1e-6 at τ = 10 (transmission 5e-5), far below the quantum noise of any exposure the
/// detector models (1/√N ≥ 1e-4 for N ≤ 10⁸ photons) and the tabulated attenuation's own
/// uncertainty (~1 %). The monochromatic projector stays f64 throughout.
#[multiversion::multiversion(targets("x86_64+avx512f+avx2+fma", "x86_64+avx2+fma"))]
pub(super) fn row_kernel(
    integrator: &SpectralIntegrator,
    t: &[f64],
    factors: &[f64],
    att: &mut [f32],
    out: &mut RowOut,
) {
    let avx512 = multiversion::target::target_cfg_f!(target_feature = "avx512f");
    let fma = multiversion::target::target_cfg_f!(target_feature = "fma");
    match (avx512, fma) {
        (true, _) => row_body::<true, true>(integrator, t, factors, att, out),
        (false, true) => row_body::<true, false>(integrator, t, factors, att, out),
        (false, false) => row_body::<false, false>(integrator, t, factors, att, out),
    }
}

/// The body of [`row_kernel`]; `FMA`: fuse multiply-adds (only where the CPU has FMA,
/// which is otherwise emulated in software); `AVX512`: the inner loops of
/// [`super::avx512`] (only where the CPU has AVX-512).
#[inline(always)]
fn row_body<const FMA: bool, const AVX512: bool>(
    integrator: &SpectralIntegrator,
    t: &[f64],
    factors: &[f64],
    att: &mut [f32],
    out: &mut RowOut,
) {
    let k = integrator.materials.len();
    debug_assert_eq!(t.len(), k * factors.len());
    let (mass_att, bins) = (&integrator.mass_att[..], integrator.padded_bins);
    for (c, &f) in factors.iter().enumerate() {
        let t = &t[c * k..(c + 1) * k];
        if t.iter().all(|&x| x == 0.0) {
            // Nothing in the way (air): the open field.
            out.set_open(c, &integrator.open, f);
            continue;
        }
        transmission_on::<FMA, AVX512>(mass_att, bins, t, att);
        for (ch, channel) in integrator.channels.iter().enumerate() {
            let (m1, m2) = dots_on::<FMA, AVX512>(&channel.first, &channel.second, att);
            out.mean[ch][c] = m1 * channel.scale.0 * f;
            out.second[ch][c] = m2 * channel.scale.1 * f;
        }
    }
}

/// [`transmission`], by [`avx512::transmission`] where `AVX512` (and the materials fit
/// its registers).
#[inline(always)]
fn transmission_on<const FMA: bool, const AVX512: bool>(
    mass_att: &[f32],
    bins: usize,
    t: &[f64],
    att: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    if AVX512 && t.len() <= avx512::MAX_MATERIALS {
        // SAFETY: `AVX512` is set only in the kernel's AVX-512 build, which runs only
        // where the CPU has AVX-512.
        unsafe { avx512::transmission(mass_att, bins, t, att) };
        return;
    }
    transmission::<FMA>(mass_att, bins, t, att);
}

/// [`dots`], by [`avx512::dots`] where `AVX512`.
#[inline(always)]
fn dots_on<const FMA: bool, const AVX512: bool>(a: &[f32], b: &[f32], x: &[f32]) -> (f64, f64) {
    #[cfg(target_arch = "x86_64")]
    if AVX512 {
        // SAFETY: as for `transmission_on`.
        return unsafe { avx512::dots(a, b, x) };
    }
    dots::<FMA>(a, b, x)
}

/// The transmission per bin behind thicknesses `t` (g/cm², one per material) into `att`,
/// with `mass_att` material-major over `bins` padded bins. `FMA`: as for [`row_body`].
#[inline(always)]
fn transmission<const FMA: bool>(mass_att: &[f32], bins: usize, t: &[f64], att: &mut [f32]) {
    // Two passes over the bins: optical depths material by material, then every
    // exponential — no branch between bins, so their latency chains overlap. Plain loops
    // over contiguous bins, which the compiler vectorises whole (the bins are padded to
    // whole blocks). Each bin's arithmetic is the same in any pass order.
    att.fill(0.0);
    for (m, &tm) in t.iter().enumerate() {
        if tm != 0.0 {
            let tm = tm as f32;
            for (a, &u) in att.iter_mut().zip(&mass_att[m * bins..(m + 1) * bins]) {
                *a = madd::<FMA>(tm, u, *a);
            }
        }
    }
    for a in att.iter_mut() {
        *a = exp_neg::<FMA>(*a);
    }
}

/// a·b + c, fused when `FMA`.
#[inline(always)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// (Σ a·x, Σ b·x) over whole blocks of [`BIN_BLOCK`] (the padded bins): one f32 partial
/// sum per lane (each adds at most a few dozen positive terms), the lanes added in f64 as
/// a tree (a chain of 16 dependent adds would cost more than the bins themselves at few
/// bins). The order is fixed, so results are the same on every run.
#[inline(always)]
fn dots<const FMA: bool>(a: &[f32], b: &[f32], x: &[f32]) -> (f64, f64) {
    let (mut sa, mut sb) = ([0.0f32; BIN_BLOCK], [0.0f32; BIN_BLOCK]);
    for ((a, b), x) in a
        .chunks_exact(BIN_BLOCK)
        .zip(b.chunks_exact(BIN_BLOCK))
        .zip(x.chunks_exact(BIN_BLOCK))
    {
        for l in 0..BIN_BLOCK {
            sa[l] = madd::<FMA>(a[l], x[l], sa[l]);
            sb[l] = madd::<FMA>(b[l], x[l], sb[l]);
        }
    }
    // The barrier keeps the vectoriser from shaping the lanes' loop after the tree below
    // (it would otherwise build the 16 lanes from 2-lane pieces, several times slower).
    let (sa, sb) = std::hint::black_box((sa, sb));
    (lane_sum(&sa), lane_sum(&sb))
}

/// The sum of a block's lanes, in f64, as a tree.
#[inline(always)]
fn lane_sum(s: &[f32; BIN_BLOCK]) -> f64 {
    let mut h: [f64; BIN_BLOCK / 2] =
        std::array::from_fn(|l| f64::from(s[l]) + f64::from(s[l + BIN_BLOCK / 2]));
    let mut n = BIN_BLOCK / 2;
    while n > 1 {
        n /= 2;
        for l in 0..n {
            h[l] += h[l + n];
        }
    }
    h[0]
}

/// e^(−x) for x ≥ 0 in f32, branch-free so that loops over it vectorise: x·log₂e split
/// into the nearest integer k and a remainder f in [−½, ½], 2^f from its Taylor series
/// ([`EXP2_TAYLOR`]), k put in the exponent. The rounding of x·log₂e adds ≈ x·2⁻²⁴
/// relative. Results below 2^−126 (x > 87.3) are flushed to 0, like a transmission that
/// underflows; never NaN. `FMA`: fused multiply-adds (see [`row_kernel`]).
#[inline(always)]
pub(super) fn exp_neg<const FMA: bool>(x: f32) -> f32 {
    let y = -x.clamp(0.0, 200.0) * std::f32::consts::LOG2_E; // in [−289, 0]
    let k = y.round_ties_even();
    let f = y - k;
    let mut p = EXP2_TAYLOR[7];
    for &c in EXP2_TAYLOR[..7].iter().rev() {
        p = madd::<FMA>(p, f, c);
    }
    // 2^k through the exponent field; biased exponents ≤ 0 give +0.0.
    let biased = (k + 127.0).max(0.0);
    let scale = f32::from_bits((biased + 8_388_608.0).to_bits() << 23);
    p * scale
}

#[cfg(test)]
mod tests {
    use super::exp_neg;

    /// Against f64's exp on [0, 87] (where f32 holds the result as a normal number): the
    /// relative error stays within (x + 2)·2⁻²³, the bound [`exp_neg`] states (input
    /// rounding x·2⁻²⁴ twice over, plus the polynomial's and the product's rounding).
    #[test]
    fn fast_exp_matches_std_exp() {
        let mut worst = 0.0f64;
        for i in 0..200_000 {
            let x = i as f32 * 0.000_435; // 0 … 87
            let b = (-f64::from(x)).exp();
            for e in [exp_neg::<false>, exp_neg::<true>] {
                let rel = ((f64::from(e(x)) - b) / b).abs();
                worst = worst.max(rel / ((f64::from(x) + 2.0) * 2f64.powi(-23)));
            }
        }
        assert!(worst < 1.0, "worst error {worst} × the stated bound");
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx512f") {
            // The AVX-512 form: the same polynomial, so the same values where the result
            // is a normal number (x ≤ 87), and the same bound.
            let mut x: Vec<f32> = (0..200_000).map(|i| i as f32 * 0.000_435).collect();
            let portable: Vec<f32> = x.iter().map(|&v| exp_neg::<true>(v)).collect();
            // SAFETY: the CPU has AVX-512 (checked above).
            unsafe { super::super::avx512::exp_neg_in_place(&mut x) };
            assert_eq!(x, portable);
            let mut edge = [
                0.0,
                100.0,
                f32::INFINITY,
                87.0,
                1e30,
                0.5,
                2.0,
                3.0,
                4.0,
                5.0,
                6.0,
                7.0,
                8.0,
                9.0,
                10.0,
                11.0,
            ];
            // SAFETY: as above.
            unsafe { super::super::avx512::exp_neg_in_place(&mut edge) };
            assert_eq!(edge[0], 1.0);
            assert!(edge[1] < 1e-43 && edge[1] >= 0.0, "e^-100 gave {}", edge[1]);
            assert_eq!(edge[2], 0.0);
            assert_eq!(edge[4], 0.0);
            assert!(edge[3] > 0.0 && edge[3].is_finite());
        }
        for e in [exp_neg::<false>, exp_neg::<true>] {
            assert_eq!(e(0.0), 1.0);
            assert_eq!(e(100.0), 0.0);
            assert_eq!(e(f32::INFINITY), 0.0);
            assert!(e(87.0) > 0.0 && e(87.0).is_finite());
        }
    }

    /// The AVX-512 transmission and dot products give the portable (FMA) forms' values
    /// bit for bit: the same operations in the same order, on optical depths where the
    /// transmission is a normal f32.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_loops_equal_portable_ones() {
        if !std::is_x86_feature_detected!("avx512f") {
            return;
        }
        use super::super::avx512;
        use super::{dots, transmission};
        let (k, bins) = (5, 112);
        // A fixed pseudo-random sequence in [0, 1).
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mass_att: Vec<f32> = (0..k * bins).map(|_| 5.0 * next()).collect();
        let w: Vec<f32> = (0..2 * bins).map(|_| next()).collect();
        for trial in 0..200 {
            // Up to 3 g/cm² per material (τ ≤ 75), some materials absent.
            let t: Vec<f64> = (0..k)
                .map(|m| {
                    if (trial + m) % 3 == 0 {
                        0.0
                    } else {
                        3.0 * f64::from(next())
                    }
                })
                .collect();
            let (mut a, mut b) = (vec![0.0f32; bins], vec![0.0f32; bins]);
            transmission::<true>(&mass_att, bins, &t, &mut a);
            // SAFETY: the CPU has AVX-512 (checked above).
            unsafe { avx512::transmission(&mass_att, bins, &t, &mut b) };
            assert_eq!(a, b, "transmission, thicknesses {t:?}");
            let portable = dots::<true>(&w[..bins], &w[bins..], &a);
            // SAFETY: as above.
            let fast = unsafe { avx512::dots(&w[..bins], &w[bins..], &a) };
            assert_eq!(portable, fast, "dot products, thicknesses {t:?}");
        }
    }
}
