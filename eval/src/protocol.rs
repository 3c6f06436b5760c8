//! The evaluation protocol's steps, shared by `tomograf reconstruct`, `tomograf evaluate`
//! and the studies: the paper's view sets, an item's reference projections, scatter
//! correction of its views, one reconstruction from a checkpoint, and writing it in HU.

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::Path;
use tomograf_model::baseline::{Baseline, MeanVolume};
use tomograf_model::checkpoint;
use tomograf_model::config::InferConfig;
use tomograf_model::data::Item;
use tomograf_model::reconstruct::{Reconstruction, Reference, reconstruct};
use tomograf_model::scatter_correction::{ScatterCorrection, correct_item};
use tomograf_sim::{Pose, Volume};

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
