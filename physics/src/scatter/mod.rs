//! Scattered radiation: Monte Carlo photon transport through the patient's composition with
//! forced detection, and a fast estimate of it.
//!
//! * [`anti_scatter_grid`] — the focused linear grid's transmission for primary and scatter;
//! * [`cross_sections`] — where a scattered photon goes (KN × S, Thomson × F²);
//! * [`interaction_table`] — a material's cross sections as the transport reads them
//!   (log–log between knots at every keV and at the absorption edges);
//! * [`majorant`] — per-brick majorants for Woodcock tracking;
//! * [`transport`] — Woodcock tracking and interaction sampling in the voxel composition;
//! * [`estimator`] — the point-detector (forced detection) estimator on a coarse grid;
//! * [`engine`] — photons from the source, batches, seeds, the separate images;
//! * [`strata`] — Latin hypercube strata of a batch's pixels, energies and first-collision
//!   depths (the first collision forced: [`transport::Medium::fly_forced`]);
//! * [`start`] — where a history starts (pixel, point in it, energy and depth uniforms);
//! * [`sobol`] — the same start (and the first scatter) from an Owen-scrambled Sobol
//!   sequence instead ([`Sampler::Sobol`]);
//! * [`orbit`] — each view's scatter fitted in gantry angle with its neighbours';
//! * [`field`] — a point source collimated to a rectangular field;
//! * [`region`] — analytic scoring regions (boxes, cylinders);
//! * [`energy_imparted`] — the energy-imparted (dose) tally per voxel and region;
//! * [`dose`] — an acquisition's absorbed dose (Gy), view by view;
//! * [`estimate`] — the fast estimate (coarse, few photons, smoothed);
//!
//! The scatter images are expected detector signal (mean and second moment per channel),
//! in the same units as the primary's [`crate::detector::ExpectedImage`], so the
//! acquisition adds them before the detector records (see docs/scatter.md).

pub mod anti_scatter_grid;
pub mod cross_sections;
pub mod detection_grid;
pub mod dose;
pub mod energy_imparted;
pub mod engine;
pub mod estimate;
pub mod estimator;
pub mod field;
pub mod interaction_table;
pub mod majorant;
pub mod orbit;
pub mod region;
pub mod sobol;
pub mod start;
pub mod strata;
pub mod transport;

pub use anti_scatter_grid::AntiScatterGrid;
pub use engine::{Histories, ScatterEngine, ScatterImages, ScoringPoints};

use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};

/// Where a batch of histories draws its start — the pixel aimed at, the energy, the depth of
/// the forced first collision — from (a scene's `[scatter]` `sampler`). Both are unbiased;
/// they differ in how evenly a batch covers those dimensions (docs/scatter.md, "Sobol
/// points and sparse multiple scatter").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Sampler {
    /// Each dimension stratified on its own: a Latin hypercube over the batch ([`strata`]),
    /// the pixel's index drawn row-major.
    #[default]
    LatinHypercube,
    /// An Owen-scrambled Sobol sequence, one point per history ([`sobol`]): each dimension
    /// stratified as by the Latin hypercube, the pixel's row and column and the depth also
    /// jointly, and the first scatter's draws from the sequence too.
    Sobol,
}

/// How scatter is modelled (a scene's `[scatter]` table, `model = "none" | "estimate" |
/// "monte-carlo"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "model", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ScatterModel {
    /// No scatter (costs nothing).
    #[default]
    None,
    /// The fast estimate: a coarse Monte Carlo with few photons, smoothed.
    #[serde(rename_all = "snake_case")]
    Estimate {
        /// Photon histories (default 2 000).
        #[serde(default = "default_estimate_photons")]
        photons: u64,
        /// Scoring points per detector side (default 8).
        #[serde(default = "default_estimate_grid")]
        grid: usize,
        /// Scoring points per side for photons scattered more than once (the smooth
        /// multiple-scatter image); 0 (the default): the same as `grid`.
        #[serde(default)]
        multiple_grid: usize,
        /// Gaussian smoothing of the coarse grid, σ in grid cells (default 1).
        #[serde(default = "default_smoothing")]
        smoothing: f64,
        /// Forced detection's paths traced through cells of about this size (mm), the
        /// volume's voxels merged ([`detection_grid`]; default 8); 0: the full resolution.
        #[serde(default = "default_estimate_cell")]
        detection_cell_mm: f64,
    },
    /// Full Monte Carlo with forced detection.
    #[serde(rename_all = "snake_case")]
    MonteCarlo {
        /// Photon histories per view (default 100 000).
        #[serde(default = "default_photons")]
        photons: u64,
        /// Scoring points per detector side, interpolated to every pixel (default 16).
        #[serde(default = "default_grid")]
        grid: usize,
        /// Scoring points per side for photons scattered more than once (the smooth
        /// multiple-scatter image, which fewer points describe: each collision after the
        /// first then costs fewer forced-detection traces); 0 (the default): the same as
        /// `grid`.
        #[serde(default)]
        multiple_grid: usize,
        /// Most scatters followed per history (default 50).
        #[serde(default = "default_max_order")]
        max_order: u32,
        /// Forced detection's paths traced through cells of about this size (mm), the
        /// volume's voxels merged ([`detection_grid`]); 0 (the default): the full
        /// resolution.
        #[serde(default)]
        detection_cell_mm: f64,
        /// Each view's scatter fitted, pixel by pixel, with a quadratic in gantry angle
        /// through the raw images of the scene's views within this many degrees of it (on
        /// the same orbit: [`orbit`]) — scatter changes slowly with the angle, so each view's
        /// Monte Carlo noise is averaged with its neighbours'; 0 (the default): each view
        /// on its own histories alone.
        #[serde(default)]
        angular_window_deg: f64,
        /// Branches each history splits into at its first collision (default 1: no
        /// splitting). The primary's path and the single-scatter scores are paid once per
        /// history; each branch follows the later flights, which make the multiple-scatter
        /// image, with 1/`split` of the weight — unbiased, and the multiple image's
        /// history-to-history spread shrinks (docs/scatter.md, "Splitting at the first
        /// collision").
        #[serde(default = "default_split")]
        split: u32,
        /// Each collision after the first scores a random quarter of the multiple-scatter
        /// points — those whose row and column parities it draws — each four times (default
        /// false: every point). Unbiased; forced detection after the first collision then
        /// costs a quarter, which pays for more branches (`split`).
        #[serde(default)]
        sparse_multiple: bool,
        /// Where each batch draws its histories' start from (default `latin-hypercube`).
        #[serde(default)]
        sampler: Sampler,
        /// With `detection_cell_mm` > 0: one scored path in this many is also traced at full
        /// resolution, and each component's image is scaled by the ratio of the two summed
        /// signals — the cells' level error removed, their shape error not (docs/scatter.md,
        /// "Checking the cells"); 0 (the default): no check. The histories are unchanged.
        #[serde(default)]
        cell_check: u32,
    },
}

fn default_estimate_photons() -> u64 {
    2_000
}
fn default_estimate_grid() -> usize {
    8
}
fn default_smoothing() -> f64 {
    1.0
}
fn default_estimate_cell() -> f64 {
    8.0
}
fn default_photons() -> u64 {
    100_000
}
fn default_grid() -> usize {
    16
}
fn default_max_order() -> u32 {
    50
}
fn default_split() -> u32 {
    1
}

/// Most photons per view a scene may ask for (beyond it a run would take hours).
pub const MAX_PHOTONS: u64 = 1_000_000_000;
/// Most scoring points per side.
pub const MAX_GRID: usize = 512;
/// Most branches a history may split into at its first collision.
pub const MAX_SPLIT: u32 = 64;
/// Largest cell of the detection grid, mm.
pub const MAX_DETECTION_CELL_MM: f64 = 100.0;

impl ScatterModel {
    /// The full Monte Carlo with its default settings (100 000 photons, 16² scoring
    /// points, 50 orders).
    pub fn monte_carlo_default() -> Self {
        ScatterModel::MonteCarlo {
            photons: default_photons(),
            grid: default_grid(),
            multiple_grid: 0,
            max_order: default_max_order(),
            detection_cell_mm: 0.0,
            angular_window_deg: 0.0,
            split: 1,
            sparse_multiple: false,
            sampler: Sampler::default(),
            cell_check: 0,
        }
    }

    /// The fast estimate with its default settings (2 000 photons, 8² points, σ 1 cell,
    /// forced detection through 8 mm cells; chosen on a validation phantom, docs/scatter.md
    /// "Scatter at data-set speed").
    pub fn estimate_default() -> Self {
        ScatterModel::Estimate {
            photons: default_estimate_photons(),
            grid: default_estimate_grid(),
            multiple_grid: 0,
            smoothing: default_smoothing(),
            detection_cell_mm: default_estimate_cell(),
        }
    }

    /// Checks the settings, naming the bad one.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(SimError::OutOfRange(format!("[scatter] {m}")));
        let (photons, grid, multiple_grid, cell) = match *self {
            ScatterModel::None => return Ok(()),
            ScatterModel::Estimate {
                photons,
                grid,
                multiple_grid,
                smoothing,
                detection_cell_mm,
            } => {
                if !(smoothing.is_finite() && (0.0..=100.0).contains(&smoothing)) {
                    return bad(format!(
                        "smoothing = {smoothing}; give a σ in grid cells in 0–100"
                    ));
                }
                (photons, grid, multiple_grid, detection_cell_mm)
            }
            ScatterModel::MonteCarlo {
                photons,
                grid,
                multiple_grid,
                max_order,
                detection_cell_mm,
                angular_window_deg,
                split,
                cell_check,
                ..
            } => {
                if cell_check > 0 && detection_cell_mm == 0.0 {
                    return bad(format!(
                        "cell_check = {cell_check} needs forced detection through cells; give \
                         detection_cell_mm > 0 or cell_check = 0"
                    ));
                }
                if max_order == 0 {
                    return bad("max_order = 0; give ≥ 1 (1: single scatter only)".into());
                }
                if !(1..=MAX_SPLIT).contains(&split) {
                    return bad(format!(
                        "split = {split}; give 1 to {MAX_SPLIT} branches (1: no splitting)"
                    ));
                }
                if !(angular_window_deg.is_finite()
                    && (0.0..=orbit::MAX_WINDOW_DEG).contains(&angular_window_deg))
                {
                    return bad(format!(
                        "angular_window_deg = {angular_window_deg}; give 0–{} degrees (0: \
                         each view alone)",
                        orbit::MAX_WINDOW_DEG
                    ));
                }
                (photons, grid, multiple_grid, detection_cell_mm)
            }
        };
        if multiple_grid > MAX_GRID {
            return bad(format!(
                "multiple_grid = {multiple_grid}; give 1 to {MAX_GRID} points per side (0: as grid)"
            ));
        }
        if !(cell.is_finite() && (0.0..=MAX_DETECTION_CELL_MM).contains(&cell)) {
            return bad(format!(
                "detection_cell_mm = {cell}; give a cell size in 0–{MAX_DETECTION_CELL_MM} mm (0: full resolution)"
            ));
        }
        if !(1..=MAX_PHOTONS).contains(&photons) {
            return bad(format!("photons = {photons}; give 1 to {MAX_PHOTONS}"));
        }
        if !(1..=MAX_GRID).contains(&grid) {
            return bad(format!(
                "grid = {grid}; give 1 to {MAX_GRID} points per side"
            ));
        }
        Ok(())
    }

    /// Whether scatter is modelled at all.
    pub fn is_none(&self) -> bool {
        matches!(self, ScatterModel::None)
    }

    /// Photon histories per view (`None` without scatter).
    pub fn photons(&self) -> Option<u64> {
        match self {
            ScatterModel::None => None,
            ScatterModel::Estimate { photons, .. } | ScatterModel::MonteCarlo { photons, .. } => {
                Some(*photons)
            }
        }
    }

    /// The same model with `n` photon histories (no change without scatter).
    pub fn with_photons(mut self, n: u64) -> Self {
        if let ScatterModel::Estimate { photons, .. } | ScatterModel::MonteCarlo { photons, .. } =
            &mut self
        {
            *photons = n;
        }
        self
    }

    /// Forced detection's cell size, mm (0: full resolution, and without scatter).
    pub fn detection_cell_mm(&self) -> f64 {
        match self {
            ScatterModel::None => 0.0,
            ScatterModel::Estimate {
                detection_cell_mm, ..
            }
            | ScatterModel::MonteCarlo {
                detection_cell_mm, ..
            } => *detection_cell_mm,
        }
    }

    /// The angular window of the Monte Carlo, degrees (0: none, and for other models).
    pub fn angular_window_deg(&self) -> f64 {
        match self {
            ScatterModel::MonteCarlo {
                angular_window_deg, ..
            } => *angular_window_deg,
            _ => 0.0,
        }
    }

    /// The same model with forced detection through cells of `mm` (0: full resolution).
    pub fn with_detection_cell_mm(mut self, mm: f64) -> Self {
        if let ScatterModel::Estimate {
            detection_cell_mm, ..
        }
        | ScatterModel::MonteCarlo {
            detection_cell_mm, ..
        } = &mut self
        {
            *detection_cell_mm = mm;
        }
        self
    }
}
