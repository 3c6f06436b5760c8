//! `tomograf train`: parses the flags into a [`Training`] and runs it (the driver is
//! `tomograf_eval::training`).

use crate::progress::Bar;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
pub use tomograf_eval::training::{Training, train};

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Data set folder made by `tomograf dataset` (manifest.jsonl and item folders).
    #[arg(required_unless_present = "replot")]
    pub data: Option<PathBuf>,
    /// Run folder: checkpoint/, metrics.csv, loss.png.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Preset (tiny, small, medium, small-gan, paper) or a TOML file [default: small; with --init, the
    /// checkpoint's].
    #[arg(long, conflicts_with = "init")]
    pub config: Option<String>,
    /// Override the configuration's iteration count.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Override the configuration's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Use only the items of this split.
    #[arg(long)]
    pub split: Option<String>,
    /// Continue from the run folder's checkpoint (putting back one whose save was killed);
    /// when there is none yet — a run killed before its first checkpoint — start afresh, so
    /// the same command resumes a job however far it got.
    #[arg(long)]
    pub resume: bool,
    /// Fine-tune this checkpoint on DATA instead of training fresh networks: its networks,
    /// configuration and iteration count, new codes for DATA's items and DATA's mean volume
    /// (docs/model.md, "Fine-tuning a checkpoint on other CTs"). --iterations counts on from
    /// the checkpoint's; once the run folder holds a checkpoint, --resume continues it.
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// Backend: flex (CPU, default), ndarray, cuda, wgpu (as compiled in).
    #[arg(long)]
    pub backend: Option<String>,
    /// Do not train: redraw the loss plot of this metrics.csv (a run's, or the shipped
    /// model's `model/checkpoints/demo-metrics.csv`) into `-o`/loss.png.
    #[arg(long)]
    pub replot: Option<PathBuf>,
}

pub fn run(args: TrainArgs) -> Result<()> {
    if let Some(csv) = &args.replot {
        std::fs::create_dir_all(&args.output)?;
        let png = args.output.join("loss.png");
        tomograf_eval::training::replot_losses(csv, &png)?;
        eprintln!("wrote {}", png.display());
        return Ok(());
    }
    let data = args
        .data
        .as_deref()
        .expect("clap requires data without --replot");
    train(
        &Training {
            data,
            output: &args.output,
            config: args.config.as_deref().unwrap_or("small"),
            iterations: args.iterations,
            seed: args.seed,
            split: args.split.as_deref(),
            resume: args.resume,
            init: args.init.as_deref(),
            backend: args.backend.as_deref(),
        },
        &Bar::default(),
    )
}
