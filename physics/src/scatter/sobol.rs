//! Randomised quasi-Monte Carlo for one batch of histories: history `j` of a batch takes
//! point `j` of an Owen-scrambled Sobol sequence (Burley's hash-based scrambling,
//! `sobol_burley`), scrambled by the batch's seed. Each point is uniform on the unit cube,
//! so every estimator stays unbiased, and batches are independent replicates (their spread
//! still estimates the error); within a batch of 2^k histories every dimension is
//! stratified into 2^k strata as a Latin hypercube is, and the leading pairs of dimensions
//! jointly (2^k points in every 2-D elementary box of the pairs (0, 1), (0, 2), (1, 2)).

use rand::{Rng, RngCore};

/// Dimensions of a point: the history's start (pixel row, pixel column, first-collision
/// depth, energy, sub-pixel row and column) and its first uniforms after that.
pub const START: usize = 6;

/// Draws after the start taken from the sequence: the first scatter's (Compton or
/// Rayleigh, its angle's first trial, the azimuth) and the next flight's first.
pub const FIRST_SCATTER_DRAWS: usize = 8;

/// The Sobol points of one batch.
#[derive(Debug, Clone, Copy)]
pub struct SobolBatch {
    seed: u32,
}

impl SobolBatch {
    /// A batch scrambled by `seed`.
    pub fn new<R: Rng>(rng: &mut R) -> Self {
        Self {
            seed: rng.next_u32(),
        }
    }

    /// Coordinate `dim` of history `j`'s point, in [0, 1), with the bits below the
    /// sequence's 23 filled from `rng` so that it is uniform to double precision.
    pub fn at<R: Rng>(&self, j: usize, dim: usize, rng: &mut R) -> f64 {
        let s = f64::from(sobol_burley::sample(j as u32, dim as u32, self.seed));
        s + rng.random::<f64>() * (1.0 / 8_388_608.0)
    }

    /// History `j`'s start: [pixel row, pixel column, depth, energy, sub-pixel row,
    /// sub-pixel column].
    pub fn start<R: Rng>(&self, j: usize, rng: &mut R) -> [f64; START] {
        std::array::from_fn(|d| self.at(j, d, rng))
    }
}

/// A random stream whose first `n` draws are history `j`'s Sobol coordinates `START..`,
/// then `inner`'s: the first scatter (process, angle, azimuth) and the next flight take
/// the sequence's coordinates as far as they go. Without a batch it is `inner` itself,
/// draw for draw.
pub struct Prefixed<'a, R: RngCore> {
    batch: Option<SobolBatch>,
    j: usize,
    next: usize,
    end: usize,
    inner: &'a mut R,
}

impl<'a, R: RngCore> Prefixed<'a, R> {
    /// History `j`'s stream: `n` draws of `batch`'s point (none without one), then `inner`.
    pub fn new(batch: Option<SobolBatch>, j: usize, n: usize, inner: &'a mut R) -> Self {
        let n = if batch.is_some() { n } else { 0 };
        Self {
            batch,
            j,
            next: START,
            end: START + n,
            inner,
        }
    }
}

impl<R: RngCore> RngCore for Prefixed<'_, R> {
    fn next_u32(&mut self) -> u32 {
        if self.batch.is_none() {
            return self.inner.next_u32();
        }
        // With a batch, a 32-bit draw is the top of a 64-bit one, prefix or not.
        (self.next_u64() >> 32) as u32
    }

    fn next_u64(&mut self) -> u64 {
        let Some(batch) = self.batch.filter(|_| self.next < self.end) else {
            return self.inner.next_u64();
        };
        let s = sobol_burley::sample(self.j as u32, self.next as u32, batch.seed);
        self.next += 1;
        // 23 bits from the sequence on top, the rest from the inner stream.
        let top = (f64::from(s) * 8_388_608.0) as u64;
        (top << 41) | (self.inner.next_u64() >> 23)
    }

    fn fill_bytes(&mut self, dst: &mut [u8]) {
        self.inner.fill_bytes(dst)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// A batch of 256: each start coordinate takes each of the 256 strata of [0, 1) once,
    /// and the pairs (row, column), (row, depth) and (column, depth) each of the 16 × 16
    /// boxes once; another batch's seed gives other points.
    #[test]
    fn a_batch_is_stratified_alone_and_in_pairs() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for _ in 0..3 {
            let b = SobolBatch::new(&mut rng);
            let pts: Vec<[f64; START]> = (0..256).map(|j| b.start(j, &mut rng)).collect();
            for d in 0..START {
                let mut hit = [0u8; 256];
                for p in &pts {
                    assert!((0.0..1.0).contains(&p[d]));
                    hit[(p[d] * 256.0) as usize] += 1;
                }
                assert!(hit.iter().all(|&h| h == 1), "dimension {d}");
            }
            for (x, y) in [(0, 1), (0, 2), (1, 2)] {
                let mut hit = [0u8; 256];
                for p in &pts {
                    hit[(p[x] * 16.0) as usize * 16 + (p[y] * 16.0) as usize] += 1;
                }
                assert!(hit.iter().all(|&h| h == 1), "dimensions {x}, {y}");
            }
        }
        let (a, b) = (SobolBatch::new(&mut rng), SobolBatch::new(&mut rng));
        assert_ne!(a.at(0, 0, &mut rng), b.at(0, 0, &mut rng));
    }

    /// The prefixed stream gives the history's next coordinates (to the sequence's 23 bits)
    /// for its first `n` draws, then the inner stream's own.
    #[test]
    fn the_prefix_comes_from_the_sequence_then_the_stream() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let b = SobolBatch::new(&mut rng);
        let mut inner = ChaCha8Rng::seed_from_u64(5);
        let mut copy = inner.clone();
        let mut s = Prefixed::new(Some(b), 7, 3, &mut inner);
        for k in 0..3 {
            let want = f64::from(sobol_burley::sample(7, (START + k) as u32, b.seed));
            let got: f64 = s.random();
            assert!(
                got >= want && got < want + 1.0 / 8_388_608.0,
                "draw {k}: {got} {want}"
            );
        }
        // Three inner draws filled the low bits; the next is the inner stream's fourth.
        for _ in 0..3 {
            copy.next_u64();
        }
        assert_eq!(s.next_u64(), copy.next_u64());
    }
}
