//! `tomograf demo`: the whole pipeline in a minute or two on a CPU — held-out phantoms
//! (`--profile`: the training population `lidc` by default, or the shifted `full-chest`
//! with a pacemaker) → realistic detector projections (`--preset`, default a 120 kVp flat
//! panel with noise; the checkpoint was trained on ideal DRRs) → 1-view TomoGRAF
//! reconstruction with the shipped checkpoint → metrics next to the mean training volume,
//! the PCA-MAP prior of the same training volumes, FDK and SART-TV (from zero and from the
//! mean), and PNG figures.

use crate::physics::PhysicsArgs;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use tomograf_datasets::anatomy::Profile;
use tomograf_eval::evaluation::DEFAULT_PCA_NOISE;
use tomograf_scene::dataset::DatasetJob;

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
    let train = args.output.join("train-set");
    if args.train_phantoms > 0 {
        eprintln!(
            "1/3 remaking the checkpoint's training set ({} lidc phantoms, {size}³) for the PCA prior",
            args.train_phantoms
        );
        crate::dataset::run_job(&DatasetJob::phantoms(
            train.clone(),
            (0, args.train_phantoms),
            Profile::LidcCropped,
            false,
            (size, 36),
            "train",
            None,
        ))?;
    }
    let pacemaker = args.profile == "full-chest";
    eprintln!(
        "2/3 making {} held-out {} phantoms{} and their projections ({size}³, every 36° + AP + lateral, {})",
        args.phantoms,
        args.profile,
        if pacemaker { " with pacemakers" } else { "" },
        args.preset
    );
    let acquisition = crate::physics::from_args(&PhysicsArgs {
        preset: Some(args.preset.clone()),
        ..PhysicsArgs::default()
    })?;
    crate::dataset::run_job(&DatasetJob::phantoms(
        test.clone(),
        (100_000, args.phantoms),
        Profile::parse(&args.profile)?,
        pacemaker,
        (size, 10),
        "test",
        acquisition,
    ))?;
    eprintln!("3/3 reconstructing and scoring");
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
        refine: None,
        seed: 0,
        backend: args.backend,
        shard: None,
        no_baselines: false,
        merge: false,
        train_data: (args.train_phantoms > 0).then_some(train),
        pca_noise: DEFAULT_PCA_NOISE,
        scatter_correction: Default::default(),
        scatter_prior_data: None,
    })?;
    eprintln!(
        "results: {0}/results.md, figures: {0}/*_slices.png, {0}/*_profile.png",
        args.output.display()
    );
    Ok(())
}
