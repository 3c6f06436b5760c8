//! `tomograf reconstruct`: a CT from 1–10 projections of a data-set item with a trained
//! checkpoint, written as NIfTI in HU.

use crate::progress::Bar;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use tomograf_eval::protocol::{
    ItemReconstruction, paper_poses, reconstruct_item, spread_hu, write_hu,
};
use tomograf_model::config::{InferOverrides, Tune};
use tomograf_model::scatter_correction::ScatterCorrection;
use tomograf_sim::geometry::angles::parse_pose;

/// Flags that override a checkpoint's inference settings (`reconstruct`, `evaluate`).
#[derive(Debug, Args, Clone, Default)]
pub struct InferArgs {
    /// What to fine-tune: codes-and-generator (default, as the paper) or codes.
    #[arg(long)]
    pub tune: Option<Tune>,
    /// Override the checkpoint's inference iteration cap.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Override the checkpoint's inference stopping threshold: the PSNR (dB) every input
    /// view's rendered rays must reach (the paper's 25).
    #[arg(long, allow_negative_numbers = true)]
    pub psnr_threshold: Option<f64>,
    /// Override the checkpoint's data-consistency sweeps after the network's fit (SART-TV
    /// started from the network's volume; 0 = the network's volume as it is).
    #[arg(long)]
    pub refine: Option<usize>,
    /// Override the TV step of those sweeps (0 = plain SART; the default 0.2).
    #[arg(long)]
    pub refine_tv_step: Option<f64>,
}

impl InferArgs {
    /// The flags as plain data.
    pub fn overrides(&self) -> InferOverrides {
        InferOverrides {
            tune: self.tune,
            iterations: self.iterations,
            psnr_threshold: self.psnr_threshold,
            refine_iterations: self.refine,
            refine_tv_step: self.refine_tv_step,
        }
    }
}

#[derive(Debug, Args)]
pub struct ReconstructArgs {
    /// Item folder of a data set (views.json, projections.npy; ct.nii.gz gives the grid).
    pub item: PathBuf,
    /// Checkpoint folder written by `tomograf train`.
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Output NIfTI (HU).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Number of views, chosen as in the paper: 1 = AP, 2 = AP + lateral, 5 = every 72°,
    /// 10 = every 36° (other n: every 360/n°).
    #[arg(long, default_value_t = 1, conflicts_with = "poses")]
    pub views: usize,
    /// Explicit poses instead: e.g. `ap,lateral` or `0;45,10` (θ or θ,φ separated by ';').
    #[arg(long)]
    pub poses: Option<String>,
    #[command(flatten)]
    pub infer: InferArgs,
    /// Seed of the initial codes and ray jitter.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Backend: flex (CPU, default), ndarray, cuda, wgpu (as compiled in).
    #[arg(long)]
    pub backend: Option<String>,
    /// Correct the views for scatter first (items recorded with scatter): `prior` from the
    /// checkpoint's mean training volume, `oracle` from the item's ground truth (an upper
    /// bound, not a method), `none` (default). See docs/scatter.md.
    #[arg(long, default_value = "none")]
    pub scatter_correction: ScatterCorrection,
    /// Also write where the averaged fits disagree: each voxel's standard deviation across
    /// them, in HU (NIfTI). Needs a checkpoint that averages several fits for this view
    /// count (`[infer] ensemble`, `ensemble_max_views`).
    #[arg(long)]
    pub spread: Option<PathBuf>,
}

pub fn run(args: ReconstructArgs) -> Result<()> {
    let poses = match &args.poses {
        Some(text) => text
            .split(';')
            .map(|p| parse_pose(p).map_err(anyhow::Error::from))
            .collect::<Result<Vec<_>>>()?,
        None => paper_poses(args.views)?,
    };
    let (item, rec) = reconstruct_item(
        &ItemReconstruction {
            item: &args.item,
            checkpoint: &args.checkpoint,
            poses,
            infer: args.infer.overrides(),
            seed: args.seed,
            backend: args.backend.as_deref(),
            scatter_correction: args.scatter_correction,
        },
        &Bar::default(),
    )?;
    write_hu(&item, &rec.volume, &args.output)?;
    if let Some(path) = &args.spread {
        let Some(sd) = &rec.spread else {
            anyhow::bail!(
                "--spread {}: the checkpoint fits once for {} view(s) (its [infer] ensemble or \
                 ensemble_max_views), so there is no spread across fits to write; the \
                 reconstruction is in {}",
                path.display(),
                rec.psnr.len(),
                args.output.display()
            );
        };
        tomograf_datasets::nifti::write_nifti(path, &spread_hu(&item, sd)?)?;
    }
    if let Some(b) = &rec.blend {
        eprintln!(
            "SART-TV from the mean blended in with W = {} (the volume before the blend explains \
             the views at {:.2} dB on average; the checkpoint's [infer] mean_sweeps_*)",
            b.weight, b.views_psnr_db
        );
    }
    eprintln!(
        "{} iterations, PSNR per view {:?} dB (estimated peak memory {:.0} MiB): {}",
        rec.iterations,
        rec.psnr
            .iter()
            .map(|p| (p * 100.0).round() / 100.0)
            .collect::<Vec<_>>(),
        rec.peak_bytes as f64 / (1u64 << 20) as f64,
        args.output.display()
    );
    Ok(())
}
