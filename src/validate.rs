//! `tomograf validate tg195`: parses the flags and runs the TG-195 validation report
//! (`tomograf_eval::tg195`; docs/validation.md).

use crate::progress::Bar;
use anyhow::Result;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use tomograf_eval::tg195::{Validation, replot, validate};

#[derive(Subcommand, Debug)]
pub enum ValidateCommand {
    /// The AAPM TG-195 Monte Carlo reference cases 1, 2, 3 and 4.2 against EGSnrc, Geant4,
    /// MCNP and Penelope: a table (ours ± standard error, each code, their mean and
    /// spread, our deviation in % and in standard errors), a CSV and plots.
    Tg195(Tg195Args),
}

#[derive(Args, Debug)]
pub struct Tg195Args {
    /// Output folder (tg195.md, tg195.csv, tg195-deviations.png, tg195-case42.png).
    #[arg(short, long, default_value = "docs/validation")]
    output: PathBuf,
    /// Cases to run, comma-separated: 1, 2, 3, 4.2.
    #[arg(long, default_value = "1,2,3,4.2", value_delimiter = ',')]
    cases: Vec<String>,
    /// Photons per Case 1 run (three runs per beam, four beams).
    #[arg(long, default_value_t = 10_000_000)]
    photons_case1: u64,
    /// Photons per Case 2 run (four runs).
    #[arg(long, default_value_t = 50_000_000)]
    photons_case2: u64,
    /// Photons per Case 3 run (four runs).
    #[arg(long, default_value_t = 20_000_000)]
    photons_case3: u64,
    /// Photons per Case 4.2 run (four runs; each scores all 36 angles).
    #[arg(long, default_value_t = 40_000_000)]
    photons_case42: u64,
    /// Random seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Redraw the figures from the output folder's tg195.csv without running anything.
    #[arg(long)]
    replot: bool,
    /// Run only `--cases` and keep the other cases' rows and seconds from the output
    /// folder's tg195.csv and tg195.md (e.g. after a change that touches one case).
    #[arg(long, conflicts_with = "replot")]
    update: bool,
}

pub fn run(cmd: ValidateCommand) -> Result<()> {
    let ValidateCommand::Tg195(args) = cmd;
    if args.replot {
        return replot(&args.output, &Bar::default());
    }
    validate(
        &Validation {
            output: args.output,
            cases: args.cases,
            photons_case1: args.photons_case1,
            photons_case2: args.photons_case2,
            photons_case3: args.photons_case3,
            photons_case42: args.photons_case42,
            seed: args.seed,
            update: args.update,
        },
        &Bar::default(),
    )
}
