//! Inference (Methods 1.2.3, eq. 13), code first.
//!
//! 1. The codes start at the mean of the training codes (whitened codes u = 0, see
//!    [`crate::prior::CodeStats`]) and are fitted alone, the generator frozen, for
//!    `code_iterations` iterations of Adam at `lr_codes`, on coarse rays spanning the whole
//!    image (`code_patch`).
//! 2. With `tune = codes-and-generator`, the generator is then tuned with the codes, at the
//!    lower rate `lr`, on `patch`×`patch` patches at random scales.
//!
//! 3. With `refine_iterations` > 0, when some reference view's full-image PSNR against the
//!    network volume's projection is below `refine_below_db` (the prior could not explain
//!    the views: anatomy outside the training population), or always from
//!    `refine_always_from_views` views on, or as views left out of the fit decide
//!    (`refine_gate = "held-out"`, [`crate::held_out`]), SART-TV (sim's defaults) runs that
//!    many sweeps from the network's volume ([`crate::refine`]: where they start).
//!    The network's own volume is kept beside the result.
//!
//! Each iteration fits one randomly drawn reference view with eq. 13's loss,
//! λ1·L_r + λ2·L_PSNR + λ3·NLL (0.3, 0.1, `w_nll`), the NLL taken under the training codes'
//! Gaussian. Every `check_every` iterations the current volume is rendered on the grid and
//! projected with sim's Siddon projector into every reference view; inference stops when
//! each view's full-image PSNR reaches the threshold, or at the iteration cap.

use crate::checkpoint::Generator;
use crate::config::{InferConfig, RefineGate, RefineStart};
use crate::ensemble::fit_ensemble;
use crate::error::Result;
use crate::held_out;
use crate::refine::{StartWeights, start_weights, sweep_from};
use burn::tensor::{Device, Tensor};
use tomograf_sim::Volume;

pub use crate::fit::{
    Fit, LAMBDA_PSNR, LAMBDA_R, fit_network, projection_psnr, projection_sq_err, render_volume,
};
pub use crate::reference::{Reference, check_references};

/// What inference produced.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    /// Normalised density on the requested grid (after the data-consistency sweeps, when
    /// they ran).
    pub volume: Volume,
    /// The network's own volume before the data-consistency sweeps (equal to `volume` when
    /// the gate kept them from running); `None` when `refine_iterations` is 0.
    pub network: Option<NetworkVolume>,
    /// Iterations run (both phases).
    pub iterations: usize,
    /// Full-image PSNR (dB, projections scaled to [0, 1]) of each reference view, from the
    /// final volume projected with sim's Siddon projector.
    pub psnr: Vec<f64>,
    /// Loss per iteration.
    pub losses: Vec<f64>,
    /// The fitted codes `(z_sh, z_a)` (not whitened).
    pub codes: (Vec<f32>, Vec<f32>),
    /// With several fits averaged ([`crate::ensemble`]): each voxel's standard deviation
    /// across them (normalised density); `None` for a single fit.
    pub spread: Option<Volume>,
    /// The estimated peak memory, bytes ([`crate::config::TrainConfig::inference_peak_bytes`]),
    /// checked against the memory available before the fit.
    pub peak_bytes: u128,
    /// The blend with SART-TV from the mean, when it ran (`[infer] mean_sweeps_weight`,
    /// `mean_sweeps_weight_below`); `None` when it did not.
    pub blend: Option<Blend>,
}

/// What the blend with SART-TV from the mean did (see [`InferConfig::mean_sweeps_weight_for`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blend {
    /// W, the weight of SART-TV from the mean (where the fits' spread is large against
    /// `mean_sweeps_spread`; everywhere when that is 0), in [0, 1].
    pub weight: f64,
    /// The mean over the views of the projection PSNR (dB) of the volume before the blend:
    /// what chose W against `mean_sweeps_below_db`.
    pub views_psnr_db: f64,
}

/// The network's volume before data-consistency sweeps.
#[derive(Debug, Clone)]
pub struct NetworkVolume {
    /// Normalised density on the requested grid.
    pub volume: Volume,
    /// Full-image PSNR (dB) of each reference view against its projection, as
    /// [`Reconstruction::psnr`].
    pub psnr: Vec<f64>,
    /// Whether the sweeps ran (some view's PSNR was below `refine_below_db`, or the gate of
    /// `refine_always_from_views` or `refine_gate` opened).
    pub refined: bool,
    /// The weights of the sweeps' start (network volume, mean volume), when they ran.
    pub start: Option<StartWeights>,
    /// Seconds the sweeps took (with the refits of a start or gate chosen by left-out
    /// views, also when those chose no sweeps).
    pub refine_seconds: f64,
    /// When left-out views chose: each candidate (`None`: no sweeps) and its PSNR (dB) on
    /// the left-out views ([`held_out::HeldOutChoice::scores`]).
    pub held_out: Option<held_out::CandidateScores>,
}

/// Refuses an inference whose estimated peak
/// ([`crate::config::TrainConfig::inference_peak_bytes`]), beyond what the process holds
/// now, exceeds the memory available; the estimate otherwise.
fn check_memory(
    generator: &Generator,
    infer: &InferConfig,
    refs: &[Reference],
    grid: &Volume,
) -> Result<u128> {
    let c = &generator.config;
    let view_pixels = refs
        .iter()
        .map(|r| r.view.rows as u128 * r.view.cols as u128)
        .max()
        .unwrap_or(0);
    let peak = c.inference_peak_bytes(infer, view_pixels) as u128;
    let held = tomograf_sim::memory::resident_bytes().map_or(0, u128::from);
    let [nx, ny, nz] = grid.dims();
    tomograf_sim::memory::check(
        peak.saturating_sub(held),
        &format!(
            "inference onto a {nx}×{ny}×{nz} grid with the checkpoint's field (hidden {}, depth \
             {}, {} samples per ray, infer.patch {}, infer.code_patch {}; estimated peak {:.0} \
             MiB), beyond what is already held,",
            c.model.hidden,
            c.model.depth,
            c.model.samples,
            infer.patch,
            infer.code_patch,
            peak as f64 / (1u64 << 20) as f64
        ),
    )?;
    Ok(peak)
}

/// Whether the data-consistency sweeps run after the network's fit to `refs` (its volume
/// `network`, its views' projection PSNR `psnr`) and from which start (`None`: they do
/// not), with the left-out views' scores when those decided:
/// - from `refine_always_from_views` views on, always, from the whole network volume;
/// - with `refine_gate = "held-out"` and two to `held_out_max_views` views, as the left-out
///   views choose among no sweeps and the starts ([`held_out::gate_candidates`]);
/// - else when some view is unexplained (`refine_below_db`), from the start
///   [`start_weights`] gives, or — with `refine_start = "held-out"`, two to
///   `held_out_max_views` views and no view explained — the one left-out views choose.
#[allow(clippy::too_many_arguments)]
fn sweeps_start(
    generator: &Generator,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    device: &Device,
    psnr: &[f64],
    network: &Volume,
) -> Result<(Option<StartWeights>, Option<held_out::CandidateScores>)> {
    let held_out_views = (2..=infer.held_out_max_views).contains(&refs.len());
    if infer
        .refine_always_from_views
        .is_some_and(|n| refs.len() >= n)
    {
        let whole = StartWeights {
            network: 1.0,
            mean: 0.0,
        };
        return Ok((Some(whole), None));
    }
    if infer.refine_gate == RefineGate::HeldOut && held_out_views {
        let choice = held_out::choose(generator, refs, grid, infer, seed, device, true)?;
        return Ok((choice.weights, Some(choice.scores)));
    }
    if !psnr.iter().any(|&p| p < infer.refine_below_db) {
        return Ok((None, None));
    }
    let explained = psnr.iter().any(|&p| p >= infer.refine_below_db);
    if infer.refine_start == RefineStart::HeldOut && !explained && held_out_views {
        let choice = held_out::choose(generator, refs, grid, infer, seed, device, false)?;
        return Ok((choice.weights, Some(choice.scores)));
    }
    let w = start_weights(
        refs,
        network,
        &generator.prior,
        &generator.state.density_scale,
        infer,
        psnr,
    )?;
    Ok((Some(w), None))
}

/// Fits `generator` to `refs` (code first, then — as `infer.tune` says — the generator) and
/// renders the volume on `grid` (its geometry only); then, when `infer` asks for them and
/// some view is unexplained, the data-consistency sweeps ([`crate::refine`], and
/// [`crate::held_out`] for a start chosen by views left out). `progress(iteration, loss)`
/// is called after each iteration of the fit to all views.
pub fn reconstruct(
    generator: Generator,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    device: &Device,
    mut progress: impl FnMut(usize, f64),
) -> Result<Reconstruction> {
    check_references(refs)?;
    let peak_bytes = check_memory(&generator, infer, refs, grid)?;
    let fit = fit_ensemble(&generator, refs, grid, infer, seed, device, &mut progress)?;
    let Fit {
        tuned,
        iterations,
        losses,
        mut volume,
        mut psnr,
        spread,
    } = fit;
    let density_scale = generator.state.density_scale;
    let proj_scale = generator.state.proj_scale;
    let mut network = None;
    if infer.refine_iterations > 0 {
        let t0 = std::time::Instant::now();
        let (weights, held_out) =
            sweeps_start(&generator, refs, grid, infer, seed, device, &psnr, &volume)?;
        let mut net = NetworkVolume {
            volume: volume.clone(),
            psnr: psnr.clone(),
            refined: weights.is_some(),
            start: weights,
            refine_seconds: 0.0,
            held_out,
        };
        if let Some(w) = weights {
            volume = sweep_from(
                refs,
                &net.volume,
                &generator.prior,
                &density_scale,
                infer,
                w,
            )?;
            psnr = projection_psnr(&volume, &density_scale, refs, proj_scale)?;
        }
        net.refine_seconds = t0.elapsed().as_secs_f64();
        network = Some(net);
    }
    let weight = infer.mean_sweeps_weight_for(&psnr);
    let blend =
        (weight > 0.0 && (infer.mean_sweeps_spread == 0.0 || spread.is_some())).then(|| Blend {
            weight,
            views_psnr_db: psnr.iter().sum::<f64>() / psnr.len() as f64,
        });
    if blend.is_some() {
        volume = blend_with_mean_sweeps(
            refs,
            &volume,
            spread.as_ref(),
            &generator.prior,
            &density_scale,
            infer,
            weight,
        )?;
        psnr = projection_psnr(&volume, &density_scale, refs, proj_scale)?;
    }
    let stats = &generator.codes.stats;
    let (z_sh, z_a) = stats.codes(tuned.codes.shape.val(), tuned.codes.app.val());
    let read = |t: Tensor<2>| t.into_data().try_to_vec::<f32>().expect("f32 codes");
    Ok(Reconstruction {
        volume,
        network,
        iterations,
        peak_bytes,
        psnr,
        losses,
        codes: (read(z_sh), read(z_a)),
        spread,
        blend,
    })
}

/// (1 − w) × `volume` + w × SART-TV from the mean training volume alone (`infer`'s sweeps),
/// voxel by voxel: w = W = `weight` ([`InferConfig::mean_sweeps_weight_for`] the volume's
/// views), or, with `infer.mean_sweeps_spread` = S > 0 and the fits' `spread` s,
/// w = W × s² / (s² + S²).
fn blend_with_mean_sweeps(
    refs: &[Reference],
    volume: &Volume,
    spread: Option<&Volume>,
    prior: &crate::prior::MeanVolume,
    density_scale: &crate::render::DensityScale,
    infer: &InferConfig,
    weight: f64,
) -> Result<Volume> {
    let from_mean = StartWeights {
        network: 0.0,
        mean: 1.0,
    };
    let classical = sweep_from(refs, volume, prior, density_scale, infer, from_mean)?;
    let s2 = infer.mean_sweeps_spread.powi(2);
    let at = |i: usize| -> f32 {
        match spread {
            Some(sd) if s2 > 0.0 => {
                let v = f64::from(sd.data()[i]).powi(2);
                (weight * v / (v + s2)) as f32
            }
            _ => weight as f32,
        }
    };
    let blended = volume
        .data()
        .iter()
        .zip(classical.data())
        .enumerate()
        .map(|(i, (&n, &c))| {
            let w = at(i);
            (1.0 - w) * n + w * c
        })
        .collect();
    Ok(Volume::new(
        volume.dims(),
        volume.spacing(),
        volume.origin(),
        volume.direction(),
        blended,
    )?)
}
