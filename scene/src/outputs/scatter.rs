//! The separate primary / scatter images `tomograf project` writes beside its main output
//! (the scene's `[scatter] images`, [`crate::scatter`]).
//!
//! `[scatter]` holds the simulator's [`ScatterModel`] (`model`, `photons`, `grid`, …) plus
//! two keys of its own: `images` (which separate images to write) and the
//! `[scatter.anti_scatter_grid]` table ([`AntiScatterGrid`], which goes to the
//! acquisition). Each image is the **expected** (noiseless) detector signal per channel,
//! in the raw signal units of [`tomograf_physics::detector::ExpectedImage`] (before blur, gain
//! and noise): `primary`, `compton` (single Compton), `rayleigh` (single Rayleigh),
//! `multiple`, `scatter` (their sum) and `total` (primary + scatter). They are written as
//! `{prefix}_{image}_NNN.<ext>`, `{prefix}_{image}.npy` and `{prefix}_{image}.json` (with
//! `_ch{c}` after the image name for multi-channel detectors), in the main output's formats.

use super::Outputs;
use crate::scatter::ScatterImage;
use anyhow::Result;
use tomograf_datasets::sidecar::{PixelQuantity, Sidecar};
use tomograf_physics::acquisition::{Acquired, add_into};
use tomograf_physics::detector::ExpectedImage;
use tomograf_sim::Projection;

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
