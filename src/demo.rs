//! `tomograf demo`: the whole pipeline in a minute or two on a CPU — held-out phantoms
//! (`--profile`: the training population `lidc` by default, or the shifted `full-chest`
//! with a pacemaker) → realistic detector projections (`--preset`, default a 120 kVp flat
//! panel with noise; the checkpoint was trained on ideal DRRs) → 1-view TomoGRAF
//! reconstruction with the shipped checkpoint → metrics next to the mean training volume,
//! the PCA-MAP prior of the same training volumes, FDK and SART-TV (from zero and from the
//! mean), and PNG figures. The flags become a [`Demo`] of `tomograf_eval::demo`.

use crate::progress::Bar;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use tomograf_datasets::anatomy::Profile;
use tomograf_eval::demo::{Demo, demo};

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
    /// Inference iteration cap (the checkpoint's own cap when 0, the default).
    #[arg(long, default_value_t = 0)]
    pub iterations: usize,
    /// Phantom profile of the held-out test set: `lidc` (the population the shipped
    /// checkpoint was trained on; held-out seeds) or `full-chest` (arms, neck and a
    /// pacemaker: the shifted population, where the shipped model does not yet beat SART-TV
    /// from one view; docs/model.md).
    #[arg(long, default_value = "lidc")]
    pub profile: String,
    /// Remake the shipped checkpoint's training set (this many `lidc` phantoms, seed 0, as
    /// it was trained) to score the PCA-MAP prior built from the same volumes; 0 skips it.
    #[arg(long, default_value_t = 32)]
    pub train_phantoms: usize,
    /// Acquisition of the test projections: `kv-flat-panel-120kvp` (the default: a 120 kVp
    /// spectrum, material-resolved attenuation, a CsI flat panel with quantum and
    /// electronic noise, read as −ln of the flat-field-corrected signal), `cbct-100kvp`, or
    /// `ideal-drr` (monochromatic line integrals, what the checkpoint was trained on).
    #[arg(long, default_value = "kv-flat-panel-120kvp")]
    pub preset: String,
    /// Backend: flex (CPU, default), ndarray, cuda, wgpu (as compiled in).
    #[arg(long)]
    pub backend: Option<String>,
    /// The baselines' settings (a `tomograf tune-baselines` baselines.toml). Default: the
    /// checkpoint's own baselines.toml when it has one (the shipped checkpoint's were
    /// chosen on validation phantoms), else the baselines' defaults.
    #[arg(long)]
    pub baselines: Option<PathBuf>,
}

pub fn run(args: DemoArgs) -> Result<()> {
    let md = demo(
        &Demo {
            output: args.output,
            checkpoint: args.checkpoint.clone(),
            phantoms: args.phantoms,
            views: args.views,
            iterations: (args.iterations > 0).then_some(args.iterations),
            profile: Profile::parse(&args.profile)?,
            train_phantoms: args.train_phantoms,
            preset: args.preset,
            backend: args.backend,
            baselines: args.baselines.or_else(|| {
                let own = args.checkpoint.join(tomograf_eval::tuning::FILE);
                own.exists().then_some(own)
            }),
        },
        &Bar::default(),
    )?;
    println!("{md}");
    Ok(())
}
