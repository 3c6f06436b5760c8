//! The evaluation protocol's steps, shared by `tomograf reconstruct`, `tomograf evaluate`
//! and the studies: the paper's view sets, an item's reference projections, scatter
//! correction of its views, one reconstruction from a checkpoint, and writing it in HU.

use anyhow::{Context, Result, bail};
use std::path::Path;
use tomograf_datasets::population::Population;
use tomograf_model::baseline::{Baseline, MeanVolume};
use tomograf_model::checkpoint;
use tomograf_model::config::{InferConfig, InferOverrides};
use tomograf_model::data::Item;
use tomograf_model::reconstruct::{Reconstruction, Reference, reconstruct};
use tomograf_model::scatter_correction::{ScatterCorrection, correct_item};
use tomograf_scene::Progress;
use tomograf_sim::{Pose, Volume};

/// The items of the data set `data` (only `split`'s; at most `items` of them) for view
/// counts `views`, as `evaluate` and `tune-baselines` take them: errors name a view count
/// of 0 and `--items 0`.
pub fn load_items(
    data: &Path,
    split: Option<&str>,
    items: Option<usize>,
    views: &[usize],
) -> Result<Vec<Item>> {
    if views.is_empty() || views.contains(&0) {
        bail!("view counts must be ≥ 1 (view count 0 given)");
    }
    let mut loaded = tomograf_model::data::load_dataset(data, split)?;
    if let Some(n) = items {
        if n == 0 {
            bail!("--items 0 scores nothing: give at least 1 (or leave it out for every item)");
        }
        loaded.truncate(n);
    }
    Ok(loaded)
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
    progress: &dyn Progress,
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
    progress.note(&format!(
        "item {}: correcting {} view(s) for scatter ({correction} estimate)",
        item.id,
        indices.len()
    ));
    let seed = tomograf_sim::seed::frame_seed(seed, 0x5CA7);
    Ok(Some(correct_item(item, &estimate, &indices, seed)?))
}

/// Loads a checkpoint's generator and reconstructs `item` from `poses` (stage
/// "iteration" of `progress`).
pub fn run_one(
    ck: &Path,
    item: &Item,
    poses: &[Pose],
    infer: Option<&InferConfig>,
    seed: u64,
    device: &tomograf_model::Device,
    progress: &dyn Progress,
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
    progress.start("iteration", infer.iterations as u64, 0);
    let rec = reconstruct(generator, &refs, &grid, &infer, seed, device, |i, loss| {
        progress.set(i as u64);
        progress.set_message(&format!("loss {loss:.4}"));
    });
    progress.finish();
    Ok(rec?)
}

/// A reconstruction of one data-set item with a checkpoint (`tomograf reconstruct`,
/// Python's `tomograf.reconstruct`).
#[derive(Debug, Clone)]
pub struct ItemReconstruction<'a> {
    /// Item folder of a data set (views.json, projections.npy; ct.nii.gz gives the grid).
    pub item: &'a Path,
    /// Checkpoint folder written by `tomograf train`.
    pub checkpoint: &'a Path,
    /// The views to use, by pose (the item must hold each; [`paper_poses`] for the paper's).
    pub poses: Vec<Pose>,
    /// Overrides of the checkpoint's inference settings.
    pub infer: InferOverrides,
    /// Seed of the initial codes and ray jitter.
    pub seed: u64,
    /// Backend name (`None`: the default).
    pub backend: Option<&'a str>,
    /// Correct the views for scatter first (`prior`: from the checkpoint's mean training
    /// volume).
    pub scatter_correction: ScatterCorrection,
}

/// Reconstructs the item (stage "iteration" of `progress`); returns the item as read (its
/// window converts the normalised volume to HU: [`hu`]) and the reconstruction.
pub fn reconstruct_item(
    r: &ItemReconstruction,
    progress: &dyn Progress,
) -> Result<(Item, Reconstruction)> {
    let device = tomograf_model::backend::device(
        r.backend.unwrap_or(tomograf_model::backend::default_name()),
    )?;
    let item = tomograf_model::data::load_item(r.item)?;
    warn_population(r.item, r.checkpoint, progress)?;
    let generator = checkpoint::load_generator(r.checkpoint, &device)?;
    let corrected = correct_scatter(
        &item,
        r.scatter_correction,
        Some(&generator.prior),
        &r.poses,
        r.seed,
        progress,
    )?;
    let item = corrected.unwrap_or(item);
    let infer = generator.config.infer.overridden(&r.infer)?;
    let rec = run_one(
        r.checkpoint,
        &item,
        &r.poses,
        Some(&infer),
        r.seed,
        &device,
        progress,
    )?;
    Ok((item, rec))
}

/// Notes (through `progress`), naming the numbers, when the item in `item_dir` lies far
/// from the training population the checkpoint records (`population.json`;
/// [`Population::outliers`]): its body fraction or tissue fractions; and when its CT grid
/// is not the grid of the checkpoint's prior (`mean_volume.npy`, the training CTs' grid),
/// which inference then resamples. Silent when the item or the checkpoint records none.
pub fn warn_population(item_dir: &Path, checkpoint: &Path, progress: &dyn Progress) -> Result<()> {
    let Some(record) = tomograf_datasets::item::finished_record(item_dir) else {
        return Ok(());
    };
    if let Some(mean) = tomograf_model::checkpoint::load_mean(checkpoint)?
        && mean.dims != record.ct_dims
    {
        let [a, b] = [mean.dims, record.ct_dims].map(|d| format!("{}×{}×{}", d[0], d[1], d[2]));
        progress.note(&format!(
            "warning: item {} has a {b} CT grid but the checkpoint's prior (mean_volume.npy, \
             the grid it was trained on) is {a}: the prior is resampled to the item's grid; \
             a checkpoint is meant for items of its training size",
            item_dir.display()
        ));
    }
    let Some(population) = Population::read(checkpoint)? else {
        return Ok(());
    };
    let off = population.outliers(&record);
    if !off.is_empty() {
        progress.note(&format!(
            "warning: item {} lies far from the checkpoint's training population ({} items): \
             {}; its reconstruction leans on a prior that has not seen such a CT",
            item_dir.display(),
            population.items,
            off.join("; ")
        ));
    }
    Ok(())
}

/// A normalised volume of `item`'s data set in HU.
pub fn hu(item: &Item, volume: &Volume) -> Result<Volume> {
    Ok(item.window.denormalize(volume)?)
}

/// A spread of normalised density (the ensemble's voxel-wise standard deviation,
/// [`Reconstruction::spread`]) in HU: scaled by the width of `item`'s HU window, not shifted.
pub fn spread_hu(item: &Item, spread: &Volume) -> Result<Volume> {
    let width = item.window.hi - item.window.lo;
    Ok(spread.map(|v| v * width)?)
}

/// Writes a normalised volume as NIfTI in HU.
pub fn write_hu(item: &Item, volume: &Volume, path: &Path) -> Result<()> {
    tomograf_datasets::nifti::write_nifti(path, &hu(item, volume)?)?;
    Ok(())
}
