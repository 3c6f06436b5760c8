//! The whole pipeline in a minute or two on a CPU (`tomograf demo`): held-out phantoms →
//! realistic detector projections → TomoGRAF reconstruction with a checkpoint → scores
//! next to the mean training volume, the PCA-MAP prior of the same training volumes, FDK
//! and SART-TV (from zero and from the mean), with PNG figures.

use crate::evaluation::{DEFAULT_PCA_NOISE, Evaluation, evaluate, merge};
use crate::tuning::BaselineSettings;
use anyhow::{Context, Result};
use std::path::PathBuf;
use tomograf_datasets::anatomy::Profile;
use tomograf_model::config::InferOverrides;
use tomograf_scene::Progress;
use tomograf_scene::dataset::DatasetJob;
use tomograf_scene::overrides::PhysicsOverrides;

/// What the demo runs.
#[derive(Debug, Clone)]
pub struct Demo {
    /// Output folder (test-set/, train-set/, results.md, figures).
    pub output: PathBuf,
    /// A checkpoint folder written by `tomograf train` (its mean volume sets the CT size).
    pub checkpoint: PathBuf,
    /// Test phantoms (seeds 100000…, held out from any training set).
    pub phantoms: usize,
    /// View counts to reconstruct from.
    pub views: Vec<usize>,
    /// Inference iteration cap (`None`: the checkpoint's own).
    pub iterations: Option<usize>,
    /// Phantom profile of the test set (`FullChest` adds a pacemaker).
    pub profile: Profile,
    /// Remake this many `lidc` training phantoms (seed 0) for the PCA-MAP prior; 0: none.
    pub train_phantoms: usize,
    /// Acquisition preset of the test projections (`ideal-drr`: line integrals).
    pub preset: String,
    /// Backend name (`None`: the default).
    pub backend: Option<String>,
    /// The baselines' settings tuned on validation (`baselines.toml` of `tomograf
    /// tune-baselines`; `None`: their defaults).
    pub baselines: Option<PathBuf>,
}

/// Runs the demo; returns the results table (also written to `output/results.md`).
pub fn demo(d: &Demo, progress: &dyn Progress) -> Result<String> {
    let baselines = d
        .baselines
        .as_deref()
        .map(BaselineSettings::read)
        .transpose()?;
    if let Some(b) = &baselines {
        for &count in &d.views {
            b.for_views(count)?;
        }
    }
    // Both counts before any work (a bad --phantoms was refused only after the training
    // set had been remade).
    tomograf_scene::dataset::check_phantom_count(0, d.train_phantoms)
        .context("--train-phantoms")?;
    tomograf_scene::dataset::check_phantom_count(100_000, d.phantoms).context("--phantoms")?;
    let mean = tomograf_model::checkpoint::load_mean(&d.checkpoint)
        .with_context(|| format!("checkpoint {}", d.checkpoint.display()))?
        .context("the checkpoint has no mean_volume.npy")?;
    let size = mean.dims[0];
    let test = d.output.join("test-set");
    let train = d.output.join("train-set");
    if d.train_phantoms > 0 {
        progress.note(&format!(
            "1/3 remaking the checkpoint's training set ({} lidc phantoms, {size}³) for the \
             PCA prior",
            d.train_phantoms
        ));
        DatasetJob::phantoms(
            train.clone(),
            (0, d.train_phantoms),
            Profile::LidcCropped,
            false,
            (size, 36),
            "train",
            None,
        )
        .context("--train-phantoms")?
        .make(progress)?;
    }
    let pacemaker = d.profile == Profile::FullChest;
    progress.note(&format!(
        "2/3 making {} held-out {} phantoms{} and their projections ({size}³, every 36° + AP \
         + lateral, {})",
        d.phantoms,
        match d.profile {
            Profile::LidcCropped => "lidc",
            Profile::FullChest => "full-chest",
        },
        if pacemaker { " with pacemakers" } else { "" },
        d.preset
    ));
    let acquisition = PhysicsOverrides {
        preset: Some(d.preset.clone()),
        ..PhysicsOverrides::default()
    }
    .acquisition()?;
    DatasetJob::phantoms(
        test.clone(),
        (100_000, d.phantoms),
        d.profile,
        pacemaker,
        (size, 10),
        "test",
        acquisition,
    )
    .context("--phantoms")?
    .make(progress)?;
    progress.note("3/3 reconstructing and scoring");
    evaluate(&Evaluation {
        data: &test,
        checkpoint: Some(&d.checkpoint),
        train_data: (d.train_phantoms > 0).then_some(train.as_path()),
        output: &d.output,
        views: &d.views,
        split: None,
        items: None,
        infer: InferOverrides {
            iterations: d.iterations,
            ..InferOverrides::default()
        },
        seed: 0,
        backend: d.backend.as_deref(),
        shard: (0, 1),
        pca_noise: DEFAULT_PCA_NOISE,
        baselines: baselines.as_ref(),
        classical: true,
        scatter_correction: Default::default(),
        scatter_prior_data: None,
        progress,
        all_figures: false,
        replace: true,
    })?;
    let (md, _) = merge(&d.output, false)?;
    progress.note(&format!(
        "results: {0}/results.md, figures: {0}/*_slices.png, {0}/*_profile.png",
        d.output.display()
    ));
    Ok(md)
}
