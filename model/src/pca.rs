//! A linear statistical prior: the mean of the training volumes plus their principal
//! components, with the coefficients of a held-out item found by a MAP fit to its views
//! (a Gaussian prior with the components' variances; components projected with sim's
//! Siddon projector). The baseline a learned, nonlinear prior has to beat.
//!
//! With training volumes x_n (normalised density, N of them, V voxels), the mean m and the
//! centred rows X, the components come from the N×N Gram matrix X·Xᵀ/(N − 1) = E Λ Eᵀ:
//! c_k = Xᵀe_k / √((N − 1)λ_k), unit-norm, with variance λ_k. For references p (line
//! integrals), the projection is affine in the coefficients a where the density is above
//! air's threshold (mu = k·(δ − t)): p ≈ A·mu(m) + Σ_k a_k·k·A·c_k, so the MAP estimate is
//! (JᵀJ/σ² + Λ⁻¹)·a = Jᵀ(p − A·mu(m))/σ², σ the assumed noise of the scaled projections.

use crate::baseline::Baseline;
use crate::error::{Result, ensure};
use crate::prior::MeanVolume;
use crate::reconstruct::Reference;
use crate::render::DensityScale;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::{Projector, Renderer, Volume};

/// The PCA-MAP prior's settings a user would tune.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PcaSettings {
    /// Assumed noise of the projections, as a fraction of the largest training line
    /// integral (`proj_scale`); > 0.
    pub noise: f64,
    /// Use only the first this many components (by variance); absent: all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub components: Option<usize>,
}

impl Default for PcaSettings {
    /// Noise 1 % of the largest line integral, every component.
    fn default() -> Self {
        Self {
            noise: 0.01,
            components: None,
        }
    }
}

impl PcaSettings {
    /// Checks the noise is finite and > 0 and at least one component is kept.
    pub fn validate(&self) -> Result<()> {
        ensure!(
            self.noise.is_finite() && self.noise > 0.0 && self.noise <= 1e6,
            "PCA-MAP noise {} must be > 0 (a fraction of the largest line integral)",
            self.noise
        );
        ensure!(
            self.components != Some(0),
            "PCA-MAP with 0 components is the mean volume: give at least 1"
        );
        Ok(())
    }
}

/// The linear system of a MAP fit: the components' projections `J` (one column each) and
/// the residual of the mean's projection, both scaled by the projections' scale.
#[derive(Debug, Clone)]
pub struct PcaSystem {
    j: DMatrix<f64>,
    residual: DVector<f64>,
}

/// Principal components of a set of training volumes, and the MAP fit of their
/// coefficients to a new item's views.
#[derive(Debug, Clone)]
pub struct PcaMap {
    /// The mean volume.
    pub mean: MeanVolume,
    /// Unit-norm components, each `V` values, by decreasing variance.
    pub components: Vec<Vec<f32>>,
    /// Variance of each component's coefficient (normalised density², per unit-norm
    /// component).
    pub variances: Vec<f64>,
    /// Noise and how many components the fit uses.
    pub settings: PcaSettings,
    /// The projections' scale (largest training line integral).
    pub proj_scale: f64,
}

impl PcaMap {
    /// Components of `volumes` (all on one grid; at least 2), keeping those with variance
    /// above 1e-9 of the largest. `noise` is the assumed projection noise as a fraction of
    /// `proj_scale`.
    pub fn from_volumes(volumes: &[&Volume], noise: f64, proj_scale: f64) -> Result<Self> {
        ensure!(
            volumes.len() >= 2,
            "the PCA prior needs at least 2 training volumes"
        );
        ensure!(
            noise.is_finite() && noise > 0.0 && proj_scale.is_finite() && proj_scale > 0.0,
            "PCA noise {noise} and projection scale {proj_scale} must be > 0"
        );
        let settings = PcaSettings {
            noise,
            components: None,
        };
        let mean = MeanVolume::from_volumes(volumes.iter().copied())?;
        let n = volumes.len();
        let centred: Vec<Vec<f32>> = volumes
            .iter()
            .map(|v| {
                v.data()
                    .iter()
                    .zip(&mean.data)
                    .map(|(x, m)| x - m)
                    .collect()
            })
            .collect();
        let dot = |a: &[f32], b: &[f32]| -> f64 {
            a.par_iter()
                .zip(b)
                .map(|(x, y)| f64::from(*x) * f64::from(*y))
                .sum()
        };
        let mut gram = DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            for j in 0..=i {
                let g = dot(&centred[i], &centred[j]) / (n - 1) as f64;
                gram[(i, j)] = g;
                gram[(j, i)] = g;
            }
        }
        let eig = gram.symmetric_eigen();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let top = eig.eigenvalues[order[0]].max(0.0);
        let mut components = Vec::new();
        let mut variances = Vec::new();
        for &k in &order {
            let lambda = eig.eigenvalues[k];
            if lambda.is_nan() || lambda <= 1e-9 * top {
                continue;
            }
            let norm = ((n - 1) as f64 * lambda).sqrt();
            let mut c = vec![0.0f64; mean.data.len()];
            for (i, row) in centred.iter().enumerate() {
                let w = eig.eigenvectors[(i, k)] / norm;
                c.par_iter_mut()
                    .zip(row)
                    .for_each(|(a, &x)| *a += w * f64::from(x));
            }
            components.push(c.into_iter().map(|x| x as f32).collect());
            variances.push(lambda);
        }
        Ok(Self {
            mean,
            components,
            variances,
            settings,
            proj_scale,
        })
    }

    /// The same prior fitted with `settings`.
    pub fn with(self, settings: PcaSettings) -> Self {
        Self { settings, ..self }
    }

    /// This prior as a baseline fitted with `settings` (borrowed: no copy of the
    /// components).
    pub fn fitted_with(&self, settings: PcaSettings) -> PcaFit<'_> {
        PcaFit {
            prior: self,
            settings,
        }
    }

    /// The MAP coefficients for `refs` on `grid` (normalised density → mu by `scale`),
    /// with the prior's own settings.
    pub fn fit(&self, refs: &[Reference], grid: &Volume, scale: &DensityScale) -> Result<Vec<f64>> {
        self.solve(&self.system(refs, grid, scale)?, &self.settings)
    }

    /// The fit's linear system for `refs` on `grid`: the expensive part (every component
    /// projected through every view), shared by fits with different [`PcaSettings`].
    pub fn system(
        &self,
        refs: &[Reference],
        grid: &Volume,
        scale: &DensityScale,
    ) -> Result<PcaSystem> {
        ensure!(!refs.is_empty(), "no reference views");
        ensure!(
            grid.dims() == self.mean.dims,
            "PCA prior is on a {:?} grid but the test grid is {:?}",
            self.mean.dims,
            grid.dims()
        );
        let on_grid = |data: Vec<f32>| {
            Volume::new(
                grid.dims(),
                grid.spacing(),
                grid.origin(),
                grid.direction(),
                data,
            )
        };
        let project = |v: &Volume| -> Result<Vec<f64>> {
            let r = Renderer::new(v, Projector::Siddon)?;
            let mut out = Vec::new();
            for rf in refs {
                out.extend(
                    r.render(&rf.view)?
                        .data
                        .iter()
                        .map(|&x| f64::from(x) / self.proj_scale),
                );
            }
            Ok(out)
        };
        let mu_mean = on_grid(
            self.mean
                .data
                .iter()
                .map(|&d| scale.mu_scalar(f64::from(d)) as f32)
                .collect(),
        )?;
        let base = project(&mu_mean)?;
        let target: Vec<f64> = refs
            .iter()
            .flat_map(|r| r.image.iter().map(|&x| f64::from(x) / self.proj_scale))
            .collect();
        // Each component's projection, linearised where the mean is above air's threshold.
        let active: Vec<bool> = self
            .mean
            .data
            .iter()
            .map(|&d| f64::from(d) > scale.threshold)
            .collect();
        let columns: Vec<Vec<f64>> = self
            .components
            .iter()
            .map(|c| {
                let mu: Vec<f32> = c
                    .iter()
                    .zip(&active)
                    .map(|(&x, &a)| {
                        if a {
                            (scale.mu_per_unit * f64::from(x)) as f32
                        } else {
                            0.0
                        }
                    })
                    .collect();
                project(&on_grid(mu)?)
            })
            .collect::<Result<_>>()?;
        let k = columns.len();
        let m = target.len();
        let j = DMatrix::from_fn(m, k, |r, c| columns[c][r]);
        let residual = DVector::from_iterator(m, target.iter().zip(&base).map(|(t, b)| t - b));
        Ok(PcaSystem { j, residual })
    }

    /// The MAP coefficients of `system` under `settings` (coefficients past
    /// `settings.components` are 0).
    pub fn solve(&self, system: &PcaSystem, settings: &PcaSettings) -> Result<Vec<f64>> {
        settings.validate()?;
        let all = system.j.ncols();
        let k = settings.components.unwrap_or(all).min(all);
        let j = system.j.columns(0, k);
        let s2 = settings.noise * settings.noise;
        let mut lhs = j.transpose() * j / s2;
        for (i, v) in self.variances.iter().take(k).enumerate() {
            lhs[(i, i)] += 1.0 / v;
        }
        let rhs = j.transpose() * &system.residual / s2;
        let a = lhs
            .cholesky()
            .ok_or_else(|| {
                crate::ModelError::Invalid("PCA MAP system is not positive definite".into())
            })?
            .solve(&rhs);
        let mut out: Vec<f64> = a.iter().copied().collect();
        out.resize(all, 0.0);
        Ok(out)
    }

    /// The volume of coefficients `a` on `grid`'s geometry.
    pub fn volume_on(&self, a: &[f64], grid: &Volume) -> Result<Volume> {
        Ok(Volume::new(
            grid.dims(),
            grid.spacing(),
            grid.origin(),
            grid.direction(),
            self.volume(a),
        )?)
    }

    /// The volume m + Σ a_k c_k.
    pub fn volume(&self, a: &[f64]) -> Vec<f32> {
        let mut v: Vec<f64> = self.mean.data.iter().map(|&x| f64::from(x)).collect();
        for (c, &w) in self.components.iter().zip(a) {
            v.par_iter_mut()
                .zip(c)
                .for_each(|(x, &y)| *x += w * f64::from(y));
        }
        v.into_iter().map(|x| x as f32).collect()
    }
}

impl Baseline for PcaMap {
    fn name(&self) -> &str {
        "PCA-MAP prior"
    }

    fn reconstruct(
        &self,
        refs: &[Reference],
        grid: &Volume,
        scale: &DensityScale,
    ) -> Result<Volume> {
        self.fitted_with(self.settings)
            .reconstruct(refs, grid, scale)
    }
}

/// A [`PcaMap`] fitted with other settings than its own ([`PcaMap::fitted_with`]).
#[derive(Debug, Clone, Copy)]
pub struct PcaFit<'a> {
    prior: &'a PcaMap,
    settings: PcaSettings,
}

impl Baseline for PcaFit<'_> {
    fn name(&self) -> &str {
        self.prior.name()
    }

    fn reconstruct(
        &self,
        refs: &[Reference],
        grid: &Volume,
        scale: &DensityScale,
    ) -> Result<Volume> {
        let system = self.prior.system(refs, grid, scale)?;
        let a = self.prior.solve(&system, &self.settings)?;
        self.prior.volume_on(&a, grid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// Volumes m + Σ a_k b_k with two orthogonal patterns: the components span them, and
    /// a MAP fit with little noise recovers a held-out member from its views.
    #[test]
    fn recovers_a_member_of_the_span_and_the_variances() {
        let n = 12usize;
        let len = n * n * n;
        let base: Vec<f32> = (0..len)
            .map(|i| 0.3 + 0.05 * ((i % 7) as f32 / 7.0))
            .collect();
        let b1: Vec<f32> = (0..len)
            .map(|i| if (i / n) % n < n / 2 { 0.1 } else { -0.1 })
            .collect();
        let b2: Vec<f32> = (0..len)
            .map(|i| if i % n < n / 2 { 0.1 } else { -0.1 })
            .collect();
        let make = |a1: f32, a2: f32| {
            let d: Vec<f32> = (0..len)
                .map(|i| base[i] + a1 * b1[i] + a2 * b2[i])
                .collect();
            Volume::centred([n, n, n], DVec3::splat(4.0), DVec3::ZERO, d).unwrap()
        };
        let train: Vec<Volume> = [
            (1.0, 0.0),
            (-1.0, 0.5),
            (0.5, -1.0),
            (0.0, 1.0),
            (-0.5, -0.5),
        ]
        .iter()
        .map(|&(a, b)| make(a, b))
        .collect();
        let refs: Vec<&Volume> = train.iter().collect();
        let pca = PcaMap::from_volumes(&refs, 1e-4, 1.0).unwrap();
        assert_eq!(pca.components.len(), 2, "two patterns, two components");
        let truth = make(0.7, -0.3);
        let scale = DensityScale::from_window(-1024.0, 2048.0, 0.02).unwrap();
        let mu = truth.map(|d| scale.mu_scalar(f64::from(d)) as f32).unwrap();
        let refs = crate::reference::test_references(&mu);
        let v = pca.reconstruct(&refs, &truth, &scale).unwrap();
        let err = v
            .data()
            .iter()
            .zip(truth.data())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(err < 1e-3, "max error {err}");
        // The mean alone is far off, so the fit did the work.
        let err0 = pca
            .mean
            .data
            .iter()
            .zip(truth.data())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(err0 > 0.05, "{err0}");

        // The settings: one system, several fits.
        let system = pca.system(&refs, &truth, &scale).unwrap();
        let fit = |noise: f64, components: Option<usize>| {
            pca.solve(&system, &PcaSettings { noise, components })
                .unwrap()
        };
        assert_eq!(fit(1e-4, None), pca.fit(&refs, &truth, &scale).unwrap());
        assert_eq!(fit(1e-4, Some(2)), fit(1e-4, None));
        let max_err = |a: &[f64]| {
            pca.volume(a)
                .iter()
                .zip(truth.data())
                .map(|(x, y)| (x - y).abs())
                .fold(0.0f32, f32::max)
        };
        // One component cannot hold a mix of both patterns; the other coefficient is 0.
        let one = fit(1e-4, Some(1));
        assert_eq!(one.len(), 2);
        assert_eq!(one[1], 0.0);
        assert!(max_err(&one) > 0.01, "{}", max_err(&one));
        // Noise far above the projections' scale: the prior wins, the fit stays at the mean.
        let loud = fit(1e3, None);
        assert!(loud.iter().all(|a| a.abs() < 1e-3), "{loud:?}");
        for bad in [0.0, -1.0, f64::NAN] {
            assert!(
                pca.solve(
                    &system,
                    &PcaSettings {
                        noise: bad,
                        components: None
                    }
                )
                .is_err()
            );
        }
        assert!(
            pca.solve(
                &system,
                &PcaSettings {
                    noise: 0.01,
                    components: Some(0)
                }
            )
            .is_err()
        );
        // Through the baseline interface, with other settings than the prior's own.
        let v = pca
            .fitted_with(PcaSettings {
                noise: 1e-4,
                components: Some(1),
            })
            .reconstruct(&refs, &truth, &scale)
            .unwrap();
        assert_eq!(v.data(), pca.volume(&one).as_slice());
    }
}
