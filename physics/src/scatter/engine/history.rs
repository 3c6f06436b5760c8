//! One photon history: the flights, collisions and forced-detection scoring of a photon
//! from the source (or of a branch of a split history), with implicit capture and Russian
//! roulette.

use super::ScatterEngine;
use crate::scatter::Sampler;
use crate::scatter::detection_grid::DetectionGrid;
use crate::scatter::estimator::{CellCheck, ScoreGrid, Tally, score};
use crate::scatter::transport::E_CUTOFF_KEV;
use rand::Rng;

/// Russian roulette threshold, as a fraction of the starting weight.
const ROULETTE: f64 = 0.05;

/// How each history is followed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Histories {
    /// Most scatters per history (≥ 1).
    pub max_order: u32,
    /// Branches each history splits into at its first collision (1: none).
    pub split: u32,
    /// Each collision after the first scores a random quarter of the points, ×4.
    pub sparse_multiple: bool,
    /// Where a batch draws its histories' start from.
    pub sampler: Sampler,
    /// With forced detection through cells, one scored path in this many is also traced at
    /// full resolution and each component's image scaled by the ratio of the two
    /// ([`CellCheck`]); 0: none.
    pub cell_check: u32,
}

impl Histories {
    /// At most `max_order` scatters, `split` branches, every point scored, the default
    /// sampler.
    pub fn new(max_order: u32, split: u32) -> Self {
        Self {
            max_order,
            split,
            sparse_multiple: false,
            sampler: Sampler::default(),
            cell_check: 0,
        }
    }
}

impl ScatterEngine {
    /// One history with forced detection at each collision; its first collision forced
    /// ([`Medium::fly_forced`]) at the depth drawn from `first.0` (`first.1`: scratch),
    /// unless the engine samples analog; later flights analog. `start` is (weight, the
    /// weight Russian roulette is measured against, scatters so far): `(w0, w0, 0)` for a
    /// photon from the source; a branch of a split history starts after its first scatter.
    /// `histories`: most scatters, branches at the first collision, sparse scoring after it.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn history<R: Rng>(
        &self,
        mut p: glam::DVec3,
        mut d: glam::DVec3,
        mut e: f64,
        start: (f64, f64, u32),
        histories: Histories,
        single: (&ScoreGrid, &mut Tally),
        mut multiple: Option<(&ScoreGrid, &mut Tally)>,
        paths: (Option<&DetectionGrid>, Option<&mut CellCheck>),
        first: (f64, &mut Vec<(usize, f64)>),
        rng: &mut R,
    ) {
        let (sgrid, stally) = single;
        let (detection, mut check) = paths;
        let (mut w, w0, mut order) = start;
        let Histories {
            max_order,
            split,
            sparse_multiple,
            ..
        } = histories;
        let (u_depth, segments) = first;
        while order < max_order {
            let flight = if order == 0 && !self.analog {
                self.medium
                    .fly_forced(p, d, e, u_depth, segments)
                    .map(|(c, p_collide)| {
                        w *= p_collide;
                        c
                    })
            } else {
                self.medium.fly(p, d, e, rng)
            };
            let Some(c) = flight else {
                return;
            };
            // The first collision scores the single-scatter images, later ones the multiple.
            let (grid, tally) = match multiple.as_mut() {
                Some((g, t)) if order > 0 => (*g, &mut **t),
                _ => (sgrid, &mut *stally),
            };
            score(
                &self.medium,
                detection,
                grid,
                &self.response,
                self.anti_scatter.as_ref(),
                &c,
                d,
                w,
                order,
                tally,
                (order > 0 && sparse_multiple)
                    .then(|| (rng.random_range(0..2usize), rng.random_range(0..2usize))),
                check.as_deref_mut(),
            );
            w *= 1.0 - c.p_photo;
            if order == 0 && split > 1 && max_order > 1 {
                // Split: the branches share this site; each is a history of its own from
                // its scatter on, with its share of the weight.
                let k = f64::from(split);
                for _ in 0..split {
                    let (nd, ne, _) = self.medium.scatter(&c, d, rng);
                    if ne < E_CUTOFF_KEV {
                        continue;
                    }
                    let mut wb = w / k;
                    if wb < ROULETTE * w0 / k {
                        if rng.random::<f64>() < 0.5 {
                            wb *= 2.0;
                        } else {
                            continue;
                        }
                    }
                    self.history(
                        c.position,
                        nd,
                        ne,
                        (wb, w0 / k, 1),
                        histories,
                        (sgrid, &mut *stally),
                        multiple.as_mut().map(|(g, t)| (*g, &mut **t)),
                        (detection, check.as_deref_mut()),
                        (f64::NAN, &mut *segments),
                        rng,
                    );
                }
                return;
            }
            let (nd, ne, _) = self.medium.scatter(&c, d, rng);
            order += 1;
            if ne < E_CUTOFF_KEV {
                return;
            }
            if w < ROULETTE * w0 {
                if rng.random::<f64>() < 0.5 {
                    w *= 2.0;
                } else {
                    return;
                }
            }
            p = c.position;
            d = nd;
            e = ne;
        }
    }
}
