//! The scene's `[scatter]` table as the CLI reads it, and the separate primary / scatter
//! images `tomograf project` writes beside its main output.
//!
//! `[scatter]` holds the simulator's [`ScatterModel`] (`model`, `photons`, `grid`, …) plus
//! two keys of its own: `images` (which separate images to write) and the
//! `[scatter.anti_scatter_grid]` table ([`AntiScatterGrid`], which goes to the
//! acquisition). Each image is the **expected** (noiseless) detector signal per channel,
//! in the raw signal units of [`tomograf_sim::detector::ExpectedImage`] (before blur, gain
//! and noise): `primary`, `compton` (single Compton), `rayleigh` (single Rayleigh),
//! `multiple`, `scatter` (their sum) and `total` (primary + scatter). They are written as
//! `{prefix}_{image}_NNN.<ext>`, `{prefix}_{image}.npy` and `{prefix}_{image}.json` (with
//! `_ch{c}` after the image name for multi-channel detectors), in the main output's formats.

use crate::output::Outputs;
use anyhow::{Result, bail};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use tomograf_datasets::sidecar::{PixelQuantity, Sidecar};
use tomograf_sim::Projection;
use tomograf_sim::acquisition::{Acquired, add_into};
use tomograf_sim::detector::ExpectedImage;
use tomograf_sim::scatter::{AntiScatterGrid, ScatterModel};

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
    fn needs_scatter(self) -> bool {
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

/// The writers of the separate images of a run, and the stacks they collect.
pub struct ScatterWriters {
    /// Per image: its outputs per channel and the images collected per channel.
    sets: Vec<(ScatterImage, Vec<Outputs>, Vec<Vec<Projection>>)>,
}

impl ScatterWriters {
    /// Writers for `images` beside `main` (same folder, formats and window).
    pub fn new(main: &Outputs, images: &[ScatterImage]) -> Self {
        let sets = images
            .iter()
            .map(|&i| {
                let out = Outputs {
                    dir: main.dir.clone(),
                    prefix: format!("{}_{}", main.prefix, i.name()),
                    formats: main.formats.clone(),
                    window: None,
                };
                (i, vec![out], Vec::new())
            })
            .collect();
        Self { sets }
    }

    /// Whether there is nothing to write.
    pub fn is_empty(&self) -> bool {
        self.sets.is_empty()
    }

    /// Writes view `index`'s separate images from the parts of its acquisition.
    pub fn write_view(&mut self, index: usize, parts: &Acquired) -> Result<()> {
        for (kind, outs, stacks) in &mut self.sets {
            let image = compose(*kind, parts)?;
            let channels = image.channels;
            if stacks.is_empty() {
                let base = outs.remove(0);
                *outs = (0..channels)
                    .map(|c| base.for_channel(c, channels))
                    .collect();
                *stacks = vec![Vec::new(); channels];
            }
            for (c, (out, stack)) in outs.iter().zip(stacks.iter_mut()).enumerate() {
                let p = channel(&image, c);
                out.write_view(index, &p)?;
                stack.push(p);
            }
        }
        Ok(())
    }

    /// Writes the NPY stacks and sidecars (each `sidecar` plus what the image holds);
    /// returns the number of files written.
    pub fn finish(&self, sidecar: &Sidecar) -> Result<usize> {
        let mut files = 0;
        for (kind, outs, stacks) in &self.sets {
            for (c, (out, stack)) in outs.iter().zip(stacks).enumerate() {
                let mut sc = sidecar.clone();
                sc.quantity = PixelQuantity::Described(format!(
                    "expected detector signal (noiseless mean, raw signal units, before blur, \
                     gain and noise): {}",
                    kind.name()
                ));
                if outs.len() > 1 {
                    sc.channel = Some(c);
                }
                files += out.finish(stack, sc)?;
            }
        }
        Ok(files)
    }
}

/// The expected image `kind` from one view's parts.
fn compose(kind: ScatterImage, parts: &Acquired) -> Result<ExpectedImage> {
    let scatter = || {
        parts.scatter.as_ref().ok_or_else(|| {
            anyhow::anyhow!("[scatter] image '{}' needs a scatter model", kind.name())
        })
    };
    Ok(match kind {
        ScatterImage::Primary => parts.primary.clone(),
        ScatterImage::Compton => scatter()?.single_compton.clone(),
        ScatterImage::Rayleigh => scatter()?.single_rayleigh.clone(),
        ScatterImage::Multiple => scatter()?.multiple.clone(),
        ScatterImage::Scatter => scatter()?.total(),
        ScatterImage::Total => {
            let mut t = parts.primary.clone();
            if let Some(s) = &parts.scatter {
                add_into(&mut t, &s.total());
            }
            t
        }
    })
}

/// Channel `c`'s mean as a projection.
fn channel(image: &ExpectedImage, c: usize) -> Projection {
    let n = image.rows * image.cols;
    Projection {
        rows: image.rows,
        cols: image.cols,
        data: image.mean[c * n..(c + 1) * n]
            .iter()
            .map(|&v| v as f32)
            .collect(),
    }
}
