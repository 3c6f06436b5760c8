//! Losses: hinge (eqs. 9–10), reconstruction (eqs. 7–8) with a swappable perceptual
//! distance, and the inference terms of eq. 13 (PSNR and the codes' negative
//! log-likelihood).
//!
//! **Deviation from the paper:** LPIPS needs ImageNet-trained VGG16 weights, which cannot be
//! downloaded here. [`SsimL1`] (global SSIM with the paper's constants plus L1) stands in
//! for it behind the [`Perceptual`] trait, so a learned metric can be plugged in later.

use burn::tensor::Tensor;
use burn::tensor::activation::relu;

/// A perceptual distance between batches of images or volumes, flattened to `[B, N]`;
/// returns a scalar tensor `[1]` (mean over the batch).
pub trait Perceptual: Send + Sync + std::fmt::Debug {
    /// The distance; 0 for identical inputs.
    fn distance(&self, a: Tensor<2>, b: Tensor<2>) -> Tensor<1>;
}

/// `(1 − SSIM)/2 + L1`, SSIM over each whole sample with k1 = 0.01, k2 = 0.03, L = 1 (the
/// data's [0, 1] range).
#[derive(Debug, Clone, Copy, Default)]
pub struct SsimL1;

impl Perceptual for SsimL1 {
    fn distance(&self, a: Tensor<2>, b: Tensor<2>) -> Tensor<1> {
        let l1 = (a.clone() - b.clone()).abs().mean();
        let s = global_ssim(a, b);
        (s.neg().add_scalar(1.0)).mul_scalar(0.5).mean() + l1
    }
}

/// SSIM of each row of `a` and `b` (`[B, N]` → `[B]`), statistics over the whole row,
/// c1 = (0.01·1)², c2 = (0.03·1)².
pub fn global_ssim(a: Tensor<2>, b: Tensor<2>) -> Tensor<1> {
    let (c1, c2) = (1e-4, 9e-4);
    let [bsz, _] = a.dims();
    let ma = a.clone().mean_dim(1);
    let mb = b.clone().mean_dim(1);
    let da = a - ma.clone();
    let db = b - mb.clone();
    let va = (da.clone() * da.clone()).mean_dim(1);
    let vb = (db.clone() * db.clone()).mean_dim(1);
    let cov = (da * db).mean_dim(1);
    let num = (ma.clone() * mb.clone()).mul_scalar(2.0).add_scalar(c1)
        * cov.mul_scalar(2.0).add_scalar(c2);
    let den = (ma.clone() * ma + mb.clone() * mb).add_scalar(c1) * (va + vb).add_scalar(c2);
    (num / den).reshape([bsz])
}

/// Discriminator hinge loss: E[max(0, 1 − D(real))] + E[max(0, 1 + D(fake))].
pub fn hinge_discriminator(real: Tensor<1>, fake: Tensor<1>) -> Tensor<1> {
    relu(real.neg().add_scalar(1.0)).mean() + relu(fake.add_scalar(1.0)).mean()
}

/// Generator hinge loss: −E[D(fake)].
pub fn hinge_generator(fake: Tensor<1>) -> Tensor<1> {
    fake.mean().neg()
}

/// 10·log10(MSE) of `[B, N]` images with values in [0, 1]: −PSNR (dB, MAX = 1); minimising
/// it raises the PSNR.
pub fn neg_psnr(a: Tensor<2>, b: Tensor<2>) -> Tensor<1> {
    let d = a - b;
    (d.clone() * d)
        .mean()
        .add_scalar(1e-10)
        .log()
        .mul_scalar(10.0 / std::f64::consts::LN_10)
}

/// Negative log-likelihood of codes under N(0, I), per element, constants dropped:
/// mean(z²)/2.
pub fn code_nll(z: Tensor<2>) -> Tensor<1> {
    (z.clone() * z).mean().mul_scalar(0.5)
}
