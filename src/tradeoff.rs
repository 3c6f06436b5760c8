//! `tomograf tradeoff`: what each speed setting costs in accuracy on the user's own scene
//! (`tomograf_eval::tradeoff` writes the report): the flags become a [`Tradeoff`].

use crate::progress::Bar;
use crate::project::ProjectArgs;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use tomograf_eval::tradeoff::{Tradeoff, tradeoff};

#[derive(Debug, Args)]
pub struct TradeoffArgs {
    /// The scene, as for `tomograf project` (CT, geometry, preset, scatter, …). Its first
    /// view is measured; its output flags are ignored.
    #[command(flatten)]
    pub scene: ProjectArgs,
    /// Error budget: the largest acceptable RMS error relative to the reference image's
    /// RMS (0.01 = 1 %).
    #[arg(long, default_value_t = 0.01)]
    pub budget: f64,
    /// Trilinear steps to try, voxels.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.25, 0.5, 1.0, 2.0])]
    pub steps: Vec<f64>,
    /// Energy-bin counts to try (real physics only).
    #[arg(long, value_delimiter = ',', default_values_t = vec![64, 32, 16, 8, 4])]
    pub bins: Vec<usize>,
    /// Fractions of the reference's scatter photons to try (scatter scenes only): each
    /// rung is timed and compared against the reference.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.25, 0.0625])]
    pub scatter_fractions: Vec<f64>,
    /// Cell sizes (mm) to try for the scatter's forced detection (scatter scenes only;
    /// those coarser than the reference's own).
    #[arg(long, value_delimiter = ',', default_values_t = vec![16.0])]
    pub scatter_cells: Vec<f64>,
    /// Histories of the reference's scatter Monte Carlo, which bounds its cost (default:
    /// the scene's own for a Monte Carlo scene; 10000 through 8 mm cells for a scene that
    /// asks for the estimate).
    #[arg(long)]
    pub scatter_reference_photons: Option<u64>,
    /// Renders per timing (the median is reported).
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Folder for tradeoff.md, tradeoff.csv and tradeoff.png.
    #[arg(long, default_value = "tradeoff")]
    pub report: PathBuf,
}

pub fn run(args: TradeoffArgs) -> Result<()> {
    // `project`'s output flags would be silently ignored: the trade-off writes a report.
    if args.scene.output.is_some() || args.scene.prefix.is_some() || !args.scene.format.is_empty() {
        anyhow::bail!(
            "tradeoff writes no images, only its report: give the report's folder with \
             --report (default: tradeoff), not -o/--output, --prefix or --format"
        );
    }
    let scene = crate::project::merge(&args.scene)?;
    let t = Tradeoff {
        budget: args.budget,
        steps: args.steps,
        bins: args.bins,
        scatter_fractions: args.scatter_fractions,
        scatter_cells: args.scatter_cells,
        scatter_reference_photons: args.scatter_reference_photons,
        repeats: args.repeats,
        report: args.report,
    };
    println!("{}", tradeoff(&scene, &t, &Bar::default())?);
    Ok(())
}
