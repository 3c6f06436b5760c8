//! `tomograf demo`: the whole pipeline in a few minutes on a CPU — held-out phantoms of the
//! shifted profile (full chest with arms and a pacemaker) → realistic detector projections
//! (`--preset`, default a 120 kVp flat panel with noise) → 1-view TomoGRAF
//! reconstruction with the shipped checkpoint → metrics next to the mean training volume,
//! and PNG figures.

use anyhow::{Context, Result};
use clap::{Args, Parser};
use std::path::PathBuf;

/// The checkpoint shipped in the repository (`model/checkpoints/demo`).
pub const SHIPPED_CHECKPOINT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/model/checkpoints/demo");

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(short, long, default_value = "demo-output")]
    pub output: PathBuf,
    /// Checkpoint (default: the one shipped in the repository).
    #[arg(long, default_value = SHIPPED_CHECKPOINT)]
    pub checkpoint: PathBuf,
    /// Test phantoms.
    #[arg(long, default_value_t = 2)]
    pub phantoms: usize,
    /// View counts.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    pub views: Vec<usize>,
    /// Inference iteration cap (the checkpoint's own cap when 0); kept low so the demo
    /// takes minutes on a CPU.
    #[arg(long, default_value_t = 40)]
    pub iterations: usize,
    /// Acquisition of the test projections: `kv-flat-panel-120kvp` (the default: a 120 kVp
    /// spectrum, material-resolved attenuation, a CsI flat panel with quantum and
    /// electronic noise, read as −ln of the flat-field-corrected signal), `cbct-100kvp`, or
    /// `ideal-drr` (monochromatic line integrals, what the checkpoint was trained on).
    #[arg(long, default_value = "kv-flat-panel-120kvp")]
    pub preset: String,
    /// Backend: flex (CPU, default), ndarray, cuda, wgpu (as compiled in).
    #[arg(long)]
    pub backend: Option<String>,
}

#[derive(Parser)]
struct DatasetCli {
    #[command(flatten)]
    args: crate::dataset::DatasetArgs,
}

pub fn run(args: DemoArgs) -> Result<()> {
    let device = tomograf_model::backend::device(
        args.backend
            .as_deref()
            .unwrap_or(tomograf_model::backend::default_name()),
    )?;
    let mean = tomograf_model::checkpoint::load_mean(&args.checkpoint)
        .with_context(|| format!("checkpoint {}", args.checkpoint.display()))?
        .context("the checkpoint has no mean_volume.npy")?;
    drop(device);
    let size = mean.dims[0];
    let test = args.output.join("test-set");
    eprintln!(
        "1/2 making {} held-out full-chest phantoms with pacemakers and their projections ({size}³, every 36° + AP + lateral, {})",
        args.phantoms, args.preset
    );
    let ds = DatasetCli::try_parse_from([
        "dataset".to_string(),
        "-o".into(),
        test.display().to_string(),
        "--phantoms".into(),
        args.phantoms.to_string(),
        "--seed".into(),
        "100000".into(),
        "--profile".into(),
        "full-chest".into(),
        "--pacemaker".into(),
        "--views".into(),
        "10".into(),
        "--size".into(),
        size.to_string(),
        "--split".into(),
        "test".into(),
        "--preset".into(),
        args.preset.clone(),
    ])?;
    crate::dataset::run(ds.args)?;
    eprintln!("2/2 reconstructing and scoring");
    crate::evaluate::run(crate::evaluate::EvaluateArgs {
        data: test,
        checkpoint: Some(args.checkpoint),
        output: args.output.clone(),
        views: args.views,
        split: None,
        items: None,
        iterations: (args.iterations > 0).then_some(args.iterations),
        psnr_threshold: None,
        tune: None,
        seed: 0,
        backend: args.backend,
        shard: None,
        no_baselines: false,
        merge: false,
    })?;
    eprintln!(
        "results: {0}/results.md, figures: {0}/*_slices.png, {0}/*_profile.png",
        args.output.display()
    );
    Ok(())
}
