//! Training and inference configurations, as TOML; presets `tiny`, `small`, `paper`.

use crate::error::{ModelError, Result, ensure};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Generator and discriminator sizes and ray sampling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelConfig {
    /// Patch side M (rays per patch M×M); a multiple of 4.
    pub patch: usize,
    /// Stratified samples Q per ray; a multiple of 4 (D1 sees M×M×Q sub-volumes).
    pub samples: usize,
    /// Width of the radiance field's hidden layers.
    pub hidden: usize,
    /// Hidden layers of the shape encoder h.
    pub depth: usize,
    /// Shape code size M_sh.
    pub z_shape: usize,
    /// Appearance code size M_a.
    pub z_app: usize,
    /// Positional-encoding frequencies for x.
    pub freq_x: usize,
    /// Positional-encoding frequencies for the pose ξ.
    pub freq_pose: usize,
    /// Channels of the first discriminator layer.
    pub disc_channels: usize,
    /// Density depends on the view direction ξ, as eqs. 5–6 are written (the paper's form).
    /// Off by default: X-ray attenuation has no view dependence, and a ξ-dependent density
    /// lets every view be explained by a different volume.
    #[serde(default)]
    pub view_dependent: bool,
    /// Density = the mean training volume + a residual whose last layer starts at zero, so
    /// an untrained field renders the mean volume exactly (default). Off: δ = softplus(·), the
    /// paper's form, with no prior.
    #[serde(default = "yes")]
    pub mean_anchor: bool,
}

fn yes() -> bool {
    true
}

/// How training codes are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CodeMode {
    /// An auto-decoder: each training item has its own shape and appearance codes, learned
    /// with the generator (an embedding table), so V′ is paired with the item's real V.
    PerItem,
    /// Codes redrawn from N(0, I) at every step (the paper's GAN): nothing pairs a generated
    /// volume with a real one; only the discriminators' hinge terms train the generator.
    Random,
}

/// The optimiser of the generator and the codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Optimiser {
    /// Adam (β 0.9, 0.999, ε 1e-8).
    Adam,
    /// RMSprop with PyTorch's defaults (α 0.99, momentum 0, ε 1e-8), as GRAF and the paper.
    Rmsprop,
}

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
    /// Weight `w` of SART-TV from the mean in the final volume: (1 − w) × the network's
    /// volume (after its sweeps, when they ran) + w × the volume that `refine_iterations`
    /// sweeps make from the mean training volume alone, without the network (the baseline
    /// "SART-TV from the mean"). Both explain the views; where the prior's anatomy is wrong
    /// their errors differ, and the blend shrinks the network's towards the classical
    /// estimate's. 0: the network's volume alone.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mean_sweeps_weight: f64,
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
                n > 0 || c.mean_sweeps_weight == 0.0,
                "0 data-consistency sweeps, but the checkpoint's infer.mean_sweeps_weight = {} \
                 blends in SART-TV from the mean, which needs at least 1",
                c.mean_sweeps_weight
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

/// A training configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    /// Preset or user name.
    pub name: String,
    /// Items per iteration.
    pub batch: usize,
    /// Iterations to train.
    pub iterations: usize,
    /// Generator learning rate (RMSprop, momentum 0, eps 1e-8, alpha 0.99).
    pub lr_g: f64,
    /// Discriminator learning rate.
    pub lr_d: f64,
    /// DAG transformations n (identity included).
    pub n_aug: usize,
    /// DAG weight λ1 of the augmented terms (eq. 11).
    pub lambda1: f64,
    /// Weight λ2 of the projection terms (eq. 12).
    pub lambda2: f64,
    /// Save a checkpoint every this many iterations.
    pub checkpoint_every: usize,
    /// Log metrics every this many iterations.
    pub log_every: usize,
    /// Seed of everything random.
    pub seed: u64,
    /// Training codes: per item (auto-decoder, paired supervision) or random (the paper).
    pub codes: CodeMode,
    /// Optimiser of the generator and the codes (the discriminators use RMSprop).
    pub optimiser: Optimiser,
    /// Learning rate of the per-item codes.
    pub lr_codes: f64,
    /// Weight of the reconstruction loss between V′ and V at the sampled points (L1 plus
    /// the SSIM term); needs per-item codes.
    pub w_volume: f64,
    /// Weight of the reconstruction loss between P′ and P; needs per-item codes.
    pub w_projection: f64,
    /// Weight of the code penalty mean(z²)/2 (keeps codes near N(0, I)).
    pub w_code: f64,
    /// Weight of the generator's hinge terms against D1 and D2 (eqs. 9–12); 0 skips the
    /// discriminators entirely.
    pub w_adversarial: f64,
    /// Network and sampling sizes.
    pub model: ModelConfig,
    /// Inference settings stored with the checkpoint.
    pub infer: InferConfig,
}

const PRESETS: [(&str, &str); 4] = [
    ("tiny", include_str!("../presets/tiny.toml")),
    ("small", include_str!("../presets/small.toml")),
    ("small-gan", include_str!("../presets/small-gan.toml")),
    ("paper", include_str!("../presets/paper.toml")),
];

impl TrainConfig {
    /// A named preset (`tiny`, `small`, `small-gan`, `paper`) or a TOML file path.
    pub fn load(name_or_path: &str) -> Result<Self> {
        if let Some((_, text)) = PRESETS.iter().find(|(n, _)| *n == name_or_path) {
            return Self::parse(text);
        }
        let path = Path::new(name_or_path);
        let text = std::fs::read_to_string(path).map_err(|e| {
            ModelError::file(
                path,
                format!("{e} (not a preset either: tiny, small, small-gan, paper)"),
            )
        })?;
        Self::parse(&text).map_err(|e| ModelError::file(path, e))
    }

    /// Parses and checks TOML.
    pub fn parse(text: &str) -> Result<Self> {
        let c: Self =
            toml::from_str(text).map_err(|e| ModelError::Invalid(format!("config: {e}")))?;
        c.validate()?;
        Ok(c)
    }

    /// A floor under a training step's memory (bytes), from the sizes alone: the field's
    /// parameters held four times (values, gradients, two optimiser moments) and, for every
    /// sample point of a batch (`batch · patch² · samples`), one f32 activation and its
    /// gradient per hidden unit per layer. Measured peaks are 1.7–3.3× this (docs/reliability.md, "Memory budget"); a floor beyond the memory a job may take
    /// is refused before any network is made.
    pub fn memory_floor_bytes(&self) -> f64 {
        let m = &self.model;
        let (w, depth) = (m.hidden as f64, m.depth as f64);
        let inp = (encoded_dims(3, m.freq_x) + m.z_shape) as f64;
        let params = inp * w + (depth - 1.0).max(0.0) * w * w + (w + m.z_app as f64) * w / 2.0;
        let points = self.batch as f64 * (m.patch as f64).powi(2) * m.samples as f64;
        4.0 * 4.0 * params + 2.0 * 4.0 * points * w * (depth + 1.0)
    }

    /// Bytes of one training step's activations and their gradients:
    /// `8 · batch · patch² · samples · hidden · (depth + 1)` (one f32 activation and its
    /// gradient per hidden unit per layer for every sample point of the batch).
    pub fn step_activation_bytes(&self) -> f64 {
        let m = &self.model;
        let points = self.batch as f64 * (m.patch as f64).powi(2) * m.samples as f64;
        8.0 * points * m.hidden as f64 * (m.depth as f64 + 1.0)
    }

    /// Estimated peak memory of training (bytes) on items whose f32 CTs and projections
    /// take `data_bytes`: `21 MiB + (1.25 + 0.21 · [adversarial]) ·`
    /// [`Self::step_activation_bytes`] `+ 1.44 · data_bytes`, the `0.21` when the
    /// discriminators train (`w_adversarial > 0`). Fitted to `/usr/bin/time -v` peaks of
    /// `train` (2 iterations, one thread) with fields of hidden 64–256, 16–64 samples and
    /// batches of 4–8 on 8 items of 64³, 32 of 96³ and 16 of 128³, and the `tiny` preset's
    /// field on 8 items of 16³, 32³ and 64³ (docs/reliability.md, "Memory budget";
    /// `scripts/memory_peaks_train.sh`).
    pub fn training_peak_bytes(&self, data_bytes: u128) -> f64 {
        let adversarial = if self.w_adversarial > 0.0 { 0.21 } else { 0.0 };
        21.0 * (1u64 << 20) as f64
            + (1.25 + adversarial) * self.step_activation_bytes()
            + 1.44 * data_bytes as f64
    }

    /// Estimated peak memory of inference (bytes): a fit, `17 MiB + 1.23 · 8·points·hidden·
    /// (depth + 1) + 12 KiB · view_pixels`, where `points` is the larger ray batch of the
    /// two phases (`code_patch²` and `infer.patch²`, at most the largest view's
    /// `view_pixels`, the whole image for a patch of 0, times `samples`) whose activations
    /// and gradients the backward pass holds, and `view_pixels` the largest view's pixels
    /// (every pixel's ray rendered and swept through the grid). Fitted to `/usr/bin/time
    /// -v` peaks of `reconstruct` with fields of hidden 64 and 256 at 64³ and 96³ (ray
    /// batches of 4 096 and 262 144 points) and the `tiny` preset's field at 16³, 32³ and
    /// 64³ (whole views of 256 to 4 096 pixels), from one view (docs/reliability.md,
    /// "Memory budget"; `scripts/memory_peaks_inference.sh`).
    /// `infer` is the inference's settings (the configuration's, or with a command's
    /// overrides).
    pub fn inference_peak_bytes(&self, infer: &InferConfig, view_pixels: u128) -> f64 {
        let m = &self.model;
        // A patch is at most the image.
        let side = |p: usize| match p {
            0 => view_pixels as f64,
            p => ((p * p) as f64).min(view_pixels as f64),
        };
        let points = side(infer.patch).max(side(infer.code_patch)) * m.samples as f64;
        let activations = 8.0 * points * m.hidden as f64 * (m.depth as f64 + 1.0);
        17.0 * (1u64 << 20) as f64 + 1.23 * activations + 12.0 * 1024.0 * view_pixels as f64
    }

    /// Checks sizes and weights.
    pub fn validate(&self) -> Result<()> {
        let m = &self.model;
        ensure!(
            m.patch >= 4 && m.patch.is_multiple_of(4),
            "patch M = {} must be a positive multiple of 4",
            m.patch
        );
        ensure!(
            m.samples >= 4 && m.samples.is_multiple_of(4),
            "samples Q = {} must be a positive multiple of 4",
            m.samples
        );
        ensure!(
            m.hidden > 0 && m.depth > 0 && m.disc_channels > 0,
            "hidden, depth and disc_channels must be > 0"
        );
        ensure!(self.batch > 0, "batch must be > 0");
        ensure!(
            (1..=4).contains(&self.n_aug),
            "n_aug = {} must be 1..=4 (identity, flip, flip, transpose)",
            self.n_aug
        );
        for (n, v) in [
            ("lr_g", self.lr_g),
            ("lr_d", self.lr_d),
            ("infer.lr", self.infer.lr),
        ] {
            ensure!(v.is_finite() && v > 0.0, "{n} = {v} must be > 0");
        }
        ensure!(
            self.infer.psnr_threshold.is_finite(),
            "infer.psnr_threshold = {} must be a finite number (dB)",
            self.infer.psnr_threshold
        );
        ensure!(
            self.lr_codes.is_finite() && self.lr_codes > 0.0,
            "lr_codes = {} must be > 0",
            self.lr_codes
        );
        for (n, v) in [
            ("w_volume", self.w_volume),
            ("w_projection", self.w_projection),
            ("w_code", self.w_code),
            ("w_adversarial", self.w_adversarial),
            ("infer.w_nll", self.infer.w_nll),
        ] {
            ensure!(v.is_finite() && v >= 0.0, "{n} = {v} must be ≥ 0");
        }
        let paired = self.w_volume + self.w_projection;
        match self.codes {
            CodeMode::PerItem => ensure!(
                paired > 0.0 || self.w_adversarial > 0.0,
                "every loss weight is 0: nothing trains the generator"
            ),
            CodeMode::Random => ensure!(
                paired == 0.0 && self.w_adversarial > 0.0,
                "codes = \"random\" pairs no generated volume with a real one: set w_volume = \
                 w_projection = 0 and w_adversarial > 0, or use codes = \"per-item\""
            ),
        }
        ensure!(
            self.infer.lr_codes.is_finite() && self.infer.lr_codes > 0.0,
            "infer.lr_codes = {} must be > 0",
            self.infer.lr_codes
        );
        ensure!(self.infer.check_every > 0, "infer.check_every must be > 0");
        ensure!(
            (0.0..=1.0).contains(&self.infer.refine_start_weight),
            "infer.refine_start_weight = {} must be in [0, 1] (the fraction of the network \
             volume's attenuation the data-consistency sweeps start from)",
            self.infer.refine_start_weight
        );
        ensure!(
            (0.0..=1.0).contains(&self.infer.refine_start_mean_weight),
            "infer.refine_start_mean_weight = {} must be in [0, 1] (the fraction of the mean \
             training volume's attenuation the data-consistency sweeps start from)",
            self.infer.refine_start_mean_weight
        );
        ensure!(
            self.infer.refine_tv_step.is_finite() && self.infer.refine_tv_step >= 0.0,
            "infer.refine_tv_step = {} must be a finite number ≥ 0 (0: plain SART sweeps)",
            self.infer.refine_tv_step
        );
        ensure!(
            self.infer.refine_always_from_views != Some(0),
            "infer.refine_always_from_views is 0: give a view count of at least 1, or leave it out"
        );
        ensure!(
            (0.0..=1.0).contains(&self.infer.mean_sweeps_weight),
            "infer.mean_sweeps_weight = {} must be in [0, 1] (the weight of SART-TV from the \
             mean in the final volume)",
            self.infer.mean_sweeps_weight
        );
        ensure!(
            self.infer.mean_sweeps_weight == 0.0 || self.infer.refine_iterations > 0,
            "infer.mean_sweeps_weight = {} blends in SART-TV from the mean, which needs \
             refine_iterations ≥ 1 sweeps (it is 0)",
            self.infer.mean_sweeps_weight
        );
        ensure!(
            self.infer.ensemble >= 1,
            "infer.ensemble = 0: give the number of fits to average (1: one fit)"
        );
        ensure!(
            self.infer.ensemble_code_sd.is_finite() && self.infer.ensemble_code_sd >= 0.0,
            "infer.ensemble_code_sd = {} must be a finite number ≥ 0 (the starting codes' \
             spread in training-code standard deviations)",
            self.infer.ensemble_code_sd
        );
        ensure!(
            !self.infer.refine_below_db.is_nan(),
            "infer.refine_below_db is NaN: give a PSNR in dB (inf: always refine)"
        );
        ensure!(
            self.checkpoint_every > 0 && self.log_every > 0,
            "checkpoint_every and log_every must be > 0"
        );
        Ok(())
    }

    /// Checks the positional encoding against a training grid of `voxels` along its
    /// shortest axis: the finest period, 2/2^(freq_x−1) in normalised units, must span at
    /// least 2 voxels (the grid's Nyquist limit), or the field learns a pattern the grid cannot
    /// hold (the grid artefact of earlier models).
    pub fn check_grid(&self, voxels: usize) -> Result<()> {
        let f = self.model.freq_x;
        if f == 0 {
            return Ok(());
        }
        let finest = voxels as f64 / 2f64.powi(f.min(1000) as i32 - 1);
        ensure!(
            f < 64 && voxels >= 1usize << f,
            "freq_x = {f} puts the finest encoding period at {finest} voxel(s) of this {voxels}-voxel \
             grid, above its Nyquist limit (2 voxels); use freq_x ≤ {}",
            (voxels as f64 / 2.0).log2().floor() as usize + 1
        );
        Ok(())
    }

    /// The config as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("config serialises")
    }
}

/// Encoded width of `d` coordinates with `freqs` frequencies (the positional encoding
/// γ: each coordinate and a sine and cosine per frequency), the field's input width.
pub fn encoded_dims(d: usize, freqs: usize) -> usize {
    d * (1 + 2 * freqs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_and_bad_values_are_named() {
        for n in ["tiny", "small", "small-gan", "paper"] {
            let c = TrainConfig::load(n).unwrap();
            assert_eq!(c.name, n);
            assert_eq!(c.lr_g, 5e-4);
            assert_eq!(c.lr_d, 1e-4);
        }
        // The paper's training stays selectable; `small` is the paired, anchored model.
        let gan = TrainConfig::load("small-gan").unwrap();
        assert_eq!(gan.codes, CodeMode::Random);
        assert!(gan.model.view_dependent && !gan.model.mean_anchor);
        let small = TrainConfig::load("small").unwrap();
        assert_eq!(small.codes, CodeMode::PerItem);
        assert!(!small.model.view_dependent && small.model.mean_anchor);
        // Encoding frequencies against the grid's Nyquist limit: small's 6 fit 64 voxels,
        // 8 (the old preset) do not.
        small.check_grid(64).unwrap();
        let mut c8 = small.clone();
        c8.model.freq_x = 8;
        let e = c8.check_grid(64).unwrap_err().to_string();
        assert!(e.contains("freq_x = 8") && e.contains("≤ 6"), "{e}");
        // Random codes cannot take reconstruction losses.
        let mut bad = gan.clone();
        bad.w_volume = 1.0;
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains("pairs no generated volume"), "{e}");
        let mut c = TrainConfig::load("tiny").unwrap();
        c.model.patch = 6;
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("patch M = 6"), "{e}");
        // The sweeps' TV step: a preset's default is SART-TV's; a negative one is refused.
        let mut c = TrainConfig::load("tiny").unwrap();
        assert_eq!(c.infer.refine_tv_step, 0.2);
        c.infer.refine_tv_step = -0.1;
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("refine_tv_step = -0.1"), "{e}");
        // The open gate from N views: absent in the presets; 0 views is refused by name.
        let mut c = TrainConfig::load("tiny").unwrap();
        assert_eq!(c.infer.refine_always_from_views, None);
        c.infer.refine_always_from_views = Some(0);
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("refine_always_from_views is 0"), "{e}");
        // The gate: projection by default and left out of a written config; "held-out" read
        // back; an unknown gate named.
        let c = TrainConfig::load("tiny").unwrap();
        assert_eq!(c.infer.refine_gate, RefineGate::Projection);
        let text = toml::to_string(&c).unwrap();
        assert!(!text.contains("refine_gate"), "{text}");
        let held = text.replace("[infer]\n", "[infer]\nrefine_gate = \"held-out\"\n");
        assert_eq!(
            TrainConfig::parse(&held).unwrap().infer.refine_gate,
            RefineGate::HeldOut
        );
        let e =
            TrainConfig::parse(&text.replace("[infer]\n", "[infer]\nrefine_gate = \"views\"\n"))
                .unwrap_err()
                .to_string();
        assert!(e.contains("views") && e.contains("held-out"), "{e}");
        let o = InferOverrides {
            refine_tv_step: Some(f64::NAN),
            ..InferOverrides::default()
        };
        assert!(
            TrainConfig::load("tiny")
                .unwrap()
                .infer
                .overridden(&o)
                .is_err()
        );
        let e = TrainConfig::load("/nonexistent.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a preset"), "{e}");
    }
}
