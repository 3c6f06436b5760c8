//! Inference settings: what the fit tunes, when it stops, the data-consistency sweeps that
//! follow it and their gate, the ensemble and the blend with SART-TV from the mean — the
//! `[infer]` table of a model configuration ([`crate::config::TrainConfig`]).

use crate::error::{ModelError, Result, ensure};
use serde::{Deserialize, Serialize};

/// What inference fine-tunes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Tune {
    /// Only the shape and appearance codes.
    Codes,
    /// Codes and the generator's weights, as the paper does (default).
    CodesAndGenerator,
}

impl std::str::FromStr for Tune {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "codes" => Ok(Self::Codes),
            "codes-and-generator" => Ok(Self::CodesAndGenerator),
            _ => Err(ModelError::Invalid(format!(
                "tune '{s}': expected 'codes' or 'codes-and-generator'"
            ))),
        }
    }
}

/// Inference (eq. 13), code first: the codes start at the mean of the training codes and
/// are fitted alone with the generator frozen (`code_iterations`), then — with
/// `tune = codes-and-generator` — codes and generator together at the lower rate `lr`,
/// until every reference view's full-image PSNR reaches the threshold or the iteration cap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InferConfig {
    /// Iteration cap (both phases).
    pub iterations: usize,
    /// Stop when every reference view's full-image PSNR (dB, projections scaled to
    /// [0, 1]) reaches this; checked every `check_every` iterations.
    pub psnr_threshold: f64,
    /// Learning rate of the generator in the second phase (Adam).
    pub lr: f64,
    /// Rays per iteration in the second phase: a `patch`×`patch` patch at a random scale;
    /// 0 = the full image (the paper's choice; costly on a CPU).
    pub patch: usize,
    /// Codes only, or codes and then the generator.
    pub tune: Tune,
    /// Iterations of the first phase: codes only, generator frozen.
    #[serde(default)]
    pub code_iterations: usize,
    /// Learning rate of the codes (Adam, on codes whitened by the training codes' spread).
    #[serde(default = "default_lr_codes")]
    pub lr_codes: f64,
    /// Rays per side in the first phase: one patch spanning the whole image (coarse rays,
    /// every part of the image in every step); 0 = the full image.
    #[serde(default)]
    pub code_patch: usize,
    /// Weight of the codes' negative log-likelihood under the training codes' Gaussian
    /// (eq. 13's λ3 is 0.3).
    #[serde(default = "default_w_nll")]
    pub w_nll: f64,
    /// Check the full-image PSNR of every reference view every this many iterations.
    #[serde(default = "default_check_every")]
    pub check_every: usize,
    /// Data-consistency sweeps after the network's fit: SART-TV (sim's defaults) started
    /// from the network's volume, correcting what the prior could not explain in the
    /// views; 0 = the network's volume as it is. 20 (as many as SART-TV from the mean
    /// volume runs) beat 10 on validation phantoms from 2, 5 and 10 views and tied from 1
    /// (docs/model.md, "How many sweeps").
    #[serde(default = "default_refine_iterations")]
    pub refine_iterations: usize,
    /// TV step of the data-consistency sweeps (fraction of each voxel's total-variation
    /// gradient step; 0: plain SART). 0.2, SART-TV's default, unless tuned on validation
    /// (`tomograf tune-baselines --checkpoint`, docs/model.md).
    #[serde(default = "default_refine_tv_step")]
    pub refine_tv_step: f64,
    /// Run the data-consistency sweeps only when some reference view's full-image PSNR
    /// (dB) against the network volume's projection is below this: views the prior could
    /// not explain. `inf` = always.
    #[serde(default = "default_refine_below_db")]
    pub refine_below_db: f64,
    /// When no reference view is explained (every projection PSNR below
    /// `refine_below_db`), the data-consistency sweeps start from this fraction of the
    /// network volume's attenuation (1: the network's volume; 0: zero, plain SART-TV): the
    /// prior's body is wrong, and trusting it in full carries its outline into the result.
    /// Half tied with ¾ as the best of 1, ¾, ½, ¼, 0 on validation phantoms (docs/model.md,
    /// "Where the sweeps start"). When some view is explained the sweeps start from the
    /// whole volume.
    #[serde(default = "default_refine_start_weight")]
    pub refine_start_weight: f64,
    /// When no reference view is explained, the sweeps' start also holds this fraction of
    /// the mean training volume's attenuation (0: none), added to `refine_start_weight`
    /// times the network volume's. Ignored with `refine_start = "fitted"`; with
    /// `"held-out"` the first candidate.
    #[serde(default)]
    pub refine_start_mean_weight: f64,
    /// How the two weights of the start are set when no view is explained.
    #[serde(default)]
    pub refine_start: RefineStart,
    /// With `refine_start = "held-out"`: the most views for which the start is chosen by
    /// left-out views; with more, the configured weights. 2: on validation phantoms the
    /// left-out choice led from 2 views and trailed from 5 (docs/model.md, "Where the sweeps
    /// start, chosen by a view left out").
    #[serde(default = "default_held_out_max_views")]
    pub held_out_max_views: usize,
    /// What decides whether the sweeps run from two to `held_out_max_views` views:
    /// `projection` (the default), `refine_below_db` on the views the network was fitted
    /// to; `held-out`, views left out of the network's fit ([`RefineGate::HeldOut`]).
    #[serde(default, skip_serializing_if = "RefineGate::is_projection")]
    pub refine_gate: RefineGate,
    /// From this many reference views on, the sweeps run whatever the views' projection PSNR
    /// and start from the whole network volume (`None`: the gate alone decides). With many
    /// views the network can explain every view's projection above `refine_below_db`
    /// without being right inside; on validation phantoms matched to real CTs the open gate
    /// led from 5 and 10 views by 1.1 dB body PSNR (docs/real-ct/validation-real-stats.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_always_from_views: Option<usize>,
    /// Fits averaged into the network volume (1: one fit). The first starts from the mean
    /// code, as a single fit does; each other one from codes drawn from the training codes'
    /// Gaussian, its spread scaled by `ensemble_code_sd`, with its own ray draws. Where the
    /// views pin the volume down every fit agrees; where they do not, the fits disagree and
    /// their average falls back towards what they share ([`crate::ensemble`]). The average
    /// of volumes that explain the views explains them too (projection is linear).
    #[serde(default = "default_ensemble", skip_serializing_if = "is_one")]
    pub ensemble: usize,
    /// Spread of the other fits' starting codes, in units of the training codes' standard
    /// deviation (1: codes as the training set's).
    #[serde(
        default = "default_ensemble_code_sd",
        skip_serializing_if = "is_default_ensemble_code_sd"
    )]
    pub ensemble_code_sd: f64,
    /// The most reference views for which `ensemble` fits are averaged; with more, one
    /// fit (`None`: every view count). From one view the volume along the beam is the
    /// prior's guess and fits from other codes differ; from several views they agree
    /// and each extra fit costs a whole fit's time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ensemble_max_views: Option<usize>,
    /// Weight `w` of SART-TV from the mean in the final volume: (1 − w) × the network's
    /// volume (after its sweeps, when they ran) + w × the volume that `refine_iterations`
    /// sweeps make from the mean training volume alone, without the network (the baseline
    /// "SART-TV from the mean"). Both explain the views; where the prior's anatomy is wrong
    /// their errors differ, and the blend shrinks the network's towards the classical
    /// estimate's. 0: the network's volume alone.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mean_sweeps_weight: f64,
    /// With `mean_sweeps_weight` = W > 0 and several fits averaged: the blend's weight at
    /// each voxel is W × s² / (s² + S²) instead of W, where s is the voxel's standard
    /// deviation across the fits ([`crate::ensemble`]) and S this value, both in normalised
    /// density (× the HU window's width gives HU: 3072 HU for the presets' [−1024, 2048]).
    /// SART-TV from the mean is blended in where the fits disagree — where the prior is
    /// unsure — and not where they agree. With one fit (no spread) nothing is blended.
    /// 0: the constant weight W everywhere.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mean_sweeps_spread: f64,
    /// With `mean_sweeps_weight_below`: when the mean over the views of the network volume's
    /// projection PSNR (dB, after its sweeps when they ran: what `reconstruct` reports per
    /// view) is below this, the blend's W is `mean_sweeps_weight_below` in place of
    /// `mean_sweeps_weight`. A view the prior explains less well than in-distribution inputs
    /// do is a sign that its anatomy is wrong; there SART-TV from the mean is trusted more.
    /// The threshold holds for the detector and noise it was chosen at (a noisier view fits
    /// to a lower PSNR whatever the anatomy). `None`: W always.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_sweeps_below_db: Option<f64>,
    /// The blend's W when the views' projection PSNR is below `mean_sweeps_below_db`, in
    /// [0, 1]; given with it or not at all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_sweeps_weight_below: Option<f64>,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}
fn default_ensemble() -> usize {
    1
}
fn is_one(n: &usize) -> bool {
    *n == 1
}
fn default_ensemble_code_sd() -> f64 {
    1.0
}
fn is_default_ensemble_code_sd(x: &f64) -> bool {
    *x == 1.0
}

/// How the data-consistency sweeps' start weighs the network volume against the mean
/// training volume when no reference view is explained.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RefineStart {
    /// `refine_start_weight` × network + `refine_start_mean_weight` × mean.
    #[default]
    Fixed,
    /// The non-negative weights (a, b) whose start a × network + b × mean best explains the
    /// reference views in least squares (its projections against the views'), so the views
    /// decide how far each volume is trusted.
    Fitted,
    /// With two to `held_out_max_views` reference views: the network is refitted with each
    /// of (at most) two views left out, the sweeps run on the views kept from each
    /// candidate start (the configured weights, ½ × network + ½ × mean, the mean alone),
    /// and the candidate whose volumes best predict the left-out views is used
    /// ([`crate::held_out`]). Views the network was not fitted to can tell a prior that is
    /// right from one that has been bent to the views. Other view counts: the configured
    /// weights.
    HeldOut,
}

/// What decides whether the data-consistency sweeps run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RefineGate {
    /// The sweeps run when some reference view's projection PSNR against the network
    /// volume is below `refine_below_db` (a view the prior could not explain).
    #[default]
    Projection,
    /// From two to `held_out_max_views` views, views left out of the network's fit decide:
    /// the network volume without sweeps and the sweeps from the whole network volume are
    /// candidates beside the starts of [`RefineStart::HeldOut`], and the one whose volumes
    /// best predict the left-out views is used ([`crate::held_out`]). A network can explain
    /// the views it was fitted to without being right inside; a view it was not fitted to
    /// tells. Other view counts: the projection gate.
    HeldOut,
}

impl RefineGate {
    /// Whether this is the default, projection gate (left out of a written config).
    pub fn is_projection(&self) -> bool {
        *self == RefineGate::Projection
    }
}

fn default_lr_codes() -> f64 {
    0.05
}
fn default_w_nll() -> f64 {
    0.3
}
fn default_check_every() -> usize {
    10
}
fn default_refine_iterations() -> usize {
    20
}
fn default_refine_tv_step() -> f64 {
    // SART-TV's own default (`SartTvSettings::default`).
    tomograf_recon::TvOptions::default().step
}
fn default_refine_below_db() -> f64 {
    30.0
}
fn default_refine_start_weight() -> f64 {
    0.5
}
fn default_held_out_max_views() -> usize {
    2
}

/// Settings that override a checkpoint's [`InferConfig`] (from the command line); `None`
/// keeps the checkpoint's.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct InferOverrides {
    /// What is tuned.
    pub tune: Option<Tune>,
    /// Iteration cap (both phases).
    pub iterations: Option<usize>,
    /// Stopping threshold, dB.
    pub psnr_threshold: Option<f64>,
    /// Data-consistency (SART-TV) sweeps after the network's fit.
    pub refine_iterations: Option<usize>,
    /// TV step of those sweeps.
    pub refine_tv_step: Option<f64>,
}

impl InferConfig {
    /// The blend's W for views whose projection PSNRs (dB) are `psnr`:
    /// `mean_sweeps_weight_below` when their mean is below `mean_sweeps_below_db`, else
    /// `mean_sweeps_weight`.
    pub fn mean_sweeps_weight_for(&self, psnr: &[f64]) -> f64 {
        match (self.mean_sweeps_below_db, self.mean_sweeps_weight_below) {
            (Some(db), Some(w)) if !psnr.is_empty() => {
                let mean = psnr.iter().sum::<f64>() / psnr.len() as f64;
                if mean < db {
                    w
                } else {
                    self.mean_sweeps_weight
                }
            }
            _ => self.mean_sweeps_weight,
        }
    }

    /// The largest blend weight these settings can give (the sweeps must run for it).
    pub fn mean_sweeps_weight_max(&self) -> f64 {
        self.mean_sweeps_weight
            .max(self.mean_sweeps_weight_below.unwrap_or(0.0))
    }

    /// The number of fits averaged for `views` reference views: `ensemble`, or 1 with
    /// more views than `ensemble_max_views`.
    pub fn ensemble_fits(&self, views: usize) -> usize {
        match self.ensemble_max_views {
            Some(m) if views > m => 1,
            _ => self.ensemble,
        }
    }

    /// This config with `o`'s settings overridden; the stopping threshold (dB) must be
    /// finite.
    pub fn overridden(&self, o: &InferOverrides) -> Result<Self> {
        let mut c = self.clone();
        if let Some(t) = o.tune {
            c.tune = t;
        }
        if let Some(n) = o.iterations {
            ensure!(
                n >= 1,
                "inference iterations must be at least 1 (0 would score the untouched \
                 starting volume)"
            );
            c.iterations = n;
        }
        if let Some(db) = o.psnr_threshold {
            ensure!(
                db.is_finite(),
                "inference PSNR threshold {db} dB must be a finite number"
            );
            c.psnr_threshold = db;
        }
        if let Some(n) = o.refine_iterations {
            ensure!(
                n > 0 || c.mean_sweeps_weight_max() == 0.0,
                "0 data-consistency sweeps, but the checkpoint's infer.mean_sweeps_weight = {} \
                 (mean_sweeps_weight_below = {:?}) blends in SART-TV from the mean, which \
                 needs at least 1",
                c.mean_sweeps_weight,
                c.mean_sweeps_weight_below
            );
            c.refine_iterations = n;
        }
        if let Some(t) = o.refine_tv_step {
            ensure!(
                t.is_finite() && t >= 0.0,
                "the data-consistency sweeps' TV step {t} must be a finite number ≥ 0"
            );
            c.refine_tv_step = t;
        }
        Ok(c)
    }
}
