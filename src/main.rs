//! `tomograf` — X-ray projections (DRRs) of CT volumes with exact ray tracing.

mod allocator;
mod bench;
mod dataset;
mod demo;
#[cfg(test)]
mod doc_examples;
mod evaluate;
mod physics;
mod progress;
mod project;
mod recon_cmd;
mod reconstruct;
mod study;
mod tradeoff;
mod train;
mod validate;

use anyhow::Result;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

#[global_allocator]
static GLOBAL: allocator::Allocator = allocator::Allocator;

/// Every flag that takes a value accepts a negative number as that value, in every
/// subcommand, so that `--energy-kev -60` reaches the flag's own range check and its error
/// names the flag (clap would otherwise read `-60` as an unknown flag `-6`).
fn negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| {
        if a.get_action().takes_values() {
            a.allow_negative_numbers(true)
        } else {
            a
        }
    })
    .mut_subcommands(negative_numbers)
}

#[derive(Debug, Parser)]
#[command(name = "tomograf", version, about, long_about = None)]
struct Cli {
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render projections of a CT volume (or the built-in phantom when none is given).
    Project(Box<project::ProjectArgs>),
    /// Write the built-in analytic thorax phantom as a NIfTI volume (HU).
    Phantom(project::PhantomArgs),
    /// Measure projector speed and accuracy and write the figures as markdown.
    Bench(bench::BenchArgs),
    /// List the DICOM series under a folder tree (e.g. LIDC-IDRI).
    Scan(project::ScanArgs),
    /// Make a training or test set: normalised CTs and their projections, with a manifest.
    Dataset(dataset::DatasetArgs),
    /// Classical reconstruction (FDK, SART, SART-TV, SIRT) from projections with geometry.
    ReconstructClassical(Box<recon_cmd::ReconArgs>),
    /// Train TomoGRAF on a data set (checkpoints, resume, CSV metrics, loss plot).
    Train(train::TrainArgs),
    /// Reconstruct a CT (NIfTI, HU) from 1–10 projections with a trained checkpoint.
    Reconstruct(reconstruct::ReconstructArgs),
    /// Score reconstructions against ground truth (PSNR, 3D SSIM, RMSE in HU) with baselines.
    Evaluate(evaluate::EvaluateArgs),
    /// Choose the baselines' settings (SART-TV sweeps and TV step, PCA-MAP noise and
    /// components, FDK window) on a validation set; writes baselines.toml for `evaluate`.
    TuneBaselines(evaluate::TuneArgs),
    /// Phantoms → projections → 1-view reconstruction with the shipped checkpoint → metrics.
    Demo(demo::DemoArgs),
    /// The studies: realism gap (ideal DRR → real detector) and domain shift, with a report.
    #[command(subcommand)]
    Study(study::StudyCommand),
    /// Validate the physics against published references (AAPM TG-195 Monte Carlo cases).
    #[command(subcommand)]
    Validate(validate::ValidateCommand),
    /// Speed against accuracy for your scene: each projector, energy-bin, scatter and blur
    /// setting timed and compared with the most accurate, with a recommendation.
    Tradeoff(Box<tradeoff::TradeoffArgs>),
}

fn main() {
    // `tomograf … | head`: a closed stdout ends the process quietly, as it does other Unix
    // tools, instead of a panic at the next print (Rust ignores SIGPIPE by default).
    #[cfg(unix)]
    // SAFETY: sets the default disposition of one signal before any other thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    tomograf_sim::memory::set_release(allocator::release_freed);
    let cli = match Cli::from_arg_matches(&negative_numbers(Cli::command()).get_matches()) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    if let Err(e) = run(cli) {
        // The error and its causes, skipping a cause whose text a message already holds.
        let mut text = e.to_string();
        for cause in e.chain().skip(1) {
            let c = cause.to_string();
            if !text.contains(&c) {
                text = format!("{text}: {c}");
            }
        }
        eprintln!("error: {text}");
        std::process::exit(1);
    }
}

/// Most worker threads `--threads` accepts (thousands of threads exhaust the process
/// limits; more threads than cores only add switching).
const MAX_THREADS: usize = 1024;

fn run(cli: Cli) -> Result<()> {
    if let Some(n) = cli.threads {
        anyhow::ensure!(
            (1..=MAX_THREADS).contains(&n),
            "--threads {n}: give 1 to {MAX_THREADS} (this machine has {} cores; results do not \
             depend on the thread count)",
            std::thread::available_parallelism().map_or(1, |c| c.get())
        );
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {n} worker threads (--threads): {e}"))?;
    }
    match cli.command {
        Command::Project(args) => project::run(*args),
        Command::Phantom(args) => project::write_phantom(args),
        Command::Bench(args) => bench::run(args),
        Command::Scan(args) => project::scan(args),
        Command::Dataset(args) => dataset::run(args),
        Command::ReconstructClassical(args) => recon_cmd::run(*args),
        Command::Train(args) => train::run(args),
        Command::Reconstruct(args) => reconstruct::run(args),
        Command::Evaluate(args) => evaluate::run(args),
        Command::TuneBaselines(args) => evaluate::tune(args),
        Command::Demo(args) => demo::run(args),
        Command::Study(c) => study::run(c),
        Command::Validate(c) => validate::run(c),
        Command::Tradeoff(args) => tradeoff::run(*args),
    }
}
