//! The self-supervised auto-encoding discriminators (Methods 1.2.2, after MedNeRF and
//! FastGAN): D1 convolves sub-volumes in 3D, D2 patches in 2D. Both are one definition,
//! [`Discriminator`], over a convolution of either rank: a shared body, one logit head per
//! DAG transformation, and a decoder that reconstructs its (real) input at a quarter of its
//! resolution from the body's features.

use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig, Conv3d, Conv3dConfig};
use burn::nn::{PaddingConfig2d, PaddingConfig3d};
use burn::tensor::activation::leaky_relu;
use burn::tensor::{Device, Tensor};

const SLOPE: f64 = 0.2;

/// A convolution over tensors of rank `D` (`[B, C, …]`): 2D (`D` = 4) for patches, 3D
/// (`D` = 5) for sub-volumes.
pub trait Convolution<const D: usize>: Module + std::fmt::Debug {
    /// Halves each spatial size: kernel 4, stride 2, padding 1.
    fn down(inputs: usize, outputs: usize, device: &Device) -> Self;
    /// Keeps each spatial size: kernel `k` (odd), padding `k`/2.
    fn same(inputs: usize, outputs: usize, k: usize, device: &Device) -> Self;
    /// Applies the convolution.
    fn apply(&self, x: Tensor<D>) -> Tensor<D>;
}

impl Convolution<4> for Conv2d {
    fn down(i: usize, o: usize, device: &Device) -> Self {
        Conv2dConfig::new([i, o], [4, 4])
            .with_stride([2, 2])
            .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
            .init(device)
    }
    fn same(i: usize, o: usize, k: usize, device: &Device) -> Self {
        let p = k / 2;
        Conv2dConfig::new([i, o], [k, k])
            .with_padding(PaddingConfig2d::Explicit(p, p, p, p))
            .init(device)
    }
    fn apply(&self, x: Tensor<4>) -> Tensor<4> {
        self.forward(x)
    }
}

impl Convolution<5> for Conv3d {
    fn down(i: usize, o: usize, device: &Device) -> Self {
        Conv3dConfig::new([i, o], [4, 4, 4])
            .with_stride([2, 2, 2])
            .with_padding(PaddingConfig3d::Explicit(1, 1, 1))
            .init(device)
    }
    fn same(i: usize, o: usize, k: usize, device: &Device) -> Self {
        let p = k / 2;
        Conv3dConfig::new([i, o], [k, k, k])
            .with_padding(PaddingConfig3d::Explicit(p, p, p))
            .init(device)
    }
    fn apply(&self, x: Tensor<5>) -> Tensor<5> {
        self.forward(x)
    }
}

/// One auto-encoding discriminator: inputs `[B, 1, …]` → logits `[B]` of a DAG head and the
/// input decoded at a quarter of each spatial size.
#[derive(Module, Debug)]
pub struct Discriminator<C> {
    c1: C,
    c2: C,
    c3: C,
    heads: Vec<C>,
    dec1: C,
    dec2: C,
}

/// D2: patches `[B, 1, M, M]` → logits `[B]` and a decoded `[B, 1, M/4, M/4]`.
pub type PatchDiscriminator = Discriminator<Conv2d>;
/// D1: sub-volumes `[B, 1, Q, M, M]` → logits `[B]` and a decoded `[B, 1, Q/4, M/4, M/4]`.
pub type VolumeDiscriminator = Discriminator<Conv3d>;

impl<C> Discriminator<C> {
    /// `channels` in the first layer, `heads` DAG heads.
    pub fn new<const D: usize>(channels: usize, heads: usize, device: &Device) -> Self
    where
        C: Convolution<D>,
    {
        let c = channels;
        Self {
            c1: C::down(1, c, device),
            c2: C::down(c, 2 * c, device),
            c3: C::same(2 * c, 4 * c, 3, device),
            heads: (0..heads).map(|_| C::same(4 * c, 1, 3, device)).collect(),
            dec1: C::same(2 * c, c, 3, device),
            dec2: C::same(c, 1, 1, device),
        }
    }

    /// Logits of head `k` and the decoder's reconstruction.
    pub fn forward<const D: usize>(&self, x: Tensor<D>, k: usize) -> (Tensor<1>, Tensor<D>)
    where
        C: Convolution<D>,
    {
        let b = x.dims()[0];
        let f = leaky_relu(self.c2.apply(leaky_relu(self.c1.apply(x), SLOPE)), SLOPE);
        let recon = self
            .dec2
            .apply(leaky_relu(self.dec1.apply(f.clone()), SLOPE));
        let h = leaky_relu(self.c3.apply(f), SLOPE);
        let logit = self.heads[k].apply(h).reshape([b as i32, -1]).mean_dim(1);
        (logit.reshape([b]), recon)
    }
}
