//! Output files of a projection run ([`crate::project`], `tomograf project`): per-view EXR / TIFF / PNG, one NPY stack, and the
//! JSON sidecar that records every view's geometry so any image can be reproduced.
//!
//! Every file is written to a temporary name and renamed into place, so an interrupted
//! run never leaves a half-written file.

pub mod dose;
pub mod scatter;

use crate::job::Job;
use crate::scene::Scene;
use crate::volume::VolumeSource;
use anyhow::{Context, Result, bail};
use serde::Serialize;
use std::path::PathBuf;
use tomograf_datasets::image;
use tomograf_datasets::sidecar::{FilesRecord, Sidecar, ViewRecord};
use tomograf_sim::Projection;

/// An output file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// 32-bit float OpenEXR, one channel "Y", one file per view.
    Exr,
    /// 32-bit float TIFF, one file per view.
    Tiff,
    /// One `.npy` stack of shape (views, rows, cols), little-endian f32.
    Npy,
    /// 8-bit grey PNG preview per view, windowed.
    Png,
}

impl Format {
    /// The format's name, as `--format` takes it and the sidecar records it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Exr => "exr",
            Self::Tiff => "tiff",
            Self::Npy => "npy",
            Self::Png => "png",
        }
    }

    /// The format named `name` (case-insensitive; `tif` is `tiff`).
    pub fn parse(name: &str) -> Result<Self> {
        Ok(match name.trim().to_ascii_lowercase().as_str() {
            "exr" => Self::Exr,
            "tiff" | "tif" => Self::Tiff,
            "npy" => Self::Npy,
            "png" => Self::Png,
            other => bail!("unknown output format '{other}': use exr, tiff, npy or png"),
        })
    }
}

/// Formats by name (`exr`, `tiff`/`tif`, `npy`, `png`).
pub fn parse_formats(names: &[String]) -> Result<Vec<Format>> {
    names.iter().map(|n| Format::parse(n)).collect()
}

/// Where and how images are written.
pub struct Outputs {
    pub dir: PathBuf,
    pub prefix: String,
    pub formats: Vec<Format>,
    pub window: Option<[f32; 2]>,
}

impl Outputs {
    /// The outputs the scene's `[output]` table asks for (default: exr, npy, png into
    /// `out/` with prefix `drr`).
    pub fn from_scene(scene: &Scene) -> Result<Self> {
        let o = &scene.output;
        let names = o
            .formats
            .clone()
            .unwrap_or_else(|| vec!["exr".into(), "npy".into(), "png".into()]);
        let mut formats = parse_formats(&names)?;
        formats.dedup();
        if formats.is_empty() {
            bail!("no output format given");
        }
        let prefix = o.prefix.clone().unwrap_or_else(|| "drr".into());
        if prefix.is_empty() || prefix.contains(['/', '\\']) {
            bail!("output prefix '{prefix}' must be a non-empty file name without slashes");
        }
        if let Some([lo, hi]) = o.window
            && (lo >= hi || lo.is_nan() || hi.is_nan())
        {
            bail!("PNG window [{lo}, {hi}] must have LOW < HIGH");
        }
        Ok(Self {
            dir: o.dir.clone().unwrap_or_else(|| "out".into()),
            prefix,
            formats,
            window: o.window,
        })
    }

    /// Creates the output folder.
    pub fn prepare(&self) -> Result<()> {
        std::fs::create_dir_all(&self.dir)
            .with_context(|| format!("cannot create output folder {}", self.dir.display()))
    }

    fn path(&self, view: usize, ext: &str) -> PathBuf {
        self.dir.join(format!("{}_{view:03}.{ext}", self.prefix))
    }

    /// Writes the per-view files of view `index`.
    pub fn write_view(&self, index: usize, img: &Projection) -> Result<()> {
        for f in &self.formats {
            match f {
                Format::Exr => image::write_exr(&self.path(index, "exr"), img)?,
                Format::Tiff => image::write_tiff(&self.path(index, "tiff"), img)?,
                Format::Png => {
                    let (lo, hi) = match self.window {
                        Some([lo, hi]) => (lo, hi),
                        None => auto_window(img),
                    };
                    image::write_png(&self.path(index, "png"), img, (lo, hi))?
                }
                Format::Npy => {}
            }
        }
        Ok(())
    }

    /// The outputs of detector channel `c` of `n`: the same, with `_ch{c}` added to the
    /// prefix when there is more than one channel.
    pub fn for_channel(&self, c: usize, n: usize) -> Self {
        Self {
            dir: self.dir.clone(),
            prefix: if n > 1 {
                format!("{}_ch{c}", self.prefix)
            } else {
                self.prefix.clone()
            },
            formats: self.formats.clone(),
            window: self.window,
        }
    }

    /// Writes the NPY stack and the sidecar (with the files written); returns the number
    /// of files written in all.
    pub fn finish(&self, images: &[Projection], mut sidecar: Sidecar) -> Result<usize> {
        let per_view = self.formats.iter().filter(|f| **f != Format::Npy).count();
        let mut files = per_view * images.len();
        if self.formats.contains(&Format::Npy) && !images.is_empty() {
            let (rows, cols) = (images[0].rows, images[0].cols);
            if images.iter().any(|i| i.rows != rows || i.cols != cols) {
                bail!(
                    "views have different detector sizes; they cannot share one .npy stack (use exr or tiff)"
                );
            }
            let data: Vec<f32> = images.iter().flat_map(|i| i.data.iter().copied()).collect();
            image::write_npy(
                &self.dir.join(format!("{}.npy", self.prefix)),
                &data,
                &[images.len(), rows, cols],
            )?;
            files += 1;
        }
        sidecar.files = Some(FilesRecord {
            formats: self.formats.iter().map(|f| f.name().to_string()).collect(),
            per_view: format!("{}_NNN.<ext> (NNN = view index)", self.prefix),
            npy_stack: self
                .formats
                .contains(&Format::Npy)
                .then(|| format!("{}.npy", self.prefix)),
            png_window: self
                .window
                .map_or("per-image min..max".to_string(), |w| format!("{w:?}")),
        });
        sidecar.write(&self.dir.join(format!("{}.json", self.prefix)))?;
        Ok(files + 1)
    }
}

/// Min..max of an image (or [v, v+1] for a constant image).
fn auto_window(img: &Projection) -> (f32, f32) {
    let (lo, hi) = img
        .data
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if hi > lo { (lo, hi) } else { (lo, lo + 1.0) }
}

/// The sidecar of a `project` run (before its `files`), from the volume and the job.
pub fn sidecar(volume: &VolumeSource, job: &Job) -> Sidecar {
    let views = job
        .views
        .iter()
        .enumerate()
        .map(|(index, view)| ViewRecord {
            index,
            pose: job.poses.get(index).copied(),
            view: *view,
        })
        .collect();
    let mut sidecar = Sidecar::new(
        volume.clone(),
        job.projector,
        job.skipping,
        job.quantity,
        job.geometry,
        views,
    );
    sidecar.tracer = job.tracer;
    sidecar
}
