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

/// Inference (eq. 13): fine-tuning until a PSNR threshold or an iteration cap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InferConfig {
    /// Iteration cap.
    pub iterations: usize,
    /// Stop when every reference view's PSNR (dB, projections scaled to [0, 1]) reaches this.
    pub psnr_threshold: f64,
    /// RMSprop learning rate.
    pub lr: f64,
    /// Rays per iteration: a `patch`×`patch` patch at a random scale; 0 = the full image
    /// (the paper's choice; costly on a CPU).
    pub patch: usize,
    /// Codes only, or codes and generator.
    pub tune: Tune,
}

impl InferConfig {
    /// This config with the given settings overridden (`None` keeps the config's); the
    /// stopping threshold (dB) must be finite.
    pub fn overridden(
        &self,
        tune: Option<Tune>,
        iterations: Option<usize>,
        psnr_threshold: Option<f64>,
    ) -> Result<Self> {
        let mut c = self.clone();
        if let Some(t) = tune {
            c.tune = t;
        }
        if let Some(n) = iterations {
            c.iterations = n;
        }
        if let Some(db) = psnr_threshold {
            ensure!(
                db.is_finite(),
                "inference PSNR threshold {db} dB must be a finite number"
            );
            c.psnr_threshold = db;
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
    /// Network and sampling sizes.
    pub model: ModelConfig,
    /// Inference settings stored with the checkpoint.
    pub infer: InferConfig,
}

const PRESETS: [(&str, &str); 3] = [
    ("tiny", include_str!("../presets/tiny.toml")),
    ("small", include_str!("../presets/small.toml")),
    ("paper", include_str!("../presets/paper.toml")),
];

impl TrainConfig {
    /// A named preset (`tiny`, `small`, `paper`) or a TOML file path.
    pub fn load(name_or_path: &str) -> Result<Self> {
        if let Some((_, text)) = PRESETS.iter().find(|(n, _)| *n == name_or_path) {
            return Self::parse(text);
        }
        let path = Path::new(name_or_path);
        let text = std::fs::read_to_string(path).map_err(|e| {
            ModelError::file(
                path,
                format!("{e} (not a preset either: tiny, small, paper)"),
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
            self.checkpoint_every > 0 && self.log_every > 0,
            "checkpoint_every and log_every must be > 0"
        );
        Ok(())
    }

    /// The config as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("config serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_and_bad_values_are_named() {
        for n in ["tiny", "small", "paper"] {
            let c = TrainConfig::load(n).unwrap();
            assert_eq!(c.name, n);
            assert_eq!(c.lr_g, 5e-4);
            assert_eq!(c.lr_d, 1e-4);
        }
        let mut c = TrainConfig::load("tiny").unwrap();
        c.model.patch = 6;
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("patch M = 6"), "{e}");
        let e = TrainConfig::load("/nonexistent.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a preset"), "{e}");
    }
}
