//! The learned prior's fixed parts: the mean training volume, which the field's density is
//! a residual on, and the statistics of the training codes, which inference starts from and
//! regularises towards.

use crate::error::{Result, ensure};
use burn::tensor::{Device, Tensor, TensorData};
use serde::{Deserialize, Serialize};
use tomograf_sim::Volume;
use tomograf_sim::trace::trilinear;

/// The voxel-wise mean of the training CTs (normalised density, on their common grid).
#[derive(Debug, Clone, PartialEq)]
pub struct MeanVolume {
    /// Voxel values, `i` fastest.
    pub data: Vec<f32>,
    /// Grid size.
    pub dims: [usize; 3],
}

impl MeanVolume {
    /// The mean of `volumes`; errors unless they share one grid size.
    pub fn from_volumes<'a>(volumes: impl IntoIterator<Item = &'a Volume>) -> Result<Self> {
        let mut sum: Vec<f64> = Vec::new();
        let mut dims = [0; 3];
        let mut n = 0usize;
        for v in volumes {
            if n == 0 {
                dims = v.dims();
                sum = vec![0.0; v.len()];
            }
            ensure!(
                v.dims() == dims,
                "training volumes differ in size ({:?} and {:?}); the mean needs one grid",
                dims,
                v.dims()
            );
            for (s, &x) in sum.iter_mut().zip(v.data()) {
                *s += f64::from(x);
            }
            n += 1;
        }
        ensure!(n > 0, "no training volumes for the mean");
        Ok(Self {
            data: sum.iter().map(|s| (s / n as f64) as f32).collect(),
            dims,
        })
    }

    /// The mean at points in normalised grid coordinates (`[x, y, z]` triples in [−1, 1]
    /// across the grid box, flat), with sim's trilinear field: voxel-centre values,
    /// trilinear between centres, clamped in the outer half voxel, 0 outside the box. Any
    /// grid of the same box maps onto this one, whatever its voxel count.
    pub fn at_normalised(&self, points: &[f32]) -> Vec<f32> {
        points
            .chunks_exact(3)
            .map(|p| {
                let g = [0, 1, 2].map(|a| (f64::from(p[a]) + 1.0) * 0.5 * self.dims[a] as f64);
                trilinear::sample(&self.data, self.dims, g) as f32
            })
            .collect()
    }

    /// [`Self::at_normalised`] as a `[batch, points/batch]` tensor.
    pub fn tensor_at(&self, points: &[f32], batch: usize, device: &Device) -> Tensor<2> {
        let v = self.at_normalised(points);
        let n = v.len() / batch.max(1);
        Tensor::from_data(TensorData::new(v, [batch, n]), device)
    }
}

/// Per-dimension mean and spread of the training codes (shape codes, then appearance
/// codes): the Gaussian that inference starts from (its mean) and whose negative
/// log-likelihood regularises the fitted codes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CodeStats {
    /// Mean of z_sh per dimension.
    pub shape_mean: Vec<f32>,
    /// Standard deviation of z_sh per dimension (≥ 1e-3).
    pub shape_std: Vec<f32>,
    /// Mean of z_a per dimension.
    pub app_mean: Vec<f32>,
    /// Standard deviation of z_a per dimension (≥ 1e-3).
    pub app_std: Vec<f32>,
}

fn column_stats(values: &[f32], rows: usize) -> (Vec<f32>, Vec<f32>) {
    let m = values.len() / rows.max(1);
    let mut mean = vec![0.0f64; m];
    for r in values.chunks_exact(m) {
        for (a, &v) in mean.iter_mut().zip(r) {
            *a += f64::from(v) / rows as f64;
        }
    }
    let mut var = vec![0.0f64; m];
    for r in values.chunks_exact(m) {
        for ((a, &v), mu) in var.iter_mut().zip(r).zip(&mean) {
            *a += (f64::from(v) - mu).powi(2) / (rows.max(2) - 1) as f64;
        }
    }
    (
        mean.iter().map(|&x| x as f32).collect(),
        var.iter().map(|&x| (x.sqrt() as f32).max(1e-3)).collect(),
    )
}

impl CodeStats {
    /// The standard normal N(0, I) (codes drawn at random, as the paper's GAN does).
    pub fn standard(z_shape: usize, z_app: usize) -> Self {
        Self {
            shape_mean: vec![0.0; z_shape],
            shape_std: vec![1.0; z_shape],
            app_mean: vec![0.0; z_app],
            app_std: vec![1.0; z_app],
        }
    }

    /// The statistics of a code table (`rows` rows of each); a single row has spread 1.
    pub fn from_table(shape: &[f32], app: &[f32], rows: usize) -> Self {
        let (shape_mean, mut shape_std) = column_stats(shape, rows);
        let (app_mean, mut app_std) = column_stats(app, rows);
        if rows < 2 {
            shape_std.fill(1.0);
            app_std.fill(1.0);
        }
        Self {
            shape_mean,
            shape_std,
            app_mean,
            app_std,
        }
    }

    /// Codes `(z_sh, z_a)` `[1, M]` from whitened codes `u_sh`, `u_a`: z = μ + σ ⊙ u.
    pub fn codes(&self, u_sh: Tensor<2>, u_a: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        let device = u_sh.device();
        let t =
            |v: &[f32]| Tensor::<2>::from_data(TensorData::new(v.to_vec(), [1, v.len()]), &device);
        (
            u_sh * t(&self.shape_std) + t(&self.shape_mean),
            u_a * t(&self.app_std) + t(&self.app_mean),
        )
    }

    /// Whitened values (u = (z − μ)/σ) of one code `(z_sh, z_a)`.
    pub fn whiten(&self, z_sh: &[f32], z_a: &[f32]) -> (Vec<f32>, Vec<f32>) {
        let w = |z: &[f32], m: &[f32], s: &[f32]| {
            z.iter()
                .zip(m)
                .zip(s)
                .map(|((z, m), s)| (z - m) / s)
                .collect()
        };
        (
            w(z_sh, &self.shape_mean, &self.shape_std),
            w(z_a, &self.app_mean, &self.app_std),
        )
    }
}
