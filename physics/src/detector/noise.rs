//! Seeded random streams and quantum noise.
//!
//! **Streams.** Every random number belongs to a stream named by (seed, stage, channel,
//! row): a ChaCha8 generator seeded from `seed` and switched to stream
//! `stage·2⁵⁶ + channel·2³² + row`. A row's numbers therefore do not depend on which
//! thread draws them or in what order rows are processed: images are bit-identical for any
//! rayon thread count.
//!
//! **Quantum noise.** A pixel's signal is a compound Poisson sum with mean m and second
//! moment (variance) M₂ (see [`super::response`]). It is sampled as g·Poisson(λ) with
//! g = M₂/m and λ = m²/M₂: non-negative, with exactly the mean m and variance g²λ = M₂.
//! It is exact when every photon contributes the same signal (photon counting,
//! monoenergetic energy integration) and otherwise matches the first two moments.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};
use tomograf_sim::error::{Result, SimError};

/// What a random stream is used for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stage {
    /// Quantum noise of a frame.
    Quanta = 1,
    /// Electronic noise of a frame.
    Electronic = 2,
    /// The fixed gain and offset maps.
    Maps = 3,
}

/// The random stream for (`seed`, `stage`, `channel`, `row`).
pub(crate) fn stream(seed: u64, stage: Stage, channel: usize, row: usize) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(((stage as u64) << 56) | ((channel as u64) << 32) | row as u64);
    rng
}

/// A seed for frame `frame` of a series started from `seed` ([`tomograf_sim::seed::frame_seed`]
/// of `frame + 1`), so frames averaged into a flat or dark field are independent of each
/// other and of `seed`.
pub(crate) fn frame_seed(seed: u64, frame: u64) -> u64 {
    tomograf_sim::seed::frame_seed(seed, frame.wrapping_add(1))
}

/// Draws the compound-Poisson signal of a row of pixels, `mean[i]` and second moment
/// `m2[i]` (both ≥ 0, `m2` > 0 where `mean` > 0; checked by the caller), into `out`.
/// Zero mean gives exactly 0. Consecutive pixels with the same λ share the sampler set-up.
pub(crate) fn sample_row(
    rng: &mut ChaCha8Rng,
    mean: &[f64],
    m2: &[f64],
    out: &mut [f64],
) -> Result<()> {
    let mut cached: Option<(f64, Poisson<f64>)> = None;
    for ((o, &m), &s) in out.iter_mut().zip(mean).zip(m2) {
        if m <= 0.0 {
            *o = 0.0;
            continue;
        }
        let g = s / m;
        let lambda = m / g;
        let p = match cached {
            Some((l, p)) if l == lambda => p,
            _ => {
                let p = Poisson::new(lambda).map_err(|_| {
                    SimError::OutOfRange(format!(
                        "quantum noise cannot be sampled with {lambda:.3e} quanta in a pixel \
                         (mean signal {m:.3e}): the exposure is beyond any real one; lower the \
                         mAs (--mas, [spectrum] mas), or use a noiseless detector \
                         (--detector-model noiseless-csi)"
                    ))
                })?;
                cached = Some((lambda, p));
                p
            }
        };
        *o = g * p.sample(rng);
    }
    Ok(())
}

/// A standard normal deviate.
pub(crate) fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn streams_differ_by_every_coordinate() {
        let first = |s: u64, st: Stage, c: usize, r: usize| stream(s, st, c, r).random::<u64>();
        let base = first(1, Stage::Quanta, 0, 0);
        assert_ne!(base, first(2, Stage::Quanta, 0, 0));
        assert_ne!(base, first(1, Stage::Electronic, 0, 0));
        assert_ne!(base, first(1, Stage::Quanta, 1, 0));
        assert_ne!(base, first(1, Stage::Quanta, 0, 1));
        assert_eq!(base, first(1, Stage::Quanta, 0, 0));
        assert_ne!(frame_seed(5, 0), frame_seed(5, 1));
    }

    #[test]
    fn zero_mean_is_zero_and_huge_lambda_is_an_error() {
        let mut r = stream(0, Stage::Quanta, 0, 0);
        let mut out = [1.0; 2];
        sample_row(&mut r, &[0.0, 0.0], &[0.0, 0.0], &mut out).unwrap();
        assert_eq!(out, [0.0, 0.0]);
        assert!(sample_row(&mut r, &[1e30], &[1e30], &mut out[..1]).is_err());
    }
}
