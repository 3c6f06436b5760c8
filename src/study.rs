//! `tomograf study realism-gap` and `tomograf study domain-shift`: parses the flags into a
//! [`Study`] and runs the stages asked for (the studies themselves are
//! `tomograf_eval::study`; docs/studies.md).

use crate::progress::Bar;
use anyhow::{Result, bail};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use tomograf_eval::evaluation::parse_shard;
use tomograf_eval::study::peak::Stages;
use tomograf_eval::study::{Kind, Scale, Settings, Study, levels};
use tomograf_scene::dataset::expand_inputs;

#[derive(Debug, Subcommand)]
pub enum StudyCommand {
    /// Models trained on ever more realistic projections (ideal DRR → + polychromatic →
    /// + detector noise and blur → + scatter), each evaluated on every level.
    RealismGap(RealismArgs),
    /// A model trained on lidc phantoms, tested on shifted populations and exposures.
    DomainShift(ShiftArgs),
}

#[derive(Debug, Args)]
pub struct RealismArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Realism levels to include (default: all): ideal-drr, polychromatic, noise-blur,
    /// scatter.
    #[arg(long, value_delimiter = ',')]
    pub levels: Vec<String>,
}

#[derive(Debug, Args)]
pub struct ShiftArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Test sets to include (default: all): lidc, full-chest, table, pacemaker,
    /// paper-in-house, kvp-80, low-mas, starved, and user-ct with --test-ct.
    #[arg(long, value_delimiter = ',')]
    pub shifts: Vec<String>,
}

#[derive(Debug, Args)]
pub struct CommonArgs {
    /// Study folder (re-running it resumes: finished work is kept).
    #[arg(short, long)]
    pub output: PathBuf,
    /// tiny (CI: 16³, a few phantoms, the tiny model; about a minute), small (the real
    /// figure: 64³, the small model; hours on a CPU) or medium (128³ volumes and 128²
    /// panels, where the detector's noise and blur show; the medium model).
    #[arg(long, default_value = "tiny")]
    pub scale: String,
    /// Seed of the phantoms, the detector noise, training and inference.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Run one stage only: data, train, evaluate or report (default: all, in order); or
    /// `effects`: measure what each test set does to the projections (the report's first
    /// table; seconds, no data set made) and print it.
    #[arg(long, default_value = "all")]
    pub stage: String,
    /// Take part I/N (0-based) of the stage's work, for running across machines: data
    /// items, models and test items are dealt round-robin. Needs --stage.
    #[arg(long)]
    pub shard: Option<String>,
    /// Backend: flex (CPU, default), ndarray, cuda, wgpu (as compiled in).
    #[arg(long)]
    pub backend: Option<String>,
    /// With --stage data: make only the train or only the test sets (default both).
    #[arg(long)]
    pub split: Option<String>,
    /// Train on these CTs instead of phantoms: NIfTI or NRRD files or DICOM series folders (a folder
    /// of such is expanded), comma-separated or repeated. Each is brought into the patient
    /// frame and cropped to its body, as `tomograf dataset` does.
    #[arg(long, value_delimiter = ',')]
    pub train_ct: Vec<PathBuf>,
    /// Test on these CTs: realism-gap tests every level on them instead of phantoms;
    /// domain-shift adds the test set `user-ct` (the training physics on these CTs).
    #[arg(long, value_delimiter = ',')]
    pub test_ct: Vec<PathBuf>,
    /// With --stage report: report on the test items scored so far (an interim report of a
    /// sharded evaluation; it names the cells that average fewer phantoms than the scale).
    #[arg(long)]
    pub partial: bool,
    /// With --stage report: report the scores of these study folders pooled — the same
    /// study (kind, scale, sets) run with other --seed values, e.g. three training seeds —
    /// into the -o folder; comma-separated or repeated.
    #[arg(long, value_delimiter = ',')]
    pub pool: Vec<PathBuf>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    All,
    Data,
    Train,
    Evaluate,
    Report,
    Effects,
}

pub fn run(command: StudyCommand) -> Result<()> {
    let common = match &command {
        StudyCommand::RealismGap(a) => &a.common,
        StudyCommand::DomainShift(a) => &a.common,
    };
    let train_cts = expand_inputs(&common.train_ct)?;
    let test_cts = expand_inputs(&common.test_ct)?;
    for (flag, given, found) in [
        ("--train-ct", &common.train_ct, &train_cts),
        ("--test-ct", &common.test_ct, &test_cts),
    ] {
        if !given.is_empty() && found.is_empty() {
            bail!("{flag}: no NIfTI or NRRD file or DICOM series found in {given:?}");
        }
        if let Some(missing) = found.iter().find(|p| !p.exists()) {
            bail!("{flag}: {} does not exist", missing.display());
        }
    }
    let (kind, common, train, test) = match command {
        StudyCommand::RealismGap(a) => {
            let scale = Scale::parse(&a.common.scale)?;
            let levels = levels::select(
                levels::realism_levels(scale.scatter_photons),
                &a.levels,
                "realism level",
            )?;
            let tests = levels::realism_test_sets(&levels)
                .into_iter()
                .map(|s| s.with_cts(&test_cts))
                .collect();
            let trains = levels.into_iter().map(|s| s.with_cts(&train_cts)).collect();
            (Kind::RealismGap, a.common, trains, tests)
        }
        StudyCommand::DomainShift(a) => {
            let mut all = levels::shifts();
            if !test_cts.is_empty() {
                all.push(levels::user_ct_shift(&test_cts));
            } else if a.shifts.iter().any(|s| s == levels::USER_CT) {
                bail!(
                    "the test set '{}' is made of --test-ct: give the CTs",
                    levels::USER_CT
                );
            }
            let shifts = levels::select(all, &a.shifts, "shift")?;
            (
                Kind::DomainShift,
                a.common,
                vec![levels::shift_training().with_cts(&train_cts)],
                shifts,
            )
        }
    };
    let scale = Scale::parse(&common.scale)?;
    let stage = match common.stage.as_str() {
        "all" => Stage::All,
        "data" => Stage::Data,
        "train" => Stage::Train,
        "evaluate" => Stage::Evaluate,
        "report" => Stage::Report,
        "effects" => Stage::Effects,
        other => {
            bail!("unknown --stage '{other}': use all, data, train, evaluate, report or effects")
        }
    };
    let shard = common
        .shard
        .as_deref()
        .map(parse_shard)
        .transpose()?
        .unwrap_or((0, 1));
    let splits: &[&str] = match common.split.as_deref() {
        None => &["train", "test"],
        Some("train") => &["train"],
        Some("test") => &["test"],
        Some(other) => bail!("unknown --split '{other}': use train or test"),
    };
    if common.split.is_some() && stage != Stage::Data {
        bail!("--split is for --stage data (make only the train or only the test sets)");
    }
    if !common.pool.is_empty() && stage != Stage::Report {
        bail!("--pool is for --stage report (a report over runs with other seeds)");
    }
    if common.partial && stage != Stage::Report {
        bail!("--partial is for --stage report (an interim report while shards still run)");
    }
    if shard.1 > 1 && matches!(stage, Stage::All | Stage::Report | Stage::Effects) {
        bail!(
            "--shard splits one stage: give --stage data, train or evaluate (each after the \
             previous one has finished on every shard), then --stage report once"
        );
    }
    let settings = Settings {
        kind,
        scale,
        seed: common.seed,
        train_sets: train.iter().map(|s| s.name.to_string()).collect(),
        test_sets: test.iter().map(|s| s.name.to_string()).collect(),
        train_cts,
        test_cts,
    };
    let study = Study {
        dir: common.output.clone(),
        settings,
        train,
        test,
        backend: common.backend.clone(),
        pool: common.pool.clone(),
    };
    study.check_settings()?;
    let bar = Bar::default();
    let all = stage == Stage::All;
    study.check_memory(
        Stages {
            data: all || stage == Stage::Data,
            training: all || stage == Stage::Train,
            evaluation: all || stage == Stage::Evaluate,
            // The report measures the sets' effects unless `effects.json` holds them.
            report: (all || matches!(stage, Stage::Report | Stage::Effects))
                && (stage == Stage::Effects || !study.dir.join("effects.json").exists()),
        },
        &bar,
    )?;
    if all || stage == Stage::Data {
        study.data(shard, splits, &bar)?;
    }
    if all || stage == Stage::Train {
        study.train(shard, &bar)?;
    }
    if all || stage == Stage::Evaluate {
        study.evaluate(shard, &bar)?;
    }
    if stage == Stage::Effects {
        print!("{}", study.effects()?);
        eprintln!("effects: {}/effects.json", study.dir.display());
    }
    if all || stage == Stage::Report {
        study.report(common.partial)?;
        eprintln!(
            "report: {0}/report.md, {0}/report.html, {0}/results.csv, figures in {0}/figures",
            study.dir.display()
        );
    }
    Ok(())
}
