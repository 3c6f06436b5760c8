//! `tomograf reconstruct`: a CT from 1–10 projections of a data-set item with a trained
//! checkpoint, written as NIfTI in HU.

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use tomograf_model::baseline::{Baseline, MeanVolume};
use tomograf_model::config::{InferConfig, InferOverrides, Tune};
use tomograf_model::data::Item;
use tomograf_model::reconstruct::{Reconstruction, Reference, reconstruct};
use tomograf_model::scatter_correction::{ScatterCorrection, correct_item};
use tomograf_model::{backend, checkpoint, data};
use tomograf_sim::geometry::angles::parse_pose;
use tomograf_sim::{Pose, Volume};

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
}

/// The paper's view sets (Methods 1.7), starting from the AP view.
pub fn paper_poses(count: usize) -> Result<Vec<Pose>> {
    Ok(match count {
        0 => bail!("view count 0: give at least one view"),
        1 => vec![Pose::AP],
        2 => vec![Pose::AP, Pose::LATERAL],
        n => (0..n)
            .map(|i| Pose::new(i as f64 * 360.0 / n as f64, 0.0))
            .collect(),
    })
}

/// The references of `item` at `poses`; errors naming a missing pose.
pub fn references(item: &Item, poses: &[Pose]) -> Result<Vec<Reference>> {
    poses
        .iter()
        .map(|&p| {
            let i = item.find_pose(p).with_context(|| {
                format!(
                    "item {} has no projection at θ = {}°, φ = {}° (it has {} views; make the data set with --views a multiple of 10 for the 5- and 10-view sets)",
                    item.id,
                    p.theta_deg,
                    p.phi_deg,
                    item.poses.len()
                )
            })?;
            Ok(Reference {
                view: item.views[i],
                pose: item.poses[i],
                image: item.projection(i).to_vec(),
            })
        })
        .collect()
}

/// `item` with its views at `poses` corrected for scatter (`None` when `correction` is
/// none): the estimate is `prior` (the mean training volume) on the item's grid, or the
/// item's ground truth for `oracle`. `seed` seeds the estimate's Monte Carlo.
pub fn correct_scatter(
    item: &Item,
    correction: ScatterCorrection,
    prior: Option<&MeanVolume>,
    poses: &[Pose],
    seed: u64,
    show: bool,
) -> Result<Option<Item>> {
    if correction == ScatterCorrection::None {
        return Ok(None);
    }
    tomograf_model::scatter_correction::correctable(item)?;
    let grid = item.ct.as_ref().with_context(|| {
        format!(
            "item {}: scatter correction needs its ct.nii.gz for the estimate's grid",
            item.id
        )
    })?;
    let estimate = match correction {
        ScatterCorrection::Prior => prior
            .context("scatter correction from the prior needs a mean training volume")?
            .reconstruct(&[], grid, &item.scale)?,
        _ => grid.clone(),
    };
    let mut indices = poses
        .iter()
        .map(|&p| {
            item.find_pose(p).with_context(|| {
                format!(
                    "item {} has no projection at θ = {}°, φ = {}°",
                    item.id, p.theta_deg, p.phi_deg
                )
            })
        })
        .collect::<Result<Vec<usize>>>()?;
    indices.sort_unstable();
    indices.dedup();
    if show {
        eprintln!(
            "item {}: correcting {} view(s) for scatter ({correction} estimate)",
            item.id,
            indices.len()
        );
    }
    let seed = tomograf_sim::seed::frame_seed(seed, 0x5CA7);
    Ok(Some(correct_item(item, &estimate, &indices, seed)?))
}

/// Loads a checkpoint's generator and reconstructs `item` from `poses`.
pub fn run_one(
    ck: &Path,
    item: &Item,
    poses: &[Pose],
    infer: Option<&InferConfig>,
    seed: u64,
    device: &tomograf_model::Device,
    show: bool,
) -> Result<Reconstruction> {
    let generator = checkpoint::load_generator(ck, device)?;
    let infer = infer.cloned().unwrap_or(generator.config.infer.clone());
    if generator.state.density_scale != item.scale {
        bail!(
            "item {} was made with another HU window or energy than the checkpoint's training data",
            item.id
        );
    }
    let grid = item.ct.clone().map_or_else(
        || {
            bail!(
                "item {} has no ct.nii.gz to take the reconstruction grid from",
                item.id
            )
        },
        Ok,
    )?;
    let refs = references(item, poses)?;
    let bar = if show {
        ProgressBar::new(infer.iterations as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} it {pos}/{len} [{bar:30}] {elapsed} (eta {eta}) {msg}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let rec = reconstruct(generator, &refs, &grid, &infer, seed, device, |i, loss| {
        bar.set_position(i as u64);
        bar.set_message(format!("loss {loss:.4}"));
    })?;
    bar.finish_and_clear();
    Ok(rec)
}

/// Writes a normalised volume as NIfTI in HU.
pub fn write_hu(item: &Item, volume: &Volume, path: &Path) -> Result<()> {
    let hu = item.window.denormalize(volume)?;
    tomograf_datasets::nifti::write_nifti(path, &hu)?;
    Ok(())
}

pub fn run(args: ReconstructArgs) -> Result<()> {
    let device = backend::device(args.backend.as_deref().unwrap_or(backend::default_name()))?;
    let item = data::load_item(&args.item)?;
    let poses = match &args.poses {
        Some(text) => text
            .split(';')
            .map(|p| parse_pose(p).map_err(anyhow::Error::from))
            .collect::<Result<Vec<_>>>()?,
        None => paper_poses(args.views)?,
    };
    let generator = checkpoint::load_generator(&args.checkpoint, &device)?;
    let corrected = correct_scatter(
        &item,
        args.scatter_correction,
        Some(&generator.prior),
        &poses,
        args.seed,
        true,
    )?;
    let item = corrected.unwrap_or(item);
    let infer = generator.config.infer.overridden(&InferOverrides {
        tune: args.tune,
        iterations: args.iterations,
        psnr_threshold: args.psnr_threshold,
        refine_iterations: args.refine,
    })?;
    let rec = run_one(
        &args.checkpoint,
        &item,
        &poses,
        Some(&infer),
        args.seed,
        &device,
        true,
    )?;
    write_hu(&item, &rec.volume, &args.output)?;
    eprintln!(
        "{} iterations, PSNR per view {:?} dB: {}",
        rec.iterations,
        rec.psnr
            .iter()
            .map(|p| (p * 100.0).round() / 100.0)
            .collect::<Vec<_>>(),
        args.output.display()
    );
    Ok(())
}
