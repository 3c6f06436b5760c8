//! A projection run (`tomograf project`, Python's `tomograf.project`): a [`Scene`] rendered
//! view by view into its output folder — the images in every format the scene asks for,
//! the separate primary/scatter images, the dose, and the JSON sidecar that records each
//! view's geometry and the physics, so that any image can be reproduced.

use crate::outputs::scatter::ScatterWriters;
use crate::outputs::{self, Outputs};
use crate::progress::Progress;
use crate::scene::Scene;
use anyhow::{Result, bail};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tomograf_datasets::sidecar::{self, PixelQuantity};
use tomograf_physics::detector::Clipping;
use tomograf_sim::Projection;

/// What a run did.
#[derive(Debug, Clone)]
pub struct Summary {
    /// Views rendered.
    pub views: usize,
    /// Detector rows × columns of the first view (0 × 0 without views).
    pub rows: usize,
    pub cols: usize,
    /// Time spent rendering (all views), s.
    pub render_seconds: f64,
    /// Time spent reading the volume, s.
    pub load_seconds: f64,
    /// Files written.
    pub files: usize,
    /// The job's estimated peak memory, bytes (what it was checked against the limit with).
    pub peak_bytes: u128,
    /// The output folder.
    pub dir: PathBuf,
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "rendered {} view(s) of {}×{} in {:.1} ms ({:.1} ms per view; loading {:.0} ms); \
             wrote {} file(s) to {} (estimated peak memory {:.0} MiB)",
            self.views,
            self.rows,
            self.cols,
            self.render_seconds * 1e3,
            self.render_seconds * 1e3 / self.views.max(1) as f64,
            self.load_seconds * 1e3,
            self.files,
            self.dir.display(),
            self.peak_bytes as f64 / (1u64 << 20) as f64
        )
    }
}

/// Renders every view of `scene` and writes its outputs (stage "view" of `progress`;
/// geometry probably not meant and clipped pixels go to [`Progress::warn`]).
/// A warning when every pixel of every view holds one value: nothing in the beam attenuates
/// (an all-air volume, a threshold above every voxel, a volume far from the beam), so the
/// images say nothing.
fn constant_images(channels: &[Vec<Projection>]) -> Option<String> {
    let mut values = channels.iter().flatten().flat_map(|p| p.data.iter());
    let first = *values.next()?;
    values.all(|v| *v == first).then(|| {
        format!(
            "warning: every pixel of every view is {first}: nothing in the beam attenuates \
             (an all-air volume, [projector] empty_below_per_mm (--empty-below) above every \
             voxel, or a volume out of the beam), or every pixel is at the detector's ceiling \
             (a warning above says so: lower the exposure)"
        )
    })
}

pub fn project(scene: &Scene, progress: &dyn Progress) -> Result<Summary> {
    let outputs = Outputs::from_scene(scene)?;
    let prepared = crate::prepare(scene)?;
    for w in &prepared.warnings {
        progress.warn(w);
    }
    let renderer = prepared.renderer()?;
    let (job, acquisition) = (&prepared.job, &prepared.acquisition);
    outputs.prepare()?;
    let mut separate = ScatterWriters::new(
        &outputs,
        scene.scatter.as_ref().map_or(&[][..], |s| &s.images[..]),
    );
    progress.start("view", job.views.len() as u64, 0);
    let mut render_time = Duration::ZERO;
    let mut clipping = Clipping::default();
    let mut channels: Vec<Vec<Projection>> = Vec::new();
    let mut channel_outputs: Vec<Outputs> = Vec::new();
    for (i, view) in job.views.iter().enumerate() {
        let t = Instant::now();
        let crate::Frame { images, parts } = renderer.render(i, view)?;
        render_time += t.elapsed();
        if let Some(parts) = &parts {
            separate.write_view(i, parts)?;
            clipping.add(
                parts.clipped,
                parts.saturated,
                images.iter().map(|p| p.data.len()).sum(),
            );
        }
        if channel_outputs.is_empty() {
            channel_outputs = (0..images.len())
                .map(|c| outputs.for_channel(c, images.len()))
                .collect();
            channels = vec![Vec::with_capacity(job.views.len()); images.len()];
        }
        for ((img, out), stack) in images.into_iter().zip(&channel_outputs).zip(&mut channels) {
            // Nothing non-finite is written (f32 overflow of a huge I0, μ or exposure).
            if let Some(v) = img.data.iter().find(|v| !v.is_finite()) {
                bail!(
                    "view {i}: a pixel is {v}: the image overflows float32 — lower the \
                     exposure, I0 or the attenuation that produced it; nothing was written \
                     for this view"
                );
            }
            out.write_view(i, &img)?;
            stack.push(img);
        }
        progress.inc();
    }
    progress.finish();
    if let Some(w) = constant_images(&channels) {
        progress.warn(&w);
    }
    let mut sidecar = outputs::sidecar(&prepared.source, job);
    if let Some((acq, seed)) = acquisition {
        sidecar.quantity = PixelQuantity::Described("detector signal (see acquisition)".into());
        sidecar.acquisition = Some(sidecar::acquisition_record(acq, *seed)?);
        sidecar.clipped_pixels = Some(clipping.clipped as u64);
        sidecar.saturated_pixels = Some(clipping.saturated as u64);
        if let Some(w) = clipping.warning(
            acq.spectrum.mas,
            "[spectrum] mas or --mas",
            acq.detector.has_signal_unit(),
        ) {
            progress.warn(&w);
        }
    }
    let mut files = 0;
    for (c, (out, images)) in channel_outputs.iter().zip(&channels).enumerate() {
        let mut sc = sidecar.clone();
        if channel_outputs.len() > 1 {
            sc.channel = Some(c);
        }
        files += out.finish(images, sc)?;
    }
    if !separate.is_empty() {
        files += separate.finish(&sidecar)?;
    }
    if let Some(d) = &scene.dose {
        files += outputs::dose::write(
            d,
            acquisition.as_ref(),
            &prepared.volume,
            &job.views,
            &outputs,
            progress,
        )?;
    }
    Ok(Summary {
        views: job.views.len(),
        rows: job.views.first().map_or(0, |v| v.rows),
        cols: job.views.first().map_or(0, |v| v.cols),
        render_seconds: render_time.as_secs_f64(),
        load_seconds: prepared.load_seconds,
        files,
        dir: outputs.dir.clone(),
        peak_bytes: prepared.peak_bytes,
    })
}
