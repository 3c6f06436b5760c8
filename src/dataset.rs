//! `tomograf dataset`: training or test sets as in the TomoGRAF paper. The flags become a
//! [`tomograf_scene::dataset::DatasetJob`] (what an item is, and how it is made, is
//! documented there); this file parses them and shows progress.
//!
//! Resumable: a re-run skips finished items; every file is written to a temporary name and
//! renamed, so a killed run leaves no half-written file. `--shard i/n` takes items
//! `i, i+n, i+2n, …`; items are independent, so shards produce the same bytes as one run.

use crate::physics::{self, PhysicsArgs};
use crate::progress::Bar;
use anyhow::{Result, bail};
use clap::Args;
use std::path::PathBuf;
use tomograf_datasets::anatomy::Profile;
use tomograf_datasets::population::Population;
use tomograf_datasets::preprocess::HuWindow;
use tomograf_scene::dataset::{DatasetJob, ItemSettings, ItemSource, expand_inputs};

#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// CT volumes: NIfTI or NRRD files or DICOM series folders (a folder of such is expanded).
    pub inputs: Vec<PathBuf>,
    /// Output folder.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Generate this many seeded thorax phantoms instead of (or after) the inputs.
    #[arg(long, default_value_t = 0)]
    pub phantoms: usize,
    /// Seed of the first phantom; phantom n uses seed + n.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Phantom population: lidc (cropped to the thorax, like LIDC-IDRI) or full-chest (arms,
    /// neck, whole chest wall, like the paper's in-house test set).
    #[arg(long, default_value = "lidc")]
    pub profile: String,
    /// Put the phantoms on a patient table.
    #[arg(long)]
    pub table: bool,
    /// Give the phantoms a pacemaker with leads.
    #[arg(long)]
    pub pacemaker: bool,
    /// Make the phantoms' soft tissue heterogeneous as a real CT's: a spatially correlated
    /// texture (16 mm lattice) of this standard deviation, HU, in muscle, organs, blood and
    /// myocardium; 0: none (docs/datasets.md, "Soft-tissue heterogeneity").
    #[arg(long, default_value_t = 0.0)]
    pub heterogeneity: f64,
    /// Draw the phantoms' heart (size, position, turn) and diaphragm domes (heights) from
    /// ranges this many times as wide about their centres: a population whose organs differ
    /// more than the default's (a large heart, a high liver dome); 1: as drawn; 0–3
    /// (docs/datasets.md, "Organ spread").
    #[arg(long, default_value_t = 1.0)]
    pub organ_spread: f64,
    /// Warp the phantoms by a smooth random displacement field (64 mm lattice) of this
    /// standard deviation per component, mm: shapes the generator cannot draw; 0: none; at
    /// most 30 (docs/datasets.md, "Deformation").
    #[arg(long, default_value_t = 0.0)]
    pub deform: f64,
    /// Projections per full rotation (every 360/views degrees), besides AP and lateral.
    #[arg(long, default_value_t = 72)]
    pub views: usize,
    /// CT grid (size³) and detector (size²).
    #[arg(long, default_value_t = 128)]
    pub size: usize,
    /// HU window mapped to [0, 1], LOW,HIGH [default: -1024,2048].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub hu_window: Vec<f32>,
    /// Black-border crop threshold, HU: voxels at or below it count as border.
    #[arg(long, default_value_t = -900.0, allow_hyphen_values = true)]
    pub crop_hu: f32,
    /// Effective energy for HU → mu, keV.
    #[arg(long, default_value_t = 60.0)]
    pub energy_kev: f64,
    /// Source-to-isocentre and source-to-detector distances, mm.
    #[arg(long, default_value_t = 1000.0)]
    pub sad: f64,
    #[arg(long, default_value_t = 1500.0)]
    pub sid: f64,
    /// Name of the split this set belongs to (e.g. the institution: "lidc", "in-house").
    #[arg(long, default_value = "train")]
    pub split: String,
    /// Take only items i, i+n, … of the job: I/N (0-based), for running across machines.
    #[arg(long)]
    pub shard: Option<String>,
    /// Keep what lies around a CT's body — the couch, the scanner's padding, stray voxels —
    /// instead of setting it to air before the crop (docs/datasets.md, "Real CTs").
    #[arg(long)]
    pub keep_table: bool,
    /// Shape augmentation for training sets, seeded: each item drawn from this seed and its
    /// index — a small roll (±5°) and tilt (±3°), and a body section that tapers (±12 %)
    /// and drifts (±12 % of the half-width, ±15 % of the half-depth) along the patient
    /// (docs/datasets.md, "Shape augmentation").
    #[arg(long)]
    pub augment: Option<u64>,
    /// Scan-range augmentation for training sets, seeded: each item keeps a stretch of its
    /// body's length drawn from this seed and its index — half of it to all of it, placed
    /// anywhere along it — as real CTs cover the whole thorax or only part of it (an upper
    /// thorax, the lung bases) (docs/datasets.md, "Scan range").
    #[arg(long)]
    pub scan_range: Option<u64>,
    /// Warn about items far from this training population: a data-set or checkpoint folder
    /// holding population.json [default: the shipped checkpoint's].
    #[arg(long)]
    pub like: Option<PathBuf>,
    /// Real detector physics instead of ideal DRRs (item i's noise is seeded from the
    /// noise seed and i, so shards give the same bytes).
    #[command(flatten)]
    pub physics: PhysicsArgs,
}

pub fn run(args: DatasetArgs) -> Result<()> {
    let job = job(&args)?;
    let like = args
        .like
        .clone()
        .unwrap_or_else(|| PathBuf::from(crate::demo::SHIPPED_CHECKPOINT));
    // Read (and checked) before any work: a corrupt population.json is named up front.
    let reference = Population::read(&like)?;
    for w in job.settings.warnings() {
        eprintln!("{w}");
    }
    run_job(&job)?;
    warn_outliers(&job.output, &like, reference.as_ref())
}

/// Warns, naming the numbers, about each item of the data set `dir` that lies far from
/// `reference`, the population recorded in `like` (a data set or checkpoint folder); says
/// so when `like` records none. A set that lies far as a whole (a training set of another
/// population) gets its first few items named and a count of the rest, not a line per item.
fn warn_outliers(
    dir: &std::path::Path,
    like: &std::path::Path,
    reference: Option<&Population>,
) -> Result<()> {
    let Some(reference) = reference else {
        eprintln!(
            "note: {} records no training population (population.json): items not compared",
            like.display()
        );
        return Ok(());
    };
    let outliers = tomograf_scene::dataset::outliers(dir, reference)?;
    for line in outlier_lines(&outliers, like, reference.items, NAMED_OUTLIERS) {
        eprintln!("{line}");
    }
    Ok(())
}

/// How many far-off items `dataset` names one by one before it counts the rest.
const NAMED_OUTLIERS: usize = 5;

/// The warning lines for `outliers` ((item id, problems) pairs) against a population of
/// `items` items recorded in `like`: one line for each of the first `named`, then one line
/// counting the rest.
fn outlier_lines(
    outliers: &[(String, Vec<String>)],
    like: &std::path::Path,
    items: usize,
    named: usize,
) -> Vec<String> {
    let mut lines: Vec<String> = outliers
        .iter()
        .take(named)
        .map(|(id, problems)| {
            format!(
                "warning: item {id} lies far from the training population of {} ({items} items): {}",
                like.display(),
                problems.join("; ")
            )
        })
        .collect();
    if outliers.len() > named {
        lines.push(format!(
            "warning: … and {} more item(s) lie far from it ({} in all); each item's item.json \
             records its body fraction and tissue fractions",
            outliers.len() - named,
            outliers.len()
        ));
    }
    lines
}

/// Runs a data-set job with a progress bar and a summary line.
pub fn run_job(job: &DatasetJob) -> Result<()> {
    job.make(&Bar::default()).map(|_| ())
}

/// The flags as a typed job (bad flags are named before any work).
pub fn job(args: &DatasetArgs) -> Result<DatasetJob> {
    let window = match args.hu_window.as_slice() {
        [] => HuWindow::CHEST,
        [lo, hi] => HuWindow::new(*lo, *hi)?,
        _ => bail!("--hu-window takes LOW,HIGH"),
    };
    if args.size < 2 || args.views == 0 {
        bail!("--size must be at least 2 and --views at least 1");
    }
    let acquisition = physics::from_args(&args.physics)?;
    let shard = args
        .shard
        .as_deref()
        .map(tomograf_eval::evaluation::parse_shard)
        .transpose()?
        .unwrap_or((0, 1));
    let mut sources: Vec<ItemSource> = expand_inputs(&args.inputs)?
        .into_iter()
        .map(|path| ItemSource::File { path })
        .collect();
    let profile = Profile::parse(&args.profile)?;
    let h = args.heterogeneity;
    if !(h.is_finite() && (0.0..=200.0).contains(&h)) {
        bail!("--heterogeneity {h} HU is outside 0–200 HU");
    }
    let k = args.organ_spread;
    let max = tomograf_datasets::anatomy::MAX_ORGAN_SPREAD;
    if !(k.is_finite() && (0.0..=max).contains(&k)) {
        bail!("--organ-spread {k} is outside 0–{max} (1: the ranges as drawn)");
    }
    let d = args.deform;
    let max = tomograf_datasets::anatomy::deform::MAX_DEFORM_MM;
    if !(d.is_finite() && (0.0..=max).contains(&d)) {
        bail!("--deform {d} mm is outside 0–{max} mm");
    }
    tomograf_scene::dataset::check_phantom_count(args.seed, args.phantoms)
        .map_err(|e| anyhow::anyhow!("--phantoms / --seed: {e}"))?;
    sources.extend((0..args.phantoms).map(|n| {
        ItemSource::phantom(args.seed + n as u64, profile, args.table, args.pacemaker)
            .with_heterogeneity(args.heterogeneity)
            .with_organ_spread(args.organ_spread)
            .with_deformation(args.deform)
    }));
    if sources.is_empty() {
        bail!("nothing to do: give CT inputs or --phantoms N");
    }
    Ok(DatasetJob {
        sources,
        settings: ItemSettings {
            window,
            crop_hu: args.crop_hu,
            energy_kev: args.energy_kev,
            views: args.views,
            size: args.size,
            sad_mm: args.sad,
            sid_mm: args.sid,
            split: args.split.clone(),
            acquisition,
            keep_table: args.keep_table,
            augment: args
                .augment
                .map(|seed| (tomograf_datasets::augment::AugmentRanges::default(), seed)),
            scan_range: args.scan_range,
            ..ItemSettings::default()
        },
        output: args.output.clone(),
        shard,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn far(n: usize) -> Vec<(String, Vec<String>)> {
        (0..n)
            .map(|i| (format!("{i:05}"), vec![format!("body fraction {i} %")]))
            .collect()
    }

    #[test]
    fn a_few_outliers_are_each_named() {
        let lines = outlier_lines(&far(3), std::path::Path::new("ck"), 32, 5);
        assert_eq!(lines.len(), 3);
        assert!(lines[2].contains("item 00002") && lines[2].contains("body fraction 2 %"));
        assert!(lines[0].contains("ck (32 items)"));
    }

    #[test]
    fn a_set_far_as_a_whole_is_counted_not_listed() {
        let lines = outlier_lines(&far(32), std::path::Path::new("ck"), 32, 5);
        assert_eq!(lines.len(), 6);
        assert!(lines[4].contains("item 00004"));
        assert!(lines[5].contains("27 more item(s)") && lines[5].contains("(32 in all)"));
        assert!(outlier_lines(&[], std::path::Path::new("ck"), 32, 5).is_empty());
    }
}
