//! The training driver (`tomograf train` and the studies): TomoGRAF trained on a data set
//! from `tomograf dataset`, with checkpoints, resume, CSV metrics, a loss plot and a
//! progress bar. Checkpoints and metrics are written atomically, metrics first, so a run
//! killed anywhere resumes with `resume` (tests/soak.rs).

use anyhow::{Context, Result, bail};
use std::io::Write;
use std::path::Path;
use std::time::Instant;
use tomograf_datasets::population::Population;
use tomograf_model::baseline::MeanVolume;
use tomograf_model::config::TrainConfig;
use tomograf_model::train::{StepMetrics, Trainer, projection_scale};
use tomograf_model::{backend, checkpoint, data};
use tomograf_scene::Progress;

const HEADER: &str = "iteration,seconds,loss_d,loss_g,loss_volume,loss_projection,loss_code,\
hinge_v,hinge_p,recon_v,recon_p,l1_volume,l1_patch";

/// What to train and where, for [`train`] (the CLI's and the studies' entry point).
pub struct Training<'a> {
    /// Data set folder (manifest.jsonl and item folders).
    pub data: &'a Path,
    /// Run folder: checkpoint/, metrics.csv, config.toml.
    pub output: &'a Path,
    /// Preset (tiny, small, medium, small-gan, paper) or a TOML file.
    pub config: &'a str,
    /// Overrides of the configuration's iteration count and seed.
    pub iterations: Option<usize>,
    pub seed: Option<u64>,
    /// Only the items of this split.
    pub split: Option<&'a str>,
    /// Continue from the run folder's checkpoint, or start afresh when there is none yet.
    pub resume: bool,
    /// Start from this checkpoint instead of fresh networks: fine-tune it on `data`
    /// ([`checkpoint::load_trainer_for`]: its configuration — `config` is not read — its
    /// networks and its iteration count, fresh codes for `data`'s items — or its learned
    /// ones when `data` holds the very items it learned them on — and `data`'s mean
    /// volume). `iterations` counts on from the checkpoint's. Once the run folder holds a
    /// checkpoint, `resume` continues that one.
    pub init: Option<&'a Path>,
    /// Backend name (`None`: the default).
    pub backend: Option<&'a str>,
}

/// Trains (or resumes) a run (stage "iteration" of `progress`); checkpoints are written
/// atomically.
pub fn train(args: &Training, progress: &dyn Progress) -> Result<()> {
    let device = backend::device(args.backend.unwrap_or(backend::default_name()))?;
    let records = tomograf_datasets::item::read_manifest(args.data, args.split)
        .with_context(|| format!("loading the data set {}", args.data.display()))?;
    let population = Population::of(&records);
    let ck = args.output.join("checkpoint");
    if args.output.is_dir() {
        let stale = tomograf_datasets::atomic::remove_stale_temporaries(args.output)?;
        if stale > 0 {
            progress.note(&format!(
                "removed {stale} temporary file(s) a killed run left"
            ));
        }
    }
    let resumable = args.resume && checkpoint::recover(&ck)?;
    if args.resume && !resumable {
        progress.note(&format!(
            "no checkpoint in {} yet: starting afresh",
            args.output.display()
        ));
    }
    if !resumable && ck.exists() {
        bail!(
            "{} already holds a checkpoint: pass --resume to continue it or choose another --output",
            ck.display()
        );
    }
    // The run's configuration (the checkpoint's when resuming) sizes its peak, checked
    // before the items are loaded.
    let config = if resumable {
        checkpoint::read_config(&ck).with_context(|| format!("resuming from {}", ck.display()))?
    } else if let Some(init) = args.init {
        let mut config = checkpoint::read_config(init)
            .with_context(|| format!("fine-tuning {}", init.display()))?;
        if let Some(s) = args.seed {
            config.seed = s;
        }
        config
    } else {
        let mut config = TrainConfig::load(args.config)?;
        if let Some(s) = args.seed {
            config.seed = s;
        }
        config
    };
    crate::peak::check_training(&config, args.data, &records, progress)?;
    let items = data::load_dataset(args.data, args.split)
        .with_context(|| format!("loading the data set {}", args.data.display()))?;
    let scale = items[0].scale;
    let ids: Vec<String> = items.iter().map(|i| i.id.clone()).collect();
    let digests: Vec<String> = items.iter().map(data::Item::content_sha256).collect();
    let mut trainer = if resumable {
        let (mut t, state) = checkpoint::load_trainer(&ck, &device)
            .with_context(|| format!("resuming from {}", ck.display()))?;
        check_same_contents(&t, &items, &digests, &ck)?;
        // A checkpoint written before digests were recorded learns them now.
        t.item_sha256 = digests;
        progress.note(&format!("resuming at iteration {}", state.iteration));
        t
    } else if let Some(init) = args.init {
        let mean = MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref()))?;
        let (t, kept) =
            checkpoint::load_trainer_for(init, args.seed, mean, scale, ids, digests, &device)
                .with_context(|| format!("fine-tuning {}", init.display()))?;
        progress.note(&format!(
            "fine-tuning {} from its iteration {} on {} {}",
            init.display(),
            t.iteration,
            items.len(),
            match kept {
                0 => "new item(s)".to_string(),
                k if k == items.len() =>
                    "item(s) it learned codes for: their codes are kept".into(),
                k => format!("item(s), {k} of which it learned codes for: theirs are kept"),
            }
        ));
        t
    } else {
        let mean = MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref()))?;
        let mut t = Trainer::new(config, projection_scale(&items)?, mean, ids, &device)?;
        t.item_sha256 = digests;
        t
    };
    if let Some(n) = args.iterations {
        trainer.config.iterations = n;
    }
    if args.init.is_some() && !resumable && trainer.config.iterations <= trainer.iteration {
        bail!(
            "the checkpoint to fine-tune has trained {} iterations and the run stops at {}: \
             give --iterations beyond {} (the count goes on from the checkpoint's)",
            trainer.iteration,
            trainer.config.iterations,
            trainer.iteration
        );
    }
    std::fs::create_dir_all(args.output)
        .with_context(|| format!("cannot create the output folder {}", args.output.display()))?;
    let toml = trainer.config.to_toml();
    tomograf_datasets::atomic::write_atomic(&args.output.join("config.toml"), |w| {
        w.write_all(toml.as_bytes())
    })?;
    let csv_path = args.output.join("metrics.csv");
    let mut rows = keep_rows(&csv_path, trainer.iteration)?;
    let (g, d) = trainer.parameter_counts();
    progress.note(&format!(
        "{} item(s), config '{}', {} generator and {} discriminator parameters",
        items.len(),
        trainer.config.name,
        g,
        d
    ));
    let checkpoint_now = |trainer: &Trainer, rows: &[String]| {
        save(
            trainer,
            scale,
            &ck,
            &csv_path,
            rows,
            args.output,
            population.as_ref(),
        )
    };
    let total = trainer.config.iterations;
    progress.start(
        "iteration",
        total as u64,
        trainer.iteration.min(total) as u64,
    );
    while trainer.iteration < total {
        let t0 = Instant::now();
        let m = trainer.step(&items)?;
        let secs = t0.elapsed().as_secs_f64();
        if m.iteration % trainer.config.log_every == 0 || m.iteration == total {
            rows.push(row(&m, secs));
            progress.set_message(&format!(
                "G {:.4} L1(V) {:.4} L1(P) {:.4}",
                m.loss_g, m.l1_volume, m.l1_patch
            ));
        }
        if m.iteration % trainer.config.checkpoint_every == 0 || m.iteration == total {
            checkpoint_now(&trainer, &rows)?;
        }
        progress.inc();
    }
    progress.finish();
    checkpoint_now(&trainer, &rows)?;
    progress.note(&format!(
        "trained {} iterations: {}, {}",
        trainer.iteration,
        ck.display(),
        csv_path.display()
    ));
    Ok(())
}

/// A resumed run's items hold what its codes were learned on: an item whose content
/// changed under the same id (a data set re-made with other settings) is refused, naming
/// it. Checkpoints without recorded digests are not checked.
fn check_same_contents(
    t: &Trainer,
    items: &[data::Item],
    digests: &[String],
    ck: &Path,
) -> Result<()> {
    if t.item_sha256.is_empty() || t.codes.is_none() {
        return Ok(());
    }
    for ((item, new), (id, old)) in items
        .iter()
        .zip(digests)
        .zip(t.item_ids.iter().zip(&t.item_sha256))
    {
        if item.id == *id && new != old {
            bail!(
                "item {} ({}) is not the one {} learned its code on: its projections or CT \
                 changed since (content digest {} then, {} now); resume on the same data \
                 set, or fine-tune with --init into another run folder",
                item.id,
                item.dir.display(),
                ck.display(),
                &old[..12.min(old.len())],
                &new[..12.min(new.len())]
            );
        }
    }
    Ok(())
}

fn row(m: &StepMetrics, secs: f64) -> String {
    format!(
        "{},{secs:.4},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}",
        m.iteration,
        m.loss_d,
        m.loss_g,
        m.loss_volume,
        m.loss_projection,
        m.loss_code,
        m.hinge_v,
        m.hinge_p,
        m.recon_v,
        m.recon_p,
        m.l1_volume,
        m.l1_patch
    )
}

/// The CSV rows of iterations ≤ `upto` already on disk (a resumed run drops the rest).
fn keep_rows(path: &Path, upto: usize) -> Result<Vec<String>> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(Vec::new());
    };
    Ok(text
        .lines()
        .skip(1)
        .filter(|l| {
            l.split(',')
                .next()
                .and_then(|v| v.parse::<usize>().ok())
                .is_some_and(|i| i <= upto)
        })
        .map(str::to_string)
        .collect())
}

fn save(
    trainer: &Trainer,
    scale: tomograf_model::render::DensityScale,
    ck: &Path,
    csv_path: &Path,
    rows: &[String],
    out: &Path,
    population: Option<&Population>,
) -> Result<()> {
    // The metrics before the checkpoint: a run killed between the two resumes from the
    // previous checkpoint and recomputes the rows after it (the other order lost the rows
    // between the two checkpoints: found by tests/soak.rs).
    tomograf_datasets::atomic::write_atomic(csv_path, |f| {
        writeln!(f, "{HEADER}")?;
        for r in rows {
            writeln!(f, "{r}")?;
        }
        Ok(())
    })?;
    plot_losses(rows, &out.join("loss.png"))?;
    checkpoint::save(trainer, scale, ck)?;
    // What the training CTs look like, for `reconstruct` and `evaluate` to compare inputs
    // with (docs/datasets.md, "Real CTs"); absent for items that do not record it.
    if let Some(p) = population {
        p.write(ck)?;
    }
    Ok(())
}

/// Draws the losses of `rows` (lines of a run's `metrics.csv`, without its header) against
/// the iteration into `path` (PNG).
pub fn plot_losses(rows: &[String], path: &Path) -> Result<()> {
    let series = |col: usize| -> Vec<(f64, f64)> {
        rows.iter()
            .filter_map(|r| {
                let v: Vec<f64> = r.split(',').filter_map(|x| x.parse().ok()).collect();
                Some((*v.first()?, *v.get(col)?))
            })
            .collect()
    };
    crate::figures::plot_lines(
        path,
        &crate::figures::Axes {
            title: "Training losses",
            x: "iteration",
            y: "loss (dimensionless, per term)",
        },
        &[
            ("loss_g (total)", series(3)),
            ("loss_volume", series(4)),
            ("loss_projection", series(5)),
            ("l1_volume", series(11)),
            ("l1_patch", series(12)),
        ],
    )
}

/// [`plot_losses`] of the metrics file `csv` (a run's `metrics.csv`), checking its header.
pub fn replot_losses(csv: &Path, path: &Path) -> Result<()> {
    let text =
        std::fs::read_to_string(csv).with_context(|| format!("cannot read {}", csv.display()))?;
    let mut lines = text.lines();
    if lines.next() != Some(HEADER) {
        anyhow::bail!(
            "{} is not a training run's metrics.csv (its first line is not `{HEADER}`)",
            csv.display()
        );
    }
    let rows: Vec<String> = lines.map(str::to_string).collect();
    plot_losses(&rows, path)
}
