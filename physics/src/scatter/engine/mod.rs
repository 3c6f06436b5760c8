//! The Monte Carlo run of one view: photons from the source aimed over the detector,
//! batches with their own random streams, forced detection at every collision, and the
//! separate images (single Compton, single Rayleigh, multiple).
//!
//! Source sampling: a photon's energy is drawn from the spectrum (photons per bin) and its
//! direction uniformly over the area of a pixel drawn with probability ∝ its exposure
//! factor ([`crate::polychromatic::pixel_exposure_factor`]), so every photon carries the
//! same weight `mAs · Σ_b N_b · Σ_p f_p / photons` and the images come out in the primary's
//! units. Photons emitted outside the detector's solid angle are not followed (their
//! scatter into the panel is missed; the collimated field is the panel).
//!
//! Variance reduction: implicit capture (a photoelectric collision multiplies the weight
//! by 1 − P_photo instead of ending the history) and Russian roulette below 5 % of the
//! starting weight (survival ½, weight doubled) — both unbiased.
//!
//! Determinism: photons are split into batches of [`BATCH`]; batch `b` draws from a
//! ChaCha8 stream seeded by SplitMix64(seed, b), and batch tallies are summed in batch
//! order, so the bytes do not depend on the thread count.

mod history;

pub use history::Histories;

use super::anti_scatter_grid::{AntiScatterGrid, GridTransmission};
use super::detection_grid::DetectionGrid;
use super::estimate::smooth;
use super::estimator::{CellCheck, Component, Response, ScoreGrid, Tally, to_image};
use super::start::{Aim, BatchStarts, Start};
use super::transport::{E_CUTOFF_KEV, Medium};
use super::{MAX_GRID, MAX_PHOTONS, MAX_SPLIT, ScatterModel};
use crate::detector::ExpectedImage;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::sync::{Arc, Mutex};
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::{View, ViewBeam};
use tomograf_sim::seed::frame_seed;

/// Photon histories per batch (one random stream each).
pub const BATCH: u64 = 256;

/// Scoring points per detector side: for photons scattered once (`single`) and for those
/// scattered more than once (`multiple`: the smoother image, which fewer points describe).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScoringPoints {
    /// Points per side of the single-scatter images.
    pub single: usize,
    /// Points per side of the multiple-scatter image.
    pub multiple: usize,
}

/// Detection grids by cell size (the size's bits).
type DetectionGrids = Vec<(u64, Arc<DetectionGrid>)>;

/// A medium, a beam and a detector response, ready to simulate views.
#[derive(Debug, Clone)]
pub struct ScatterEngine {
    medium: Medium,
    response: Response,
    energies_kev: Vec<f64>,
    /// Cumulative photons per bin (photons per mAs per mm² at 1 m).
    cdf: Vec<f64>,
    mas: f64,
    /// The anti-scatter grid every scored photon crosses, if any.
    anti_scatter: Option<GridTransmission>,
    /// Detection grids made so far, by cell size (mm, as bits): made once per volume and
    /// shared by every view that asks for the same size.
    detection: Arc<Mutex<DetectionGrids>>,
    /// Histories start with independent draws and an analog first flight (the engine before
    /// 2026-12-01), for ablations: [`ScatterEngine::with_analog_sampling`].
    analog: bool,
}

/// Scatter images of one view: expected detector signal, same layout and units as the
/// primary's [`ExpectedImage`].
#[derive(Debug, Clone)]
pub struct ScatterImages {
    /// Photons scattered once, by Compton.
    pub single_compton: ExpectedImage,
    /// Photons scattered once, by Rayleigh.
    pub single_rayleigh: ExpectedImage,
    /// Photons scattered two or more times.
    pub multiple: ExpectedImage,
    /// Scoring grid (rows, cols).
    pub grid: (usize, usize),
    /// Channel 0's total scatter at each grid point, row-major.
    pub grid_mean: Vec<f64>,
    /// Its Monte Carlo standard error (from the spread of batch tallies), same units;
    /// infinite with fewer than two batches.
    pub grid_standard_error: Vec<f64>,
}

impl ScatterImages {
    /// The sum of the three components.
    pub fn total(&self) -> ExpectedImage {
        let mut t = self.single_compton.clone();
        for other in [&self.single_rayleigh, &self.multiple] {
            t.mean
                .iter_mut()
                .zip(&other.mean)
                .for_each(|(a, b)| *a += b);
            t.second_moment
                .iter_mut()
                .zip(&other.second_moment)
                .for_each(|(a, b)| *a += b);
        }
        t
    }
}

impl ScatterEngine {
    /// An engine for `medium` with a beam (`energies_kev`, photons per bin per mAs per mm²
    /// at 1 m), `mas` per view, and the detector `response` on the medium's 1 keV grid.
    pub fn new(
        medium: Medium,
        response: Response,
        energies_kev: Vec<f64>,
        photons: &[f64],
        mas: f64,
    ) -> Result<Self> {
        let bad = |m: String| Err(SimError::OutOfRange(m));
        if energies_kev.is_empty() || energies_kev.len() != photons.len() {
            return bad("scatter: the spectrum has no bins or mismatched counts".into());
        }
        if photons.iter().any(|p| !(p.is_finite() && *p >= 0.0)) || !(mas.is_finite() && mas > 0.0)
        {
            return bad("scatter: spectrum counts must be finite and ≥ 0 and mAs > 0".into());
        }
        if let Some(e) = energies_kev
            .iter()
            .find(|e| !(E_CUTOFF_KEV..=medium.e_max_kev()).contains(*e))
        {
            return bad(format!(
                "scatter: spectrum energy {e} keV outside the medium's tables (1–{} keV)",
                medium.e_max_kev()
            ));
        }
        if response.mean.is_empty() {
            return bad("scatter: the detector has no channels".into());
        }
        let mut cdf = Vec::with_capacity(photons.len());
        let mut acc = 0.0;
        for p in photons {
            acc += p;
            cdf.push(acc);
        }
        if acc <= 0.0 {
            return bad("scatter: the spectrum holds no photons".into());
        }
        Ok(Self {
            medium,
            response,
            energies_kev,
            cdf,
            mas,
            anti_scatter: None,
            detection: Arc::default(),
            analog: false,
        })
    }

    /// The same engine sampling as it did before 2026-12-01, for ablations (`true`): each
    /// history's pixel, energy and first flight drawn independently and the first flight
    /// analog (Woodcock; photons may leave uncollided), instead of the default Latin
    /// hypercube strata ([`super::strata`]) and forced first collision
    /// ([`Medium::fly_forced`]). Both are unbiased; docs/scatter.md measures the variance.
    pub fn with_analog_sampling(mut self, analog: bool) -> Self {
        self.analog = analog;
        self
    }

    /// The same engine with an anti-scatter grid in front of the detector (`None`: none).
    pub fn with_anti_scatter_grid(mut self, grid: Option<&AntiScatterGrid>) -> Result<Self> {
        self.anti_scatter = grid
            .map(|g| g.tabulate(self.medium.e_max_kev()))
            .transpose()?;
        Ok(self)
    }

    /// The same engine with majorants per brick of `size³` voxels or one global majorant
    /// (`None`): see [`Medium::with_majorant_bricks`].
    pub fn with_majorant_bricks(mut self, size: Option<usize>) -> Result<Self> {
        self.medium = self.medium.with_majorant_bricks(size)?;
        Ok(self)
    }

    /// The medium.
    pub fn medium(&self) -> &Medium {
        &self.medium
    }

    /// The detection grid of cells of about `cell_mm` (`None` for 0: full resolution),
    /// made on first use and kept for later views.
    pub fn detection_grid(&self, cell_mm: f64) -> Result<Option<Arc<DetectionGrid>>> {
        if cell_mm == 0.0 {
            return Ok(None);
        }
        let mut made = self.detection.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, g)) = made.iter().find(|(k, _)| *k == cell_mm.to_bits()) {
            return Ok(Some(g.clone()));
        }
        let g = Arc::new(DetectionGrid::new(self.medium.composition(), cell_mm)?);
        made.push((cell_mm.to_bits(), g.clone()));
        Ok(Some(g))
    }

    /// Scatter images of `view` as `model` asks (`None` for [`ScatterModel::None`]).
    pub fn run(
        &self,
        model: &ScatterModel,
        view: &View,
        seed: u64,
    ) -> Result<Option<ScatterImages>> {
        model.validate()?;
        let (photons, grid, multiple_grid, histories, smoothing, cell_mm) = match *model {
            ScatterModel::None => return Ok(None),
            ScatterModel::Estimate {
                photons,
                grid,
                multiple_grid,
                smoothing,
                detection_cell_mm,
            } => (
                photons,
                grid,
                multiple_grid,
                Histories::new(50, 1),
                smoothing,
                detection_cell_mm,
            ),
            ScatterModel::MonteCarlo {
                photons,
                grid,
                multiple_grid,
                max_order,
                detection_cell_mm,
                split,
                sparse_multiple,
                sampler,
                cell_check,
                ..
            } => (
                photons,
                grid,
                multiple_grid,
                Histories {
                    max_order,
                    split,
                    sparse_multiple,
                    sampler,
                    cell_check,
                },
                0.0,
                detection_cell_mm,
            ),
        };
        // 0: the single-scatter grid's points.
        let multiple_grid = if multiple_grid == 0 {
            grid
        } else {
            multiple_grid
        };
        let detection = self.detection_grid(cell_mm)?;
        self.simulate_through(
            view,
            view,
            photons,
            ScoringPoints {
                single: grid,
                multiple: multiple_grid,
            },
            histories,
            smoothing,
            detection.as_deref(),
            seed,
        )
        .map(Some)
    }

    /// The Monte Carlo: `photons` histories aimed over `aim`'s pixels, scored on a grid of
    /// at most `grid` × `grid` points of `view` (then interpolated to its pixels), at most
    /// `max_order` scatters each; the grid smoothed by σ = `smoothing` cells (0: none).
    /// Forced detection traces through the full-resolution composition.
    #[allow(clippy::too_many_arguments)]
    pub fn simulate(
        &self,
        aim: &View,
        view: &View,
        photons: u64,
        grid: usize,
        max_order: u32,
        smoothing: f64,
        seed: u64,
    ) -> Result<ScatterImages> {
        let points = ScoringPoints {
            single: grid,
            multiple: grid,
        };
        self.simulate_through(
            aim,
            view,
            photons,
            points,
            Histories::new(max_order, 1),
            smoothing,
            None,
            seed,
        )
    }

    /// [`ScatterEngine::simulate`] with forced detection traced through `detection`
    /// (`None`: the full-resolution composition), photons scattered once scored on
    /// `points.single` points per side and those scattered again on `points.multiple`.
    /// `histories` says how each is followed: with `split` > 1 the primary's path, its
    /// forced first collision and the single-scatter scores are paid once, then `split`
    /// independent scatters from that site, each with 1/`split` of the weight (and of its
    /// Russian roulette threshold), follow the later flights that make the multiple-scatter
    /// image (unbiased; 1 does not split); with `sparse_multiple` each collision after the
    /// first scores a random quarter of its grid's points, ×4; `sampler` draws the start;
    /// `cell_check` checks the cells against full resolution (with `detection` only).
    #[allow(clippy::too_many_arguments)]
    pub fn simulate_through(
        &self,
        aim: &View,
        view: &View,
        photons: u64,
        points: ScoringPoints,
        histories: Histories,
        smoothing: f64,
        detection: Option<&DetectionGrid>,
        seed: u64,
    ) -> Result<ScatterImages> {
        aim.validate()?;
        view.validate()?;
        let ViewBeam::Cone { source } = aim.beam else {
            return Err(SimError::InvalidGeometry(
                "scatter needs a cone beam (a point source); this view is parallel".into(),
            ));
        };
        let ScoringPoints {
            single: grid,
            multiple: multiple_grid,
        } = points;
        if !(1..=MAX_PHOTONS).contains(&photons)
            || !(1..=MAX_GRID).contains(&grid)
            || !(1..=MAX_GRID).contains(&multiple_grid)
        {
            return Err(SimError::OutOfRange(format!(
                "scatter: photons = {photons} (1 to {MAX_PHOTONS}), grid = {grid} and multiple \
                 grid = {multiple_grid} (1 to {MAX_GRID})"
            )));
        }
        let Histories {
            max_order, split, ..
        } = histories;
        if max_order == 0 {
            return Err(SimError::OutOfRange(
                "scatter: max_order must be ≥ 1".into(),
            ));
        }
        if !(1..=MAX_SPLIT).contains(&split) {
            return Err(SimError::OutOfRange(format!(
                "scatter: split = {split}; give 1 to {MAX_SPLIT} branches (1: no splitting)"
            )));
        }
        let pixels = Aim::new(aim);
        let f_tot = pixels.total();
        let n_tot = *self.cdf.last().expect("non-empty");
        let w0 = self.mas * n_tot * f_tot / photons as f64;
        let sgrid = ScoreGrid::new(view, grid);
        // Photons scattered again on a grid of their own, when it differs.
        let mgrid = (multiple_grid != grid).then(|| ScoreGrid::new(view, multiple_grid));
        let channels = self.response.channels();
        let batches = photons.div_ceil(BATCH);
        let checking = detection.is_some() && histories.cell_check > 0;
        let mut tallies: Vec<(Tally, Option<Tally>, Option<CellCheck>)> = (0..batches)
            .into_par_iter()
            .map(|b| {
                let mut rng = ChaCha8Rng::seed_from_u64(frame_seed(seed, b));
                let mut tally = Tally::new(channels, sgrid.len());
                let mut mtally = mgrid.as_ref().map(|g| Tally::new(channels, g.len()));
                // Its own key: the check draws from no random stream of the histories.
                let mut check = checking
                    .then(|| CellCheck::new(u64::from(histories.cell_check), frame_seed(!seed, b)));
                let n = BATCH.min(photons - b * BATCH) as usize;
                let starts = BatchStarts::new(self.analog, histories.sampler, n, &mut rng);
                let mut segments = Vec::new();
                for j in 0..n {
                    let Start {
                        pixel,
                        within: (jr, jc),
                        u_energy,
                        u_depth,
                    } = starts.draw(&pixels, j, &mut rng);
                    let (r, c) = ((pixel / aim.cols) as f64, (pixel % aim.cols) as f64);
                    let target = aim.pixel_centre(r + jr - 0.5, c + jc - 0.5);
                    let u = u_energy * n_tot;
                    let k = self
                        .cdf
                        .partition_point(|&c| c <= u)
                        .min(self.cdf.len() - 1);
                    let e = self.energies_kev[k];
                    let (dir, w) = ((target - source).normalize(), (w0, w0, 0));
                    self.history(
                        source,
                        dir,
                        e,
                        w,
                        histories,
                        (&sgrid, &mut tally),
                        mgrid.as_ref().zip(mtally.as_mut()),
                        (detection, check.as_mut()),
                        (u_depth, &mut segments),
                        &mut starts.stream(j, &mut rng),
                    );
                }
                (tally, mtally, check)
            })
            .collect();
        if checking {
            // The run's ratio full resolution / cells per component, summed in batch order.
            let mut all = CellCheck::default();
            for (_, _, k) in &tallies {
                if let Some(k) = k {
                    all.add(k);
                }
            }
            let ratios = all.ratios();
            for (t, m, _) in &mut tallies {
                for (comp, &f) in ratios.iter().enumerate() {
                    t.scale_component(comp, f);
                }
                if let Some(m) = m {
                    m.scale_component(Component::Multiple as usize, ratios[2]);
                }
            }
        }
        let mut sum = Tally::new(channels, sgrid.len());
        let mut msum = mgrid.as_ref().map(|g| Tally::new(channels, g.len()));
        for (t, m, _) in &tallies {
            sum.add(t);
            if let (Some(s), Some(m)) = (msum.as_mut(), m) {
                s.add(m);
            }
        }
        // Channel 0's total at the single grid's points (the multiple image resampled there
        // when it has points of its own).
        let total0 = |t: &Tally, m: Option<&Tally>| match (m, mgrid.as_ref()) {
            (Some(m), Some(g)) => {
                let multiple = m.channel0(&[Component::Multiple as usize]);
                let at = sgrid.resample(g, &multiple, view.rows, view.cols);
                t.channel0(&[0, 1])
                    .iter()
                    .zip(at)
                    .map(|(a, b)| a + b)
                    .collect()
            }
            _ => t.total0(),
        };
        let grid_mean = total0(&sum, msum.as_ref());
        let grid_standard_error = if tallies.len() < 2 {
            vec![f64::INFINITY; grid_mean.len()]
        } else {
            let nb = tallies.len() as f64;
            let mut ss = vec![0.0; grid_mean.len()];
            for (t, m, _) in &tallies {
                let x = total0(t, m.as_ref());
                for (s, (x, m)) in ss.iter_mut().zip(x.iter().zip(&grid_mean)) {
                    *s += (x - m / nb).powi(2);
                }
            }
            ss.iter().map(|s| (s * nb / (nb - 1.0)).sqrt()).collect()
        };
        if smoothing > 0.0 {
            for (g, t) in [(&sgrid, &mut sum)]
                .into_iter()
                .chain(mgrid.as_ref().zip(msum.as_mut()))
            {
                let pts = g.len();
                for chunk in t.mean.chunks_mut(pts).chain(t.second.chunks_mut(pts)) {
                    smooth(chunk, g.rows, g.cols, smoothing);
                }
            }
        }
        let blank = ExpectedImage {
            rows: view.rows,
            cols: view.cols,
            channels,
            pitch_u_mm: view.u.length(),
            pitch_v_mm: view.v.length(),
            mean: vec![0.0; channels * view.rows * view.cols],
            second_moment: vec![0.0; channels * view.rows * view.cols],
        };
        let image = |g: &ScoreGrid, t: &Tally, c: Component| {
            let mut im = blank.clone();
            to_image(g, t, c as usize, &mut im);
            im
        };
        let multiple = match (mgrid.as_ref(), msum.as_ref()) {
            (Some(g), Some(t)) => image(g, t, Component::Multiple),
            _ => image(&sgrid, &sum, Component::Multiple),
        };
        Ok(ScatterImages {
            single_compton: image(&sgrid, &sum, Component::SingleCompton),
            single_rayleigh: image(&sgrid, &sum, Component::SingleRayleigh),
            multiple,
            grid: (sgrid.rows, sgrid.cols),
            grid_mean,
            grid_standard_error,
        })
    }
}
