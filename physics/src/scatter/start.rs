//! Where each history starts: the detector pixel it is aimed at (drawn ∝ the pixel's
//! exposure factor, [`crate::polychromatic::pixel_exposure_factor`]), a uniform point in
//! that pixel, and the uniforms its energy and its forced first collision's depth come
//! from — drawn independently (the analog engine), from a batch's Latin hypercube
//! ([`super::strata`]) or from its Sobol points ([`super::sobol`]).

use super::Sampler;
use super::sobol::{FIRST_SCATTER_DRAWS, Prefixed, SobolBatch};
use super::strata::Strata;
use crate::polychromatic::pixel_exposure_factor;
use rand::{Rng, RngCore};
use tomograf_sim::geometry::View;

/// The exposure of the pixels a view's histories are aimed at, cumulated.
#[derive(Debug, Clone)]
pub struct Aim {
    /// Cumulative exposure factor over the pixels, row-major.
    cumulative: Vec<f64>,
    /// The cumulative exposure at each row's end.
    row_end: Vec<f64>,
    rows: usize,
    cols: usize,
}

impl Aim {
    /// The pixels of `view`.
    pub fn new(view: &View) -> Self {
        let mut cumulative = Vec::with_capacity(view.rows * view.cols);
        let mut total = 0.0;
        for r in 0..view.rows {
            for c in 0..view.cols {
                total += pixel_exposure_factor(view, r, c);
                cumulative.push(total);
            }
        }
        let row_end = (0..view.rows)
            .map(|r| cumulative[(r + 1) * view.cols - 1])
            .collect();
        Self {
            cumulative,
            row_end,
            rows: view.rows,
            cols: view.cols,
        }
    }

    /// The sum of the pixels' exposure factors.
    pub fn total(&self) -> f64 {
        *self.cumulative.last().expect("a view has pixels")
    }

    /// The pixel (row-major index) at fraction `u` of the cumulative exposure.
    fn pixel(&self, u: f64) -> usize {
        let u = u * self.total();
        self.cumulative
            .partition_point(|&c| c <= u)
            .min(self.cumulative.len() - 1)
    }

    /// The pixel whose row is at fraction `u_row` of the cumulative exposure and whose
    /// column at fraction `u_col` of that row's.
    fn pixel_by_row(&self, u_row: f64, u_col: f64) -> usize {
        let u = u_row * self.total();
        let row = self.row_end.partition_point(|&c| c <= u).min(self.rows - 1);
        let lo = if row == 0 { 0.0 } else { self.row_end[row - 1] };
        let u = lo + u_col * (self.row_end[row] - lo);
        let seg = &self.cumulative[row * self.cols..(row + 1) * self.cols];
        row * self.cols + seg.partition_point(|&c| c <= u).min(self.cols - 1)
    }
}

/// One history's start.
#[derive(Debug, Clone, Copy)]
pub struct Start {
    /// The pixel aimed at, row-major.
    pub pixel: usize,
    /// The point within it: (row, column) offsets in [0, 1) from its corner.
    pub within: (f64, f64),
    /// The uniform the energy is drawn from.
    pub u_energy: f64,
    /// The uniform the forced first collision's depth is drawn from (NaN: analog).
    pub u_depth: f64,
}

/// How one batch draws its histories' starts.
#[derive(Debug, Clone)]
pub enum BatchStarts {
    /// Independent draws, the first flight analog.
    Analog,
    /// A Latin hypercube over the batch.
    Strata(Strata),
    /// The batch's Sobol points.
    Sobol(SobolBatch),
}

impl BatchStarts {
    /// The starts of a batch of `n` (`analog`: the engine's ablation, whatever `sampler`).
    pub fn new<R: Rng>(analog: bool, sampler: Sampler, n: usize, rng: &mut R) -> Self {
        match (analog, sampler) {
            (true, _) => Self::Analog,
            (false, Sampler::LatinHypercube) => Self::Strata(Strata::new(n, rng)),
            (false, Sampler::Sobol) => Self::Sobol(SobolBatch::new(rng)),
        }
    }

    /// History `j`'s random stream after its start: the first scatter's draws from the
    /// batch's Sobol point when it has one, then (or else) `rng`, draw for draw.
    pub fn stream<'a, R: RngCore>(&self, j: usize, rng: &'a mut R) -> Prefixed<'a, R> {
        let batch = match self {
            Self::Sobol(b) => Some(*b),
            _ => None,
        };
        Prefixed::new(batch, j, FIRST_SCATTER_DRAWS, rng)
    }

    /// History `j`'s start among `aim`'s pixels.
    pub fn draw<R: Rng>(&self, aim: &Aim, j: usize, rng: &mut R) -> Start {
        match self {
            Self::Sobol(b) => {
                let s = b.start(j, rng);
                Start {
                    pixel: aim.pixel_by_row(s[0], s[1]),
                    within: (s[4], s[5]),
                    u_energy: s[3],
                    u_depth: s[2],
                }
            }
            Self::Strata(_) | Self::Analog => {
                let [u_pixel, u_energy, u_depth] = match self {
                    Self::Strata(s) => s.draw(j, rng),
                    // No first-collision depth: the first flight is analog.
                    _ => [rng.random(), rng.random(), f64::NAN],
                };
                let pixel = aim.pixel(u_pixel);
                let within = (rng.random::<f64>(), rng.random::<f64>());
                Start {
                    pixel,
                    within,
                    u_energy,
                    u_depth,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use tomograf_sim::geometry::ViewBeam;

    /// Both pixel draws follow the exposure: over a 4 × 6 panel close to the source (so the
    /// corners get less than the centre), the share of draws each pixel gets is its share of
    /// the exposure, by the row-major index and by row then column alike.
    #[test]
    fn pixels_are_drawn_as_their_exposure() {
        let view = View {
            beam: ViewBeam::Cone {
                source: DVec3::new(0.0, 0.0, -100.0),
            },
            detector_origin: DVec3::new(-60.0, -40.0, 50.0),
            u: DVec3::new(20.0, 0.0, 0.0),
            v: DVec3::new(0.0, 20.0, 0.0),
            rows: 4,
            cols: 6,
        };
        let aim = Aim::new(&view);
        let n = 240_000;
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for by_row in [false, true] {
            let mut hits = [0usize; 24];
            for _ in 0..n {
                let p = if by_row {
                    aim.pixel_by_row(rng.random(), rng.random())
                } else {
                    aim.pixel(rng.random())
                };
                hits[p] += 1;
            }
            let mut prev = 0.0;
            for (p, &h) in hits.iter().enumerate() {
                let share = (aim.cumulative[p] - prev) / aim.total();
                prev = aim.cumulative[p];
                let sd = (share * (1.0 - share) / n as f64).sqrt();
                let got = h as f64 / n as f64;
                assert!(
                    (got - share).abs() < 5.0 * sd,
                    "pixel {p}: {got} against {share}"
                );
            }
            assert!(hits[0] < hits[8], "a corner gets less than the centre");
        }
    }
}
