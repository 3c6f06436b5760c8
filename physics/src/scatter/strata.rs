//! Latin hypercube sampling over one batch of Monte Carlo histories: for each of a few
//! dimensions of a history's start (the pixel it is aimed at, its energy, the depth of its
//! first collision), the batch's `n` histories draw one each from the `n` equal strata of
//! [0, 1), in an order shuffled per dimension. Every draw is still uniform on [0, 1), so
//! any estimator stays unbiased; what the batch loses is the variance of each dimension's
//! main effect — for forced detection, chiefly how many histories happen to collide deep in
//! the patient, near the panel, where a site scores e^τ times more than near the entrance.

use rand::Rng;
use rand::seq::SliceRandom;

/// Dimensions stratified.
pub const DIMENSIONS: usize = 3;

/// The shuffled strata of one batch.
#[derive(Debug, Clone)]
pub struct Strata {
    order: [Vec<u32>; DIMENSIONS],
}

impl Strata {
    /// Strata for `n` histories, shuffled with `rng`.
    pub fn new<R: Rng>(n: usize, rng: &mut R) -> Self {
        let order = std::array::from_fn(|_| {
            let mut v: Vec<u32> = (0..n as u32).collect();
            v.shuffle(rng);
            v
        });
        Self { order }
    }

    /// History `j`'s uniforms in [0, 1), one per dimension: a uniform point of its stratum
    /// in each.
    pub fn draw<R: Rng>(&self, j: usize, rng: &mut R) -> [f64; DIMENSIONS] {
        let n = self.order[0].len() as f64;
        std::array::from_fn(|d| (f64::from(self.order[d][j]) + rng.random::<f64>()) / n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn each_dimension_draws_once_from_every_stratum() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let n = 256;
        let s = Strata::new(n, &mut rng);
        let draws: Vec<[f64; DIMENSIONS]> = (0..n).map(|j| s.draw(j, &mut rng)).collect();
        for d in 0..DIMENSIONS {
            let mut hit = vec![0; n];
            for x in &draws {
                assert!((0.0..1.0).contains(&x[d]));
                hit[(x[d] * n as f64) as usize] += 1;
            }
            assert!(hit.iter().all(|&h| h == 1), "dimension {d}: {hit:?}");
        }
        // The dimensions are shuffled independently (not the same order).
        let stratum = |j: usize, d: usize| (draws[j][d] * n as f64) as usize;
        assert!((0..n).any(|j| stratum(j, 0) != stratum(j, 1)));
        assert!((0..n).any(|j| stratum(j, 1) != stratum(j, 2)));
    }
}
