//! Data consistency after the network: SART-TV sweeps from a start built from the
//! network's volume and the mean training volume (docs/model.md, "Data consistency after
//! the network" and "Where the sweeps start").
//!
//! The sweeps run only when some reference view is unexplained (its projection PSNR below
//! `refine_below_db`). When some view is explained, the prior's body is right and what is
//! missing is seen only in other views (an object beside it): the sweeps start from the
//! whole network volume. When no view is explained, the prior's body is wrong and the start
//! is `a` × the network volume's attenuation + `b` × the mean training volume's, with
//! `(a, b)` fixed by the configuration ([`RefineStart::Fixed`]), fitted to the views
//! ([`RefineStart::Fitted`]) or chosen among candidates by views left out of the fit
//! ([`RefineStart::HeldOut`], [`crate::held_out`]).

use crate::baseline::{SartTvSettings, sart_tv_density};
use crate::config::{InferConfig, RefineStart};
use crate::error::{Result, ensure};
use crate::prior::MeanVolume;
use crate::reference::Reference;
use crate::render::DensityScale;
use tomograf_sim::{Projector, Renderer, Volume};

/// The weights of the sweeps' start: `network` × the network volume's attenuation +
/// `mean` × the mean training volume's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartWeights {
    /// Weight of the network volume.
    pub network: f64,
    /// Weight of the mean training volume.
    pub mean: f64,
}

/// The start's weights: the whole network volume when some view is explained (its PSNR in
/// `psnr` at least `infer.refine_below_db`); else the configured weights
/// ([`RefineStart::Fixed`], and [`RefineStart::HeldOut`], whose choice among candidates
/// needs the network refitted and is made by [`crate::held_out`]) or the weights fitted to
/// the views ([`RefineStart::Fitted`]).
pub fn start_weights(
    refs: &[Reference],
    network: &Volume,
    prior: &MeanVolume,
    scale: &DensityScale,
    infer: &InferConfig,
    psnr: &[f64],
) -> Result<StartWeights> {
    if psnr.iter().any(|&p| p >= infer.refine_below_db) {
        return Ok(StartWeights {
            network: 1.0,
            mean: 0.0,
        });
    }
    match infer.refine_start {
        RefineStart::Fixed | RefineStart::HeldOut => Ok(configured_weights(infer)),
        RefineStart::Fitted => fitted_weights(refs, network, &mean_on_grid(prior, network), scale),
    }
}

/// `infer.refine_start_weight` × network + `infer.refine_start_mean_weight` × mean.
pub fn configured_weights(infer: &InferConfig) -> StartWeights {
    StartWeights {
        network: infer.refine_start_weight,
        mean: infer.refine_start_mean_weight,
    }
}

/// The volume (normalised density) after `infer.refine_iterations` SART-TV sweeps (TV step
/// `infer.refine_tv_step`) fitted to `refs` from `weights.network` × the attenuation of
/// `network` + `weights.mean` × the mean training volume's.
pub fn sweep_from(
    refs: &[Reference],
    network: &Volume,
    prior: &MeanVolume,
    scale: &DensityScale,
    infer: &InferConfig,
    weights: StartWeights,
) -> Result<Volume> {
    let mean = (weights.mean > 0.0).then(|| mean_on_grid(prior, network));
    let mut start = vec![(network.data(), weights.network)];
    if let Some(m) = &mean {
        start.push((m.as_slice(), weights.mean));
    }
    let sweeps = SartTvSettings {
        sweeps: infer.refine_iterations,
        tv_step: infer.refine_tv_step,
    };
    sart_tv_density(refs, network, scale, &start, &sweeps)
}

/// The mean training volume sampled at the voxel centres of `grid` (normalised density),
/// `i` fastest; its own data when the sizes agree.
pub fn mean_on_grid(prior: &MeanVolume, grid: &Volume) -> Vec<f32> {
    let dims = grid.dims();
    if prior.dims == dims {
        return prior.data.clone();
    }
    let coord = |i: usize, a: usize| (2.0 * (i as f64 + 0.5) / dims[a] as f64 - 1.0) as f32;
    let mut points = Vec::with_capacity(grid.len() * 3);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                points.extend([coord(i, 0), coord(j, 1), coord(k, 2)]);
            }
        }
    }
    prior.at_normalised(&points)
}

/// The non-negative `(a, b)` minimising Σ over the references of
/// ‖a·P(μ_network) + b·P(μ_mean) − image‖², P the exact Siddon projection of each view.
pub fn fitted_weights(
    refs: &[Reference],
    network: &Volume,
    mean: &[f32],
    scale: &DensityScale,
) -> Result<StartWeights> {
    let mu_net = network.map(|d| scale.mu_scalar(f64::from(d)) as f32)?;
    let mu_mean = Volume::new(
        network.dims(),
        network.spacing(),
        network.origin(),
        network.direction(),
        mean.iter()
            .map(|&d| scale.mu_scalar(f64::from(d)) as f32)
            .collect(),
    )?;
    let (rn, rm) = (
        Renderer::new(&mu_net, Projector::Siddon)?,
        Renderer::new(&mu_mean, Projector::Siddon)?,
    );
    // Gram matrix [[nn, nm], [nm, mm]] and right-hand side [ny, my].
    let (mut nn, mut nm, mut mm, mut ny, mut my) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for r in refs {
        let (pn, pm) = (rn.render(&r.view)?, rm.render(&r.view)?);
        for ((&n, &m), &y) in pn.data.iter().zip(&pm.data).zip(&r.image) {
            let (n, m, y) = (f64::from(n), f64::from(m), f64::from(y));
            nn += n * n;
            nm += n * m;
            mm += m * m;
            ny += n * y;
            my += m * y;
        }
    }
    ensure!(
        nn > 0.0 || mm > 0.0,
        "neither the network volume nor the mean volume attenuates along any reference ray: \
         no start can be fitted to the views"
    );
    Ok(nonnegative_least_squares([nn, nm, mm], [ny, my]))
}

/// argmin over a, b ≥ 0 of a²·g₀ + 2ab·g₁ + b²·g₂ − 2(a·r₀ + b·r₁): the unconstrained
/// solution when it is non-negative, else the better of the two one-weight solutions.
fn nonnegative_least_squares(g: [f64; 3], r: [f64; 2]) -> StartWeights {
    let cost = |a: f64, b: f64| {
        a * a * g[0] + 2.0 * a * b * g[1] + b * b * g[2] - 2.0 * (a * r[0] + b * r[1])
    };
    let det = g[0] * g[2] - g[1] * g[1];
    // A singular Gram matrix (collinear projections) has no unique pair: use one volume.
    if det > 1e-12 * g[0] * g[2] {
        let a = (r[0] * g[2] - r[1] * g[1]) / det;
        let b = (r[1] * g[0] - r[0] * g[1]) / det;
        if a >= 0.0 && b >= 0.0 {
            return StartWeights {
                network: a,
                mean: b,
            };
        }
    }
    let a = if g[0] > 0.0 {
        (r[0] / g[0]).max(0.0)
    } else {
        0.0
    };
    let b = if g[2] > 0.0 {
        (r[1] / g[2]).max(0.0)
    } else {
        0.0
    };
    if cost(a, 0.0) <= cost(0.0, b) {
        StartWeights {
            network: a,
            mean: 0.0,
        }
    } else {
        StartWeights {
            network: 0.0,
            mean: b,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// Views made (with sim's projector) from 0.3 × one volume + 0.6 × another give those
    /// weights back through [`fitted_weights`], and the fixed and fitted starts run.
    #[test]
    fn the_fitted_start_recovers_the_weights_that_made_the_views() {
        let n = 12;
        let scale = DensityScale::from_window(-1024.0, 2048.0, 0.02).unwrap();
        let threshold = scale.threshold as f32;
        // Two unlike densities above air: a ball and a slab.
        let make = |f: &dyn Fn(f64, f64, f64) -> f32| {
            let mut d = Vec::with_capacity(n * n * n);
            for k in 0..n {
                for j in 0..n {
                    for i in 0..n {
                        let c = |a: usize| (a as f64 + 0.5) / n as f64 - 0.5;
                        d.push(threshold + f(c(i), c(j), c(k)));
                    }
                }
            }
            Volume::centred([n; 3], DVec3::splat(4.0), DVec3::ZERO, d).unwrap()
        };
        let ball = make(&|x, y, z| {
            if x * x + y * y + z * z < 0.12 {
                0.4
            } else {
                0.0
            }
        });
        let slab = make(&|x, _, z| {
            if x.abs() < 0.3 && z > -0.2 {
                0.3 + x as f32
            } else {
                0.0
            }
        });
        let mu = |v: &Volume| v.map(|d| scale.mu_scalar(f64::from(d)) as f32).unwrap();
        let (mb, ms) = (mu(&ball), mu(&slab));
        let truth = Volume::centred(
            [n; 3],
            DVec3::splat(4.0),
            DVec3::ZERO,
            mb.data()
                .iter()
                .zip(ms.data())
                .map(|(a, b)| 0.3 * a + 0.6 * b)
                .collect(),
        )
        .unwrap();
        let refs = crate::reference::test_references(&truth);
        let w = fitted_weights(&refs, &ball, slab.data(), &scale).unwrap();
        assert!(
            (w.network - 0.3).abs() < 1e-4 && (w.mean - 0.6).abs() < 1e-4,
            "{w:?}"
        );
        // Through `start_weights` and the sweeps: the fitted start is chosen when no view is explained, the
        // whole network volume when one is.
        let prior = MeanVolume {
            data: slab.data().to_vec(),
            dims: [n; 3],
        };
        let mut infer = crate::config::TrainConfig::load("tiny").unwrap().infer;
        infer.refine_start = RefineStart::Fitted;
        infer.refine_iterations = 1;
        let run = |psnr: &[f64]| {
            let w = start_weights(&refs, &ball, &prior, &scale, &infer, psnr).unwrap();
            sweep_from(&refs, &ball, &prior, &scale, &infer, w).unwrap();
            w
        };
        let w = run(&[10.0, 10.0]);
        assert!((w.network - 0.3).abs() < 1e-4 && (w.mean - 0.6).abs() < 1e-4);
        let w = run(&[10.0, 40.0]);
        assert_eq!((w.network, w.mean), (1.0, 0.0));
        assert_eq!(mean_on_grid(&prior, &ball), slab.data());
    }

    /// Weights recovered exactly from right-hand sides made with known ones, and the
    /// non-negativity constraint picking the better single volume.
    #[test]
    fn least_squares_weights_are_recovered_and_kept_non_negative() {
        // Two independent "projections" n, m as vectors; y = 0.3 n + 0.6 m.
        let n = [1.0, 2.0, 0.5, 0.0];
        let m = [0.2, 1.0, 1.5, 2.0];
        let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(a, b)| a * b).sum::<f64>();
        let g = [dot(&n, &n), dot(&n, &m), dot(&m, &m)];
        let y: Vec<f64> = n.iter().zip(&m).map(|(a, b)| 0.3 * a + 0.6 * b).collect();
        let w = nonnegative_least_squares(g, [dot(&n, &y), dot(&m, &y)]);
        assert!(
            (w.network - 0.3).abs() < 1e-12 && (w.mean - 0.6).abs() < 1e-12,
            "{w:?}"
        );
        // y = n − 0.5 m wants a negative mean weight: the constrained answer uses n alone,
        // at the weight that fits y best with n alone.
        let y: Vec<f64> = n.iter().zip(&m).map(|(a, b)| a - 0.5 * b).collect();
        let w = nonnegative_least_squares(g, [dot(&n, &y), dot(&m, &y)]);
        assert_eq!(w.mean, 0.0);
        assert!((w.network - dot(&n, &y) / g[0]).abs() < 1e-12, "{w:?}");
        // Collinear projections (m = 2 n): a single volume, no division by zero.
        let m2: Vec<f64> = n.iter().map(|a| 2.0 * a).collect();
        let g2 = [dot(&n, &n), dot(&n, &m2), dot(&m2, &m2)];
        let w = nonnegative_least_squares(g2, [dot(&n, &n), dot(&m2, &n)]);
        assert!(w.network.is_finite() && w.mean.is_finite());
        let fit = |w: StartWeights| {
            n.iter()
                .zip(&m2)
                .map(|(a, b)| (w.network * a + w.mean * b - a).powi(2))
                .sum::<f64>()
        };
        assert!(fit(w) < 1e-20, "{w:?}");
    }
}
