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
use tomograf_sim::{Projector, Renderer, Volume};

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
    /// Assumed noise of the projections, as a fraction of the largest training line
    /// integral (`proj_scale`).
    pub noise: f64,
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
            noise,
            proj_scale,
        })
    }

    /// The MAP coefficients for `refs` on `grid` (normalised density → mu by `scale`).
    pub fn fit(&self, refs: &[Reference], grid: &Volume, scale: &DensityScale) -> Result<Vec<f64>> {
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
        let resid = DVector::from_iterator(m, target.iter().zip(&base).map(|(t, b)| t - b));
        let s2 = self.noise * self.noise;
        let mut lhs = j.transpose() * &j / s2;
        for (i, v) in self.variances.iter().enumerate() {
            lhs[(i, i)] += 1.0 / v;
        }
        let rhs = j.transpose() * resid / s2;
        let a = lhs
            .cholesky()
            .ok_or_else(|| {
                crate::ModelError::Invalid("PCA MAP system is not positive definite".into())
            })?
            .solve(&rhs);
        Ok(a.iter().copied().collect())
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
        let a = self.fit(refs, grid, scale)?;
        Ok(Volume::new(
            grid.dims(),
            grid.spacing(),
            grid.origin(),
            grid.direction(),
            self.volume(&a),
        )?)
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
        let refs = crate::reconstruct::test_references(&mu);
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
    }
}
