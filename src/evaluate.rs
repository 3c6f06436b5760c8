//! `tomograf evaluate`: parses the flags into a [`tomograf_eval::evaluation::Evaluation`],
//! runs it and prints the merged results (the protocol itself is `tomograf_eval`).

use crate::progress::Bar;
use crate::reconstruct::InferArgs;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use tomograf_eval::evaluation::{DEFAULT_PCA_NOISE, Evaluation, evaluate, merge, parse_shard};
use tomograf_eval::tuning::{BaselineSettings, FILE, Grid, Tuning};
use tomograf_model::scatter_correction::ScatterCorrection;

#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// Test data set folder (made by `tomograf dataset`, with --views a multiple of 10).
    pub data: PathBuf,
    /// Checkpoint folder written by `tomograf train` (without it: the baselines alone —
    /// FDK and SART-TV, and with --train-data the mean volume, SART-TV from it and PCA-MAP).
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
    /// Output folder: results.md, results.csv, items/, figures, reconstructions.
    #[arg(short, long)]
    pub output: PathBuf,
    /// View counts to evaluate.
    #[arg(long, value_delimiter = ',', default_value = "1,2,5,10")]
    pub views: Vec<usize>,
    /// Use only the items of this split.
    #[arg(long)]
    pub split: Option<String>,
    /// At most this many items.
    #[arg(long)]
    pub items: Option<usize>,
    #[command(flatten)]
    pub infer: InferArgs,
    /// Seed of inference.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Backend: flex (CPU, default), ndarray, cuda, wgpu (as compiled in).
    #[arg(long)]
    pub backend: Option<String>,
    /// Score only items I, I+N, … (0-based I/N), for running across machines; combine
    /// the shards' results with --merge.
    #[arg(long)]
    pub shard: Option<String>,
    /// With --checkpoint: score the model only, not FDK and SART-TV (as `tomograf study`
    /// does in its model cells; it scores the baselines once per test set).
    #[arg(long, requires = "checkpoint")]
    pub no_baselines: bool,
    /// The model's training data set (a `tomograf dataset` folder with CTs): also score the
    /// linear statistical prior built from its volumes (PCA-MAP: mean + principal
    /// components, coefficients fitted to the views); without --checkpoint, also their mean
    /// volume and SART-TV started from it.
    #[arg(long)]
    pub train_data: Option<PathBuf>,
    /// The PCA-MAP prior's assumed projection noise, as a fraction of the largest training
    /// line integral.
    #[arg(long, default_value_t = DEFAULT_PCA_NOISE, conflicts_with = "baselines")]
    pub pca_noise: f64,
    /// The baselines' settings per view count, chosen on a validation set by `tomograf
    /// tune-baselines` (its baselines.toml); without it, their defaults.
    #[arg(long)]
    pub baselines: Option<PathBuf>,
    /// Correct every method's views for scatter before reconstruction (test sets recorded
    /// with scatter): `prior` estimates it through the item's own acquisition from the mean
    /// training volume (needs --checkpoint or --train-data); `oracle` from the ground-truth
    /// CT (an upper bound on what a correction can give, not a method); `none` (default).
    #[arg(long, default_value = "none")]
    pub scatter_correction: ScatterCorrection,
    /// Without --checkpoint: the training set whose mean volume `--scatter-correction
    /// prior` starts from, when the PCA-MAP prior is not wanted (otherwise --train-data's).
    #[arg(long)]
    pub scatter_prior_data: Option<PathBuf>,
    /// Score nothing: combine the finished items' scores under --output into results.md
    /// and results.csv (errors naming the items still missing).
    #[arg(long)]
    pub merge: bool,
    /// Slice and profile figures and the reconstruction (NIfTI, HU) for every item scored,
    /// not only the first.
    #[arg(long)]
    pub all_figures: bool,
}

pub fn run(args: EvaluateArgs) -> Result<()> {
    let shard = args
        .shard
        .as_deref()
        .map(parse_shard)
        .transpose()?
        .unwrap_or((0, 1));
    if args.merge {
        let (md, _) = merge(&args.output, false)?;
        println!("{md}");
        return Ok(());
    }
    let bar = Bar::default();
    let baselines = args
        .baselines
        .as_deref()
        .map(BaselineSettings::read)
        .transpose()?;
    let e = Evaluation {
        data: &args.data,
        checkpoint: args.checkpoint.as_deref(),
        train_data: args.train_data.as_deref(),
        output: &args.output,
        views: &args.views,
        split: args.split.as_deref(),
        items: args.items,
        infer: args.infer.overrides(),
        seed: args.seed,
        backend: args.backend.as_deref(),
        shard,
        pca_noise: args.pca_noise,
        baselines: baselines.as_ref(),
        classical: !args.no_baselines,
        scatter_correction: args.scatter_correction,
        scatter_prior_data: args.scatter_prior_data.as_deref(),
        progress: &bar,
        all_figures: args.all_figures,
        replace: false,
    };
    let made = evaluate(&e)?;
    if shard.1 > 1 {
        eprintln!(
            "shard {}/{}: {made} item(s) scored into {}; when every shard is done, run `tomograf evaluate {} -o {} --merge`",
            shard.0,
            shard.1,
            args.output.join("items").display(),
            args.data.display(),
            args.output.display()
        );
    } else {
        let (md, _) = merge(&args.output, false)?;
        println!("{md}");
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct TuneArgs {
    /// Validation data set folder (made by `tomograf dataset`, seeds disjoint from the
    /// training and test sets; --views a multiple of 10 for the 5- and 10-view sets).
    pub data: PathBuf,
    /// The training set whose CTs give the mean volume (SART-TV from the mean) and the
    /// PCA-MAP prior.
    #[arg(long)]
    pub train_data: PathBuf,
    /// Output folder: baselines.toml (the chosen settings), search.md and search.csv (every
    /// setting's scores), items/ (resumable).
    #[arg(short, long)]
    pub output: PathBuf,
    /// View counts to tune for (each gets its own settings).
    #[arg(long, value_delimiter = ',', default_value = "1,2,5,10")]
    pub views: Vec<usize>,
    /// Use only the items of this split.
    #[arg(long)]
    pub split: Option<String>,
    /// At most this many items.
    #[arg(long)]
    pub items: Option<usize>,
    /// Tune for views corrected for scatter (as `evaluate --scatter-correction`; `prior`
    /// from the training set's mean volume).
    #[arg(long, default_value = "none")]
    pub scatter_correction: ScatterCorrection,
    /// Also search this checkpoint's data-consistency sweeps (TomoGRAF) on the SART-TV grid;
    /// its network runs once per item and view count. `evaluate --checkpoint` with
    /// `--baselines` then runs the chosen sweeps.
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
    /// Inference seed of the checkpoint's network (as `evaluate --seed`).
    #[arg(long, default_value_t = 0, requires = "checkpoint")]
    pub seed: u64,
    /// Backend of the checkpoint's network: flex (CPU, default), ndarray, cuda, wgpu (as
    /// compiled in).
    #[arg(long, requires = "checkpoint")]
    pub backend: Option<String>,
}

pub fn tune(args: TuneArgs) -> Result<()> {
    let bar = Bar::default();
    let (_, md) = tomograf_eval::tuning::tune(&Tuning {
        data: &args.data,
        split: args.split.as_deref(),
        items: args.items,
        train_data: &args.train_data,
        views: &args.views,
        scatter_correction: args.scatter_correction,
        checkpoint: args.checkpoint.as_deref(),
        seed: args.seed,
        backend: args.backend.as_deref(),
        grid: Grid::Full,
        output: &args.output,
        shard: (0, 1),
        progress: &bar,
    })?;
    println!("{md}");
    eprintln!(
        "the chosen settings: {}; use them with `tomograf evaluate … --baselines {0}`",
        args.output.join(FILE).display()
    );
    Ok(())
}
