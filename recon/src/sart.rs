//! SART and SIRT on the exact Siddon operator, with optional TV regularisation
//! (SART-TV / ASD-POCS).
//!
//! One iteration sweeps the ordered subsets `S` (view `i` belongs to subset `i mod n`):
//!
//! ```text
//! x ← x + λ · (Aₛᵀ ((pₛ − Aₛ x) / Aₛ1)) / Aₛᵀ1        then x ← max(x, 0) if non-negative
//! ```
//!
//! with `Aₛ1` the row sums (ray lengths in the grid) and `Aₛᵀ1` the column sums (the
//! backprojection of ones) of the subset (A. H. Andersen and A. C. Kak, "Simultaneous
//! algebraic reconstruction technique (SART)", Ultrason. Imaging 6 (1984) 81). One subset
//! holding every view is SIRT; one subset per view is classic SART. Rays that miss the
//! grid and voxels no ray of the subset crosses are left alone. With TV, each sweep is
//! followed by [`super::tv::tv_descent`] steps scaled by the size of the sweep's update.
//!
//! Forward projections use [`Renderer`] with the Siddon projector (the same exact
//! segments as [`SiddonOperator::forward_view`], traced with the SIMD packet tracer where
//! it applies and clipped to the non-zero part of `x`; values agree to ~1e-12 relative
//! before rounding to f32); backprojections use the exact adjoint.
//!
//! After each iteration the relative residual `‖Ax − p‖ / ‖p‖` over all views is reported
//! to a callback; iterations stop at the cap or when the residual improves by less than
//! `tolerance` (relative) from one iteration to the next.

use super::backproject::SiddonOperator;
use super::tv::{TvOptions, norm2, tv_descent};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::View;
use tomograf_sim::render::{Projection, Projector, Renderer};
use tomograf_sim::volume::Volume;

/// SART / SIRT settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SartOptions {
    /// Iteration cap (full sweeps over all subsets); ≥ 1.
    pub iterations: usize,
    /// Ordered subsets; 1 = SIRT, the number of views = classic SART. Capped at the
    /// number of views.
    pub subsets: usize,
    /// Relaxation `λ` in (0, 2).
    pub relaxation: f64,
    /// Clamp negative attenuation to 0 after every update.
    pub nonnegative: bool,
    /// Stop when the relative residual improves by less than this fraction in one
    /// iteration (0: run to the cap).
    pub tolerance: f64,
    /// TV steps after each sweep (`None`: plain SART/SIRT).
    pub tv: Option<TvOptions>,
}

impl Default for SartOptions {
    fn default() -> Self {
        Self {
            iterations: 20,
            subsets: 10,
            relaxation: 1.0,
            nonnegative: true,
            tolerance: 0.0,
            tv: Some(TvOptions::default()),
        }
    }
}

impl SartOptions {
    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        if self.iterations == 0 {
            return Err(SimError::OutOfRange(
                "SART needs at least 1 iteration".into(),
            ));
        }
        if self.subsets == 0 {
            return Err(SimError::OutOfRange("SART needs at least 1 subset".into()));
        }
        if !(self.relaxation > 0.0 && self.relaxation < 2.0) {
            return Err(SimError::OutOfRange(format!(
                "relaxation λ = {}; it must lie in (0, 2)",
                self.relaxation
            )));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(SimError::OutOfRange(format!(
                "tolerance {} must be finite and ≥ 0",
                self.tolerance
            )));
        }
        if let Some(tv) = &self.tv {
            tv.validate()?;
        }
        Ok(())
    }
}

/// What one iteration achieved.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IterationReport {
    /// 1-based iteration number.
    pub iteration: usize,
    /// Iteration cap.
    pub of: usize,
    /// `‖Ax − p‖ / ‖p‖` over all views after this iteration.
    pub residual: f64,
    /// `‖x_after − x_before‖ / ‖x_after‖` over the whole iteration (TV included).
    pub change: f64,
}

/// A reconstructed volume and its iteration history.
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstruction {
    /// Linear attenuation, mm⁻¹, on the template's grid.
    pub volume: Volume,
    /// One report per iteration run.
    pub history: Vec<IterationReport>,
}

/// SART (or SIRT, or SART-TV, per `options`) from line-integral images taken in `views`,
/// on the grid of `template`, starting from zero. See the module docs.
pub fn sart_tv(
    projections: &[Projection],
    views: &[View],
    options: &SartOptions,
    template: &Volume,
) -> Result<Reconstruction> {
    sart_tv_with_progress(projections, views, options, template, |_| {})
}

/// [`sart_tv`], calling `progress` after every iteration.
pub fn sart_tv_with_progress(
    projections: &[Projection],
    views: &[View],
    options: &SartOptions,
    template: &Volume,
    progress: impl FnMut(&IterationReport),
) -> Result<Reconstruction> {
    sart_tv_from(projections, views, options, template, None, progress)
}

/// [`sart_tv_with_progress`] starting from `start` (attenuation in mm⁻¹ on the template's
/// grid, e.g. a prior such as the mean of a training population) instead of zero; `None`
/// starts from zero. Errors if `start` has another voxel count or non-finite values.
pub fn sart_tv_from(
    projections: &[Projection],
    views: &[View],
    options: &SartOptions,
    template: &Volume,
    start: Option<&[f32]>,
    mut progress: impl FnMut(&IterationReport),
) -> Result<Reconstruction> {
    options.validate()?;
    super::check_projections(projections, views)?;
    if let Some(s) = start
        && (s.len() != template.len() || !s.iter().all(|v| v.is_finite()))
    {
        return Err(SimError::InvalidVolume(format!(
            "SART start volume: {} finite values needed (the template's voxels), got {} \
             values{}",
            template.len(),
            s.len(),
            if s.iter().all(|v| v.is_finite()) {
                ""
            } else {
                ", some not finite"
            }
        )));
    }
    let op = SiddonOperator::new(template, views)?;
    let dims = template.dims();
    let n_sub = options.subsets.min(views.len());
    let subsets: Vec<Vec<usize>> = (0..n_sub)
        .map(|s| (s..views.len()).step_by(n_sub).collect())
        .collect();
    let p: Vec<Vec<f64>> = projections
        .iter()
        .map(|q| q.data.iter().map(|&x| f64::from(x)).collect())
        .collect();
    let lengths: Vec<Vec<f64>> = (0..views.len()).map(|v| op.ray_lengths(v)).collect();
    let p_norm = p
        .iter()
        .map(|v| norm2(v.par_iter().copied()).powi(2))
        .sum::<f64>()
        .sqrt();
    // TV smoothing: far below any contrast that matters (mu of water ≈ 0.02 mm⁻¹).
    let eps = 1e-8;

    let mut x = start.map_or_else(|| vec![0.0f32; template.len()], <[f32]>::to_vec);
    let mut history = Vec::new();
    let mut last_residual = f64::INFINITY;
    for it in 1..=options.iterations {
        let x_start = x.clone();
        for sub in &subsets {
            // Normalised residual images of the subset.
            let current = super::on_grid(template, x.clone())?;
            let renderer = Renderer::new(&current, Projector::Siddon)?;
            let res: Vec<Vec<f64>> = sub
                .iter()
                .map(|&v| {
                    let ax = renderer.render(&views[v]).map(|p| p.data)?;
                    Ok(ax
                        .iter()
                        .zip(&p[v])
                        .zip(&lengths[v])
                        .map(|((&a, b), l)| {
                            if *l > 1e-9 {
                                (b - f64::from(a)) / l
                            } else {
                                0.0
                            }
                        })
                        .collect())
                })
                .collect::<Result<_>>()?;
            let refs: Vec<&[f64]> = res.iter().map(Vec::as_slice).collect();
            let mut num = vec![0.0f64; x.len()];
            let mut den = vec![0.0f64; x.len()];
            op.adjoint_into(sub, &refs, &mut num, Some(&mut den));
            let lambda = options.relaxation;
            let nonneg = options.nonnegative;
            x.par_iter_mut()
                .zip(num.par_iter().zip(den.par_iter()))
                .for_each(|(xv, (&n, &d))| {
                    if d > 1e-9 {
                        let mut y = f64::from(*xv) + lambda * n / d;
                        if nonneg {
                            y = y.max(0.0);
                        }
                        *xv = y as f32;
                    }
                });
        }
        if let Some(tv) = &options.tv {
            let dp = norm2(
                x.par_iter()
                    .zip(x_start.par_iter())
                    .map(|(&a, &b)| f64::from(a) - f64::from(b)),
            );
            tv_descent(&mut x, dims, tv, dp, eps, options.nonnegative);
        }
        // Report.
        let current = super::on_grid(template, x.clone())?;
        let renderer = Renderer::new(&current, Projector::Siddon)?;
        let r2: Vec<f64> = (0..views.len())
            .map(|v| {
                let ax = renderer.render(&views[v])?.data;
                Ok(norm2(
                    ax.par_iter()
                        .zip(p[v].par_iter())
                        .map(|(&a, b)| f64::from(a) - b),
                )
                .powi(2))
            })
            .collect::<Result<_>>()?;
        let residual = r2.iter().sum::<f64>().sqrt() / p_norm.max(f64::MIN_POSITIVE);
        let dx = norm2(
            x.par_iter()
                .zip(x_start.par_iter())
                .map(|(&a, &b)| f64::from(a) - f64::from(b)),
        );
        let xn = norm2(x.par_iter().map(|&a| f64::from(a)));
        let report = IterationReport {
            iteration: it,
            of: options.iterations,
            residual,
            change: if xn > 0.0 { dx / xn } else { 0.0 },
        };
        progress(&report);
        history.push(report);
        let improved = (last_residual - residual) / last_residual;
        last_residual = residual;
        if options.tolerance > 0.0 && it > 1 && improved < options.tolerance {
            break;
        }
    }
    Ok(Reconstruction {
        volume: super::on_grid(template, x)?,
        history,
    })
}
