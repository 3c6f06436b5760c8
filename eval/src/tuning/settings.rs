//! `baselines.toml`: each method's settings per view count, as a search chose them.

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;
use tomograf_model::baseline::SartTvSettings;
use tomograf_model::pca::PcaSettings;
use tomograf_recon::Window;

/// File name of the chosen settings in a tuning's output folder.
pub const FILE: &str = "baselines.toml";

/// The method names, as the evaluation tables print them.
pub const SART_TV: &str = "SART-TV";
pub const SART_TV_FROM_MEAN: &str = "SART-TV from the mean";
pub const PCA_MAP: &str = "PCA-MAP prior";
pub const FDK: &str = "FDK";
/// TomoGRAF's final volume (its network, then its data-consistency sweeps).
pub const TOMOGRAF: &str = "TomoGRAF";

/// Every baseline's settings for one view count, and TomoGRAF's sweeps when a checkpoint
/// was searched too.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewSettings {
    pub sart_tv: SartTvSettings,
    pub sart_tv_from_mean: SartTvSettings,
    pub pca_map: PcaSettings,
    /// FDK's ramp-filter window.
    pub fdk_window: Window,
    /// TomoGRAF's data-consistency sweeps (`None`: the checkpoint's own), for the checkpoint
    /// the search ran (`tomograf tune-baselines --checkpoint`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tomograf_sweeps: Option<SartTvSettings>,
}

impl ViewSettings {
    pub(super) fn validate(&self) -> Result<()> {
        self.sart_tv.options(1)?;
        self.sart_tv_from_mean.options(1)?;
        self.pca_map.validate()?;
        if let Some(s) = &self.tomograf_sweeps {
            s.options(1)?;
        }
        Ok(())
    }
}

/// `baselines.toml`: the settings per view count and what chose them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaselineSettings {
    /// The validation data (and training data) the search ran on.
    pub tuned_on: String,
    /// How the winner was chosen.
    pub rule: String,
    /// Settings per view count (keys "1", "2", …).
    pub views: BTreeMap<String, ViewSettings>,
}

impl BaselineSettings {
    /// Reads and checks a `baselines.toml`; errors name the file and the bad entry.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read the baselines' settings {}", path.display()))?;
        let s: Self = toml::from_str(&text).with_context(|| {
            format!(
                "{} is not a baselines.toml (written by `tomograf tune-baselines`)",
                path.display()
            )
        })?;
        if s.views.is_empty() {
            bail!("{}: no view counts tuned", path.display());
        }
        for (k, v) in &s.views {
            if !k.parse::<usize>().is_ok_and(|n| n >= 1) {
                bail!("{}: view count '{k}' is not a number ≥ 1", path.display());
            }
            v.validate()
                .with_context(|| format!("{}, views {k}", path.display()))?;
        }
        Ok(s)
    }

    /// The settings for `count` views; an error naming the counts tuned.
    pub fn for_views(&self, count: usize) -> Result<ViewSettings> {
        self.views
            .get(&count.to_string())
            .copied()
            .with_context(|| {
                format!(
                    "the baselines were tuned for {} view(s), not {count}: tune them for it \
                 (`tomograf tune-baselines --views …`) or leave out --baselines",
                    self.views.keys().cloned().collect::<Vec<_>>().join(", ")
                )
            })
    }
}
