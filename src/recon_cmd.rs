//! `tomograf reconstruct-classical`: FDK, SART, SART-TV or SIRT from projections written
//! by `tomograf project` (`drr.json` + `drr.npy`) or by `tomograf dataset` (an item's
//! `views.json` + `projections.npy`), to a NIfTI volume in HU (or mu). The flags become a
//! [`Classical`] job of `tomograf_eval::classical`.

use crate::progress::Bar;
use anyhow::{Result, ensure};
use clap::{Args, ValueEnum};
use std::path::PathBuf;
use tomograf_eval::classical::{self, Classical, Grid, reconstruct_classical};
use tomograf_recon::{AngularWeighting, FdkOptions, TvOptions, Window};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// Feldkamp–Davis–Kress filtered backprojection (circular cone-beam orbits).
    Fdk,
    /// SART with ordered subsets.
    Sart,
    /// SART followed by TV steps each iteration (ASD-POCS style).
    SartTv,
    /// SIRT (one subset holding every view).
    Sirt,
}

#[derive(Debug, Args)]
pub struct ReconArgs {
    /// Folder written by `tomograf project` (drr.json, drr.npy) or a `tomograf dataset`
    /// item (views.json, projections.npy).
    pub input: PathBuf,
    /// Output NIfTI volume.
    #[arg(short, long, default_value = "recon.nii.gz")]
    pub output: PathBuf,
    #[arg(long, value_enum, default_value = "sart-tv")]
    pub method: Method,
    /// Use only these view indices, e.g. `0,18` (default: all).
    #[arg(long, value_delimiter = ',')]
    pub views: Vec<usize>,
    /// Output grid from this NIfTI file (dims, spacing, origin, direction). Default: the
    /// projected volume's grid from drr.json, or the dataset item's ct.nii.gz.
    #[arg(long)]
    pub like: Option<PathBuf>,
    /// Output grid size, centred on the isocentre (with --spacing), e.g. 128,128,128.
    #[arg(long, value_delimiter = ',')]
    pub dims: Option<Vec<usize>>,
    /// Voxel size (mm) for --dims.
    #[arg(long, default_value_t = 2.5)]
    pub spacing: f64,
    /// Ramp-filter window (FDK).
    #[arg(long, value_enum, default_value = "ram-lak")]
    pub window: WindowArg,
    /// Angular weighting (FDK).
    #[arg(long, value_enum, default_value = "auto")]
    pub weighting: WeightingArg,
    /// Iteration cap (SART, SART-TV, SIRT).
    #[arg(long, default_value_t = 20)]
    pub iterations: usize,
    /// Ordered subsets (SART, SART-TV).
    #[arg(long, default_value_t = 10)]
    pub subsets: usize,
    /// Relaxation λ in (0, 2).
    #[arg(long, default_value_t = 1.0)]
    pub relaxation: f64,
    /// Stop when the residual improves by less than this fraction per iteration.
    #[arg(long, default_value_t = 0.0)]
    pub tolerance: f64,
    /// TV steps per iteration (SART-TV).
    #[arg(long, default_value_t = 10)]
    pub tv_steps: usize,
    /// TV step size α relative to the data update (SART-TV).
    #[arg(long, default_value_t = 0.2)]
    pub tv_alpha: f64,
    /// Effective energy (keV) whose water attenuation converts mu to HU.
    #[arg(long, default_value_t = 60.0)]
    pub energy_kev: f64,
    /// Write linear attenuation (mm⁻¹) instead of HU.
    #[arg(long)]
    pub mu: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WindowArg {
    RamLak,
    SheppLogan,
    Cosine,
    Hann,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WeightingArg {
    Auto,
    Gaps,
    Parker,
}

impl ReconArgs {
    /// The flags as a typed job.
    fn classical(self) -> Result<Classical> {
        let grid = match (self.like, self.dims) {
            (Some(p), _) => Grid::Like(p),
            (None, Some(d)) => {
                ensure!(d.len() == 3, "--dims takes three sizes, e.g. 128,128,128");
                Grid::Centred {
                    dims: [d[0], d[1], d[2]],
                    spacing_mm: self.spacing,
                }
            }
            (None, None) => Grid::Recorded,
        };
        Ok(Classical {
            input: self.input,
            output: self.output,
            method: match self.method {
                Method::Fdk => classical::Method::Fdk,
                Method::Sart => classical::Method::Sart,
                Method::SartTv => classical::Method::SartTv,
                Method::Sirt => classical::Method::Sirt,
            },
            views: self.views,
            grid,
            fdk: FdkOptions {
                window: match self.window {
                    WindowArg::RamLak => Window::RamLak,
                    WindowArg::SheppLogan => Window::SheppLogan,
                    WindowArg::Cosine => Window::Cosine,
                    WindowArg::Hann => Window::Hann,
                },
                weighting: match self.weighting {
                    WeightingArg::Auto => AngularWeighting::Auto,
                    WeightingArg::Gaps => AngularWeighting::Gaps,
                    WeightingArg::Parker => AngularWeighting::Parker,
                },
            },
            iterations: self.iterations,
            subsets: self.subsets,
            relaxation: self.relaxation,
            tolerance: self.tolerance,
            tv: TvOptions {
                iterations: self.tv_steps,
                step: self.tv_alpha,
            },
            energy_kev: self.energy_kev,
            mu: self.mu,
        })
    }
}

pub fn run(args: ReconArgs) -> Result<()> {
    reconstruct_classical(&args.classical()?, &Bar::default())
}
