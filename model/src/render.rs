//! Projection rendering: the differentiable line integral Σ mu(δ_q)·Δs over a ray's Q
//! samples, in sim's units (mu in mm⁻¹, Δs in mm, the integral dimensionless).

use crate::error::{Result, ensure};
use burn::tensor::Tensor;
use burn::tensor::activation::relu;
use serde::{Deserialize, Serialize};

/// How the field's normalised density δ maps to attenuation:
/// `mu = mu_per_unit · max(δ − threshold, 0)` (mm⁻¹).
///
/// For a data set normalised over the HU window [lo, hi] at an effective energy with water
/// attenuation mu_w, sim's `hu_to_mu` (mu_w·(1 + HU/1000), 0 below −1000 HU) with
/// HU = lo + δ(hi − lo) is exactly this map with `mu_per_unit = mu_w(hi − lo)/1000` and
/// `threshold = (−1000 − lo)/(hi − lo)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DensityScale {
    /// mm⁻¹ per unit of density above the threshold.
    pub mu_per_unit: f64,
    /// Density of zero attenuation (air at −1000 HU).
    pub threshold: f64,
}

impl DensityScale {
    /// Density is mu itself (mm⁻¹).
    pub const IDENTITY: Self = Self {
        mu_per_unit: 1.0,
        threshold: 0.0,
    };

    /// The map for data normalised over the HU window `[lo, hi]` with water attenuation
    /// `mu_water_per_mm`.
    pub fn from_window(lo: f64, hi: f64, mu_water_per_mm: f64) -> Result<Self> {
        ensure!(
            lo.is_finite() && hi.is_finite() && lo < hi,
            "HU window [{lo}, {hi}] must be finite with lo < hi"
        );
        ensure!(
            mu_water_per_mm.is_finite() && mu_water_per_mm > 0.0,
            "water attenuation {mu_water_per_mm} mm⁻¹ must be > 0"
        );
        Ok(Self {
            mu_per_unit: mu_water_per_mm * (hi - lo) / 1000.0,
            threshold: (-1000.0 - lo) / (hi - lo),
        })
    }

    /// mu (mm⁻¹) of densities, any shape.
    pub fn mu<const D: usize>(&self, density: Tensor<D>) -> Tensor<D> {
        relu(density.sub_scalar(self.threshold)).mul_scalar(self.mu_per_unit)
    }

    /// mu of one density value.
    pub fn mu_scalar(&self, density: f64) -> f64 {
        self.mu_per_unit * (density - self.threshold).max(0.0)
    }
}

/// Line integrals `[B, R]` from attenuation samples `mu` `[B, R, Q]` (mm⁻¹) and each ray's
/// interval length `step_mm` `[B, R]`: the midpoint (or stratified) rule Σ_q mu_q·Δs.
pub fn line_integral(mu: Tensor<3>, step_mm: Tensor<2>) -> Tensor<2> {
    let [b, r, _] = mu.dims();
    mu.sum_dim(2).reshape([b, r]) * step_mm
}

/// Rays of a batch ready for the field: normalised points `[B, R·Q, 3]`, the prior (mean
/// training volume) at them `[B, R·Q]`, interval lengths `[B, R]` (mm) and poses `[B, 3]`
/// (unit isocentre-to-source vectors).
#[derive(Debug, Clone)]
pub struct RayTensors {
    /// Normalised sample points.
    pub points: Tensor<3>,
    /// The mean training volume at the points (normalised density).
    pub prior: Tensor<2>,
    /// Δs per ray, mm.
    pub step_mm: Tensor<2>,
    /// Poses ξ as unit vectors.
    pub pose: Tensor<2>,
    /// Rays per item R.
    pub rays: usize,
    /// Samples per ray Q.
    pub samples: usize,
}

impl RayTensors {
    /// Tensors of `batch` items' rays from flat row-major buffers: points (normalised,
    /// `batch·rays·samples·3`), Δs (mm, `batch·rays`), poses (`batch·3`); the prior is
    /// sampled from `mean` at the points.
    pub fn new(
        points: Vec<f32>,
        step_mm: Vec<f32>,
        poses: Vec<f32>,
        rays: usize,
        samples: usize,
        mean: &crate::prior::MeanVolume,
        device: &burn::tensor::Device,
    ) -> Self {
        use burn::tensor::TensorData;
        let b = poses.len() / 3;
        let prior = mean.tensor_at(&points, b, device);
        Self {
            points: Tensor::from_data(TensorData::new(points, [b, rays * samples, 3]), device),
            prior,
            step_mm: Tensor::from_data(TensorData::new(step_mm, [b, rays]), device),
            pose: Tensor::from_data(TensorData::new(poses, [b, 3]), device),
            rays,
            samples,
        }
    }
}

/// The generator's forward pass for codes `z_sh` `[B, M_sh]`, `z_a` `[B, M_a]`: densities
/// V' `[B, R, Q]` and line integrals P' `[B, R]`.
pub fn render_field(
    field: &crate::field::RadianceField,
    z_sh: Tensor<2>,
    z_a: Tensor<2>,
    rays: &RayTensors,
    scale: &DensityScale,
) -> (Tensor<3>, Tensor<2>) {
    let b = rays.pose.dims()[0];
    let density = field
        .density(
            rays.points.clone(),
            rays.prior.clone(),
            rays.pose.clone(),
            z_sh,
            z_a,
        )
        .reshape([b, rays.rays, rays.samples]);
    let integral = line_integral(scale.mu(density.clone()), rays.step_mm.clone());
    (density, integral)
}
