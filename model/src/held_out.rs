//! Where the data-consistency sweeps start, chosen by views the network was not fitted to
//! (`infer.refine_start = "held-out"`; docs/model.md, "Where the sweeps start, chosen by
//! a view left out"), and — with `infer.refine_gate = "held-out"` — whether they run at all
//! (docs/real-ct/validation-real-stats.md, decision 6).
//!
//! Projection consistency cannot weigh the network volume against the mean training
//! volume: the network has been fitted to the views and explains them better than any
//! blend, whether its prior is right or has been bent to them. A view left out of the fit
//! can. For each fold (each of the first [`MAX_FOLDS`] views left out in turn), the network
//! is refitted to the other views with the same seed and settings, each candidate is made
//! from that fit — the sweeps ([`FOLD_SWEEPS`]) on the kept views from each start of
//! [`candidates`], and with the gate also the fit's volume unswept and the sweeps from its
//! whole volume ([`gate_candidates`]) — and projected into the left-out view. The candidate
//! with the least squared error over all folds' left-out views is used on all views; on a
//! tie the earliest keeps its place. Costs one network fit per fold on top of the fit to
//! all views.

use crate::checkpoint::Generator;
use crate::config::InferConfig;
use crate::error::{Result, ensure};
use crate::fit::{fit_network, projection_sq_err};
use crate::reference::Reference;
use crate::refine::{StartWeights, configured_weights, sweep_from};
use burn::tensor::Device;
use tomograf_sim::Volume;

/// Folds at most: the first this many views are each left out once (the network is
/// refitted this many times).
pub const MAX_FOLDS: usize = 2;

/// The sweeps each fold runs from each candidate (count, TV step): fixed, so that the
/// choice does not depend on the sweeps run after it (`evaluate` with tuned sweeps and
/// `tune-baselines`' search of them see the same start). 20 sweeps at TV step 0.2, the
/// shipped checkpoint's own, with which the choice was validated.
pub const FOLD_SWEEPS: (usize, f64) = (20, 0.2);

/// Each candidate (`None`: no sweeps) and its PSNR (dB) on the left-out views.
pub type CandidateScores = Vec<(Option<StartWeights>, f64)>;

/// What the folds measured and what they chose.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldOutChoice {
    /// The chosen start of the sweeps; `None`: no sweeps, the network volume as it is (a
    /// candidate only with the gate).
    pub weights: Option<StartWeights>,
    /// Each candidate (`None`: no sweeps) and its PSNR (dB, projections divided by the
    /// checkpoint's projection scale, MAX 1) over all left-out views together.
    pub scores: CandidateScores,
}

/// The candidate starts, in order of precedence: the configured weights
/// (`refine_start_weight` × network + `refine_start_mean_weight` × mean), ½ × network +
/// ½ × mean, and the mean alone (SART-TV from the mean's start); repeats dropped.
pub fn candidates(infer: &InferConfig) -> Vec<StartWeights> {
    let mut out = vec![configured_weights(infer)];
    for w in [
        StartWeights {
            network: 0.5,
            mean: 0.5,
        },
        StartWeights {
            network: 0.0,
            mean: 1.0,
        },
    ] {
        if !out.contains(&w) {
            out.push(w);
        }
    }
    out
}

/// The candidates of the held-out gate, in order of precedence: no sweeps (the network
/// volume as it is; the projection gate's choice when a view is explained), the sweeps
/// from the whole network volume, then [`candidates`]; repeats dropped.
pub fn gate_candidates(infer: &InferConfig) -> Vec<Option<StartWeights>> {
    let mut out = vec![
        None,
        Some(StartWeights {
            network: 1.0,
            mean: 0.0,
        }),
    ];
    for w in candidates(infer) {
        if !out.contains(&Some(w)) {
            out.push(Some(w));
        }
    }
    out
}

/// The start of the sweeps for `refs` (two or more views) chosen by left-out views, as the
/// module says — with `gate`, among [`gate_candidates`] (no sweeps among them), else among
/// [`candidates`]; `grid` gives the volume's geometry, `seed` the fits' seed.
pub fn choose(
    generator: &Generator,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    device: &Device,
    gate: bool,
) -> Result<HeldOutChoice> {
    ensure!(
        refs.len() >= 2,
        "a start chosen by a left-out view needs at least two views (got {})",
        refs.len()
    );
    let scale = generator.state.density_scale;
    let proj_scale = generator.state.proj_scale;
    let cands = if gate {
        gate_candidates(infer)
    } else {
        candidates(infer).into_iter().map(Some).collect()
    };
    let mut fold_infer = infer.clone();
    (fold_infer.refine_iterations, fold_infer.refine_tv_step) = FOLD_SWEEPS;
    let mut sq_err = vec![0.0f64; cands.len()];
    let mut pixels = 0usize;
    for left in 0..refs.len().min(MAX_FOLDS) {
        let kept: Vec<Reference> = refs
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != left)
            .map(|(_, r)| r.clone())
            .collect();
        let fit = fit_network(generator, &kept, grid, infer, seed, device, &mut |_, _| {})?;
        let out = std::slice::from_ref(&refs[left]);
        for (c, &w) in cands.iter().enumerate() {
            let (sum, n) = match w {
                Some(w) => {
                    let v =
                        sweep_from(&kept, &fit.volume, &generator.prior, &scale, &fold_infer, w)?;
                    projection_sq_err(&v, &scale, out, proj_scale)?[0]
                }
                None => projection_sq_err(&fit.volume, &scale, out, proj_scale)?[0],
            };
            sq_err[c] += sum;
            if c == 0 {
                pixels += n;
            }
        }
    }
    let scores: CandidateScores = cands
        .iter()
        .zip(&sq_err)
        .map(|(&w, &e)| (w, -10.0 * (e / pixels.max(1) as f64 + 1e-20).log10()))
        .collect();
    // The least error; the earliest candidate on a tie.
    let best = (0..cands.len()).fold(0, |b, c| if sq_err[c] < sq_err[b] { c } else { b });
    Ok(HeldOutChoice {
        weights: cands[best],
        scores,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_keep_the_configured_start_first_and_drop_repeats() {
        let mut infer = crate::config::TrainConfig::load("tiny").unwrap().infer;
        infer.refine_start_weight = 0.5;
        infer.refine_start_mean_weight = 0.0;
        let c = candidates(&infer);
        assert_eq!(c.len(), 3);
        assert_eq!((c[0].network, c[0].mean), (0.5, 0.0));
        infer.refine_start_mean_weight = 0.5;
        let c = candidates(&infer);
        assert_eq!(c.len(), 2);
        assert_eq!((c[0].network, c[0].mean), (0.5, 0.5));
        assert_eq!((c[1].network, c[1].mean), (0.0, 1.0));
        // The gate's: no sweeps first, then the whole network volume, then the starts.
        infer.refine_start_mean_weight = 0.0;
        let g = gate_candidates(&infer);
        assert_eq!(g.len(), 5);
        assert_eq!(g[0], None);
        assert_eq!(g[1].map(|w| (w.network, w.mean)), Some((1.0, 0.0)));
        assert_eq!(g[2].map(|w| (w.network, w.mean)), Some((0.5, 0.0)));
        // A configured start of the whole network volume is not repeated.
        infer.refine_start_weight = 1.0;
        assert_eq!(gate_candidates(&infer).len(), 4);
    }
}
