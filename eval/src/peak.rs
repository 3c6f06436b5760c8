//! The peak memory of an evaluation (`tomograf evaluate`, and the studies' evaluations),
//! estimated before the training set is loaded and checked against the memory available
//! ([`tomograf_sim::memory::check`]; docs/reliability.md, "Memory budget").
//!
//! Fitted to `/usr/bin/time -v` peaks at 64³ and 96³ grids with 8 and 24 training items
//! (`scripts/memory_peaks_evaluate.sh`):
//!
//! * the test items, as loaded (their CTs and projections);
//! * every training item of `--train-data` (PCA-MAP's prior): `3.0 ×` its f32 CT (the CT
//!   loaded, its centred copy, one principal component) plus its projections;
//! * the larger of the baselines' work, `23 MiB + 3.45 ×` the f32 grid (SART-TV's sweeps),
//!   and TomoGRAF's inference ([`tomograf_model::config::TrainConfig::inference_peak_bytes`]);
//!   with a checkpoint, `+ 11 MiB` for the network's runtime, which stays loaded while the
//!   baselines run (inference's fixed part less the process's own, 6 MiB: a `tiny`
//!   checkpoint's evaluation at 16³ measured 39 MiB against 22 for its inference and 19
//!   for the baselines alone).
//!
//! And of a training run (`tomograf train`, the studies' training): its items as loaded and
//! a step's work ([`tomograf_model::config::TrainConfig::training_peak_bytes`]), checked
//! before the data set is loaded ([`check_training`]).

use anyhow::{Context, Result};
use std::path::Path;
use tomograf_datasets::item::ItemRecord;
use tomograf_model::config::TrainConfig;
use tomograf_model::data::Item;
use tomograf_scene::Progress;

pub(crate) const MIB: f64 = (1u64 << 20) as f64;

/// What an evaluation holds besides its work: the test items loaded, and the training set
/// that PCA-MAP's prior is built from (none without `--train-data`).
#[derive(Debug, Clone, Copy, Default)]
pub struct Held {
    /// Bytes of the test items' CTs and projections (f32).
    pub test_bytes: u128,
    /// Training items.
    pub train_items: u128,
    /// Voxels of one training item's CT.
    pub train_voxels: u128,
    /// Projection pixels of one training item (all its views).
    pub train_pixels: u128,
}

/// Estimated peak memory of an evaluation on a grid of `grid_voxels`, bytes, holding
/// `held`; `inference` is TomoGRAF's estimated peak when a checkpoint is scored.
pub fn evaluation_peak_bytes(grid_voxels: u128, held: Held, inference: Option<f64>) -> u128 {
    let baselines = 23.0 * MIB + 3.45 * 4.0 * grid_voxels as f64;
    // The network's runtime stays loaded while the baselines run.
    let network = 11.0 * MIB;
    let work = inference.map_or(baselines, |i| i.max(baselines) + network);
    let train = held.train_items as f64
        * (3.0 * 4.0 * held.train_voxels as f64 + 4.0 * held.train_pixels as f64);
    (work + held.test_bytes as f64 + train) as u128
}

/// The largest test item's grid voxels and detector pixels.
pub fn largest(items: &[Item]) -> (u128, u128) {
    items.iter().fold((0, 0), |(g, p), i| {
        let voxels = i.ct.as_ref().map_or(0, |c| c.len() as u128);
        (g.max(voxels), p.max(i.rows as u128 * i.cols as u128))
    })
}

/// Refuses an evaluation whose estimated peak ([`crate::peak::evaluation_peak_bytes`]:
/// the test items held, PCA-MAP's training set when given, the larger of the baselines'
/// and TomoGRAF's work), beyond what the process holds now, exceeds the memory available;
/// read before the training set is loaded (from its manifest) and noted.
pub fn check_evaluation(
    items: &[Item],
    train_data: Option<&Path>,
    inference: Option<f64>,
    progress: &dyn Progress,
) -> Result<()> {
    let mut held = Held {
        test_bytes: items
            .iter()
            .map(|i| 4 * (i.ct.as_ref().map_or(0, |c| c.len()) + i.projections.len()) as u128)
            .sum(),
        ..Default::default()
    };
    if let Some(dir) = train_data {
        let records = tomograf_datasets::item::read_manifest(dir, None)
            .with_context(|| format!("the PCA prior's training set {}", dir.display()))?;
        held.train_items = records.len() as u128;
        for r in &records {
            let [nx, ny, nz] = r.ct_dims;
            held.train_voxels = held.train_voxels.max((nx * ny * nz) as u128);
            held.train_pixels = held
                .train_pixels
                .max((r.angles_deg.len() * nx * ny) as u128);
        }
    }
    let peak = evaluation_peak_bytes(largest(items).0, held, inference);
    let what = format!(
        "evaluating {} test item(s){} (estimated peak {:.0} MiB)",
        items.len(),
        if held.train_items > 0 {
            format!(" with a PCA prior of {} training items", held.train_items)
        } else {
            String::new()
        },
        peak as f64 / MIB
    );
    check_peak(peak, &what, progress)
}

/// Refuses a job whose estimated `peak` (bytes), beyond what the process holds now, exceeds
/// the memory available (the error names `what`, the job and its estimate), else notes
/// the estimate ("estimated peak memory N MiB").
pub fn check_peak(peak: u128, what: &str, progress: &dyn Progress) -> Result<()> {
    check_beyond_held(peak, what)?;
    progress.note(&format!(
        "estimated peak memory {:.0} MiB",
        peak as f64 / MIB
    ));
    Ok(())
}

/// Refuses a job whose estimated `peak` (bytes), beyond what the process holds now, exceeds
/// the memory available (the error names `what`, the job and its estimate).
pub fn check_beyond_held(peak: u128, what: &str) -> Result<()> {
    let resident = tomograf_sim::memory::resident_bytes().map_or(0, u128::from);
    tomograf_sim::memory::check(
        peak.saturating_sub(resident),
        &format!("{what}, beyond what is already held,"),
    )?;
    Ok(())
}

/// Bytes of a data set's items as loaded (f32): each CT's voxels (`ct_dims`) and its
/// projections, whose shape is read from the header of each item's projections file (where
/// that cannot be read, one view per angle of a detector the size of the CT's first two
/// sides, as `tomograf dataset` makes them; the loader names the file's problem later).
pub fn items_bytes(dir: &Path, records: &[ItemRecord]) -> u128 {
    records
        .iter()
        .map(|r| {
            let [nx, ny, nz] = r.ct_dims.map(|n| n as u128);
            let path = dir.join(&r.id).join(&r.projections);
            let pixels = tomograf_datasets::image::npy_shape(&path)
                .map(|s| s.iter().map(|&n| u128::from(n)).product())
                .unwrap_or(r.angles_deg.len() as u128 * nx * ny);
            4 * (nx * ny * nz + pixels)
        })
        .sum()
}

/// Refuses a training run of `config` on the items of `records` (in the data set `dir`)
/// whose estimated peak ([`TrainConfig::training_peak_bytes`]), beyond what the process
/// holds now, exceeds the memory available; read before the items are loaded, and noted.
pub fn check_training(
    config: &TrainConfig,
    dir: &Path,
    records: &[ItemRecord],
    progress: &dyn Progress,
) -> Result<()> {
    let data = items_bytes(dir, records);
    let peak = config.training_peak_bytes(data);
    let m = &config.model;
    let what = format!(
        "training '{}' (batch {}, patch {}², samples {}, hidden {}, depth {}: lower these in the \
         config) on {} item(s) of {} (estimated peak {})",
        config.name,
        config.batch,
        m.patch,
        m.samples,
        m.hidden,
        m.depth,
        records.len(),
        size(data as f64),
        size(peak)
    );
    check_peak(peak as u128, &what, progress)
}

/// `bytes` as sim's memory errors write them ("12.5 MiB", "3.2 GiB"), or "49.7 TiB".
fn size(bytes: f64) -> String {
    let tib = MIB * 1024.0 * 1024.0;
    if bytes >= tib {
        format!("{:.1} TiB", bytes / tib)
    } else {
        tomograf_sim::memory::size(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_training_set_of_pca_map_dominates_a_large_evaluation() {
        let grid = 96u128.pow(3);
        let held = |n| Held {
            test_bytes: 0,
            train_items: n,
            train_voxels: grid,
            train_pixels: 12 * 96 * 96,
        };
        let (small, large) = (
            evaluation_peak_bytes(grid, held(8), None),
            evaluation_peak_bytes(grid, held(24), None),
        );
        // 16 items more hold 16 × (3 CTs + their projections) more.
        let per_item = (large - small) as f64 / 16.0 / (4 * grid) as f64;
        assert!((per_item - 3.12).abs() < 0.01, "{per_item}");
        // A checkpoint adds its runtime (11 MiB) beside the baselines; its inference counts
        // only when it outgrows them.
        let network = 11 * (1 << 20);
        assert_eq!(
            evaluation_peak_bytes(grid, held(8), Some(1.0)),
            small + network
        );
        assert_eq!(
            evaluation_peak_bytes(grid, held(8), Some(2.0)),
            small + network
        );
        assert!(evaluation_peak_bytes(grid, held(8), Some(1e10)) > small + network);
    }
}
