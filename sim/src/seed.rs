//! Seeds: how one user seed becomes many independent random streams.
//!
//! Every stream of the simulation (a view's detector noise, a scatter batch, a dose
//! batch, a calibration frame) is seeded by [`frame_seed`] of the user's seed and the
//! stream's index, so that results depend only on the seed — never on thread count or
//! order — and neighbouring seeds or indices give unrelated streams.

/// The seed of stream `frame` (0: calibration, i + 1: view i, or a batch index) from
/// `seed`: the SplitMix64 finaliser of `seed ^ frame·0x9E3779B97F4A7C15`.
pub fn frame_seed(seed: u64, frame: u64) -> u64 {
    let mut z = seed ^ frame.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
