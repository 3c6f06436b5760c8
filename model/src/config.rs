//! Training and inference configurations, as TOML; presets `tiny`, `small`, `medium`,
//! `small-gan`, `paper`.

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

pub use crate::infer_config::{InferConfig, InferOverrides, RefineGate, RefineStart, Tune};

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

const PRESETS: [(&str, &str); 5] = [
    ("tiny", include_str!("../presets/tiny.toml")),
    ("small", include_str!("../presets/small.toml")),
    ("medium", include_str!("../presets/medium.toml")),
    ("small-gan", include_str!("../presets/small-gan.toml")),
    ("paper", include_str!("../presets/paper.toml")),
];

impl TrainConfig {
    /// A named preset (`tiny`, `small`, `medium`, `small-gan`, `paper`) or a TOML file path.
    pub fn load(name_or_path: &str) -> Result<Self> {
        if let Some((_, text)) = PRESETS.iter().find(|(n, _)| *n == name_or_path) {
            return Self::parse(text);
        }
        let path = Path::new(name_or_path);
        let text = std::fs::read_to_string(path).map_err(|e| {
            ModelError::file(
                path,
                format!("{e} (not a preset either: tiny, small, medium, small-gan, paper)"),
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
            self.infer.mean_sweeps_below_db.is_some()
                == self.infer.mean_sweeps_weight_below.is_some(),
            "infer.mean_sweeps_below_db and infer.mean_sweeps_weight_below go together: give \
             both (the PSNR in dB below which the blend's weight changes, and that weight) or \
             neither"
        );
        if let Some(db) = self.infer.mean_sweeps_below_db {
            ensure!(
                db.is_finite(),
                "infer.mean_sweeps_below_db = {db} must be a finite PSNR in dB"
            );
        }
        if let Some(w) = self.infer.mean_sweeps_weight_below {
            ensure!(
                (0.0..=1.0).contains(&w),
                "infer.mean_sweeps_weight_below = {w} must be in [0, 1] (the weight of SART-TV \
                 from the mean when the views are explained below mean_sweeps_below_db)"
            );
        }
        ensure!(
            self.infer.mean_sweeps_weight_max() == 0.0 || self.infer.refine_iterations > 0,
            "infer.mean_sweeps_weight = {} (mean_sweeps_weight_below = {:?}) blends in SART-TV \
             from the mean, which needs refine_iterations ≥ 1 sweeps (it is 0)",
            self.infer.mean_sweeps_weight,
            self.infer.mean_sweeps_weight_below
        );
        ensure!(
            self.infer.mean_sweeps_spread.is_finite() && self.infer.mean_sweeps_spread >= 0.0,
            "infer.mean_sweeps_spread = {} must be a finite number ≥ 0 (the fits' spread, in \
             normalised density, at which the blend's weight is half of mean_sweeps_weight; \
             0: a constant weight)",
            self.infer.mean_sweeps_spread
        );
        ensure!(
            self.infer.ensemble >= 1,
            "infer.ensemble = 0: give the number of fits to average (1: one fit)"
        );
        ensure!(
            self.infer.ensemble_max_views != Some(0),
            "infer.ensemble_max_views = 0 would average fits for no view count: give the \
             most views (1: one view only) or leave it out (every view count)"
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
        for n in ["tiny", "small", "medium", "small-gan", "paper"] {
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
        // `medium` is `small` at twice the grid: the same training, rays sampled and
        // encoded for 128 voxels (7 frequencies fit them, 8 do not).
        let medium = TrainConfig::load("medium").unwrap();
        medium.check_grid(128).unwrap();
        assert!(medium.check_grid(64).is_err());
        let mut m8 = medium.clone();
        m8.model.freq_x = 8;
        assert!(m8.check_grid(128).is_err());
        let mut same = medium.clone();
        (same.name, same.model.samples, same.model.freq_x) = (small.name.clone(), 32, 6);
        assert_eq!(same.to_toml(), small.to_toml());
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
