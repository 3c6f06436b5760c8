//! The scene's `[scatter]` table: the simulator's [`ScatterModel`] (`model`, `photons`,
//! `grid`, …) plus two keys of its own: `images` (which separate images `tomograf project`
//! writes beside its main output) and the `[scatter.anti_scatter_grid]` table
//! ([`AntiScatterGrid`], which goes to the acquisition). Each image is the **expected**
//! (noiseless) detector signal per channel, in the raw signal units of
//! [`tomograf_physics::detector::ExpectedImage`] (before blur, gain and noise): `primary`,
//! `compton` (single Compton), `rayleigh` (single Rayleigh), `multiple`, `scatter` (their
//! sum) and `total` (primary + scatter).

use anyhow::{Result, bail};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use tomograf_physics::scatter::{AntiScatterGrid, ScatterModel};
/// One separate image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ScatterImage {
    /// The primary (unscattered) signal.
    Primary,
    /// Photons scattered once, by Compton.
    Compton,
    /// Photons scattered once, by Rayleigh.
    Rayleigh,
    /// Photons scattered two or more times.
    Multiple,
    /// All scatter (Compton + Rayleigh + multiple).
    Scatter,
    /// Primary + all scatter.
    Total,
}

impl ScatterImage {
    /// The name used in file names and the scene.
    pub fn name(self) -> &'static str {
        match self {
            Self::Primary => "primary",
            Self::Compton => "compton",
            Self::Rayleigh => "rayleigh",
            Self::Multiple => "multiple",
            Self::Scatter => "scatter",
            Self::Total => "total",
        }
    }

    /// Whether the image needs the scatter model to be something other than `none`.
    pub fn needs_scatter(self) -> bool {
        !matches!(self, Self::Primary | Self::Total)
    }
}

/// The `[scatter]` table: the model, which images to write, and the anti-scatter grid.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScatterSection {
    /// How scatter is modelled.
    pub model: ScatterModel,
    /// Separate images to write (none by default).
    pub images: Vec<ScatterImage>,
    /// An anti-scatter grid in front of the detector.
    pub anti_scatter_grid: Option<AntiScatterGrid>,
}

impl ScatterSection {
    /// Checks the section: the model's settings, the grid's, and that scatter images are
    /// only asked for when scatter is modelled.
    pub fn validate(&self) -> Result<()> {
        self.model.validate()?;
        if let Some(g) = &self.anti_scatter_grid {
            g.validate()?;
        }
        if self.model.is_none()
            && let Some(i) = self.images.iter().find(|i| i.needs_scatter())
        {
            bail!(
                "[scatter] images asks for '{}' but model = \"none\": choose model = \
                 \"monte-carlo\" or \"estimate\"",
                i.name()
            );
        }
        Ok(())
    }
}

impl<'de> Deserialize<'de> for ScatterSection {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let mut t = toml::Table::deserialize(d)?;
        let images = match t.remove("images") {
            Some(v) => {
                let mut images = Vec::<ScatterImage>::deserialize(v)
                    .map_err(|e| D::Error::custom(format!("[scatter] images: {e}")))?;
                let mut seen = Vec::new();
                images.retain(|i| {
                    let new = !seen.contains(i);
                    seen.push(*i);
                    new
                });
                images
            }
            None => Vec::new(),
        };
        let anti_scatter_grid = t
            .remove("anti_scatter_grid")
            .map(AntiScatterGrid::deserialize)
            .transpose()
            .map_err(|e| D::Error::custom(format!("[scatter.anti_scatter_grid]: {e}")))?;
        // `model = "none"` is a unit variant: serde would drop any other key silently.
        if t.get("model").and_then(|m| m.as_str()) == Some("none") && t.len() > 1 {
            let extra: Vec<&str> = t
                .keys()
                .filter(|k| *k != "model")
                .map(|k| k.as_str())
                .collect();
            return Err(D::Error::custom(format!(
                "[scatter]: model = \"none\" takes no settings, found `{}` (choose model = \
                 \"estimate\" or \"monte-carlo\", or remove them)",
                extra.join("`, `")
            )));
        }
        let model = if t.is_empty() {
            ScatterModel::None
        } else {
            ScatterModel::deserialize(toml::Value::Table(t))
                .map_err(|e| D::Error::custom(format!("[scatter]: {e}")))?
        };
        Ok(Self {
            model,
            images,
            anti_scatter_grid,
        })
    }
}

impl Serialize for ScatterSection {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::Error as _;
        let mut t = match toml::Value::try_from(&self.model).map_err(S::Error::custom)? {
            toml::Value::Table(t) => t,
            _ => return Err(S::Error::custom("the scatter model is not a table")),
        };
        if !self.images.is_empty() {
            t.insert(
                "images".into(),
                toml::Value::try_from(&self.images).map_err(S::Error::custom)?,
            );
        }
        if let Some(g) = &self.anti_scatter_grid {
            t.insert(
                "anti_scatter_grid".into(),
                toml::Value::try_from(g).map_err(S::Error::custom)?,
            );
        }
        t.serialize(s)
    }
}
