//! The self-supervised auto-encoding discriminators (Methods 1.2.2, after MedNeRF and
//! FastGAN): D1 convolves sub-volumes in 3D, D2 patches in 2D. Each has a shared body, one
//! logit head per DAG transformation, and a decoder that reconstructs its (real) input at
//! a quarter of its resolution from the body's features.

use burn::module::Module;
use burn::nn::PaddingConfig2d;
use burn::nn::PaddingConfig3d;
use burn::nn::conv::{Conv2d, Conv2dConfig, Conv3d, Conv3dConfig};
use burn::tensor::activation::leaky_relu;
use burn::tensor::{Device, Tensor};

const SLOPE: f64 = 0.2;

/// D2: patches `[B, 1, M, M]` → logits `[B]` and a decoded `[B, 1, M/4, M/4]`.
#[derive(Module, Debug)]
pub struct PatchDiscriminator {
    c1: Conv2d,
    c2: Conv2d,
    c3: Conv2d,
    heads: Vec<Conv2d>,
    dec1: Conv2d,
    dec2: Conv2d,
}

impl PatchDiscriminator {
    /// `channels` in the first layer, `heads` DAG heads.
    pub fn new(channels: usize, heads: usize, device: &Device) -> Self {
        let c = channels;
        let down = |i, o| {
            Conv2dConfig::new([i, o], [4, 4])
                .with_stride([2, 2])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .init(device)
        };
        let same = |i, o, k: usize| {
            let p = k / 2;
            Conv2dConfig::new([i, o], [k, k])
                .with_padding(PaddingConfig2d::Explicit(p, p, p, p))
                .init(device)
        };
        Self {
            c1: down(1, c),
            c2: down(c, 2 * c),
            c3: same(2 * c, 4 * c, 3),
            heads: (0..heads).map(|_| same(4 * c, 1, 3)).collect(),
            dec1: same(2 * c, c, 3),
            dec2: same(c, 1, 1),
        }
    }

    /// Logits of head `k` and the decoder's reconstruction.
    pub fn forward(&self, x: Tensor<4>, k: usize) -> (Tensor<1>, Tensor<4>) {
        let b = x.dims()[0];
        let f = leaky_relu(
            self.c2.forward(leaky_relu(self.c1.forward(x), SLOPE)),
            SLOPE,
        );
        let recon = self
            .dec2
            .forward(leaky_relu(self.dec1.forward(f.clone()), SLOPE));
        let h = leaky_relu(self.c3.forward(f), SLOPE);
        let logit = self.heads[k].forward(h).reshape([b as i32, -1]).mean_dim(1);
        (logit.reshape([b]), recon)
    }
}

/// D1: sub-volumes `[B, 1, Q, M, M]` → logits `[B]` and a decoded `[B, 1, Q/4, M/4, M/4]`.
#[derive(Module, Debug)]
pub struct VolumeDiscriminator {
    c1: Conv3d,
    c2: Conv3d,
    c3: Conv3d,
    heads: Vec<Conv3d>,
    dec1: Conv3d,
    dec2: Conv3d,
}

impl VolumeDiscriminator {
    /// `channels` in the first layer, `heads` DAG heads.
    pub fn new(channels: usize, heads: usize, device: &Device) -> Self {
        let c = channels;
        let down = |i, o| {
            Conv3dConfig::new([i, o], [4, 4, 4])
                .with_stride([2, 2, 2])
                .with_padding(PaddingConfig3d::Explicit(1, 1, 1))
                .init(device)
        };
        let same = |i, o, k: usize| {
            let p = k / 2;
            Conv3dConfig::new([i, o], [k, k, k])
                .with_padding(PaddingConfig3d::Explicit(p, p, p))
                .init(device)
        };
        Self {
            c1: down(1, c),
            c2: down(c, 2 * c),
            c3: same(2 * c, 4 * c, 3),
            heads: (0..heads).map(|_| same(4 * c, 1, 3)).collect(),
            dec1: same(2 * c, c, 3),
            dec2: same(c, 1, 1),
        }
    }

    /// Logits of head `k` and the decoder's reconstruction.
    pub fn forward(&self, x: Tensor<5>, k: usize) -> (Tensor<1>, Tensor<5>) {
        let b = x.dims()[0];
        let f = leaky_relu(
            self.c2.forward(leaky_relu(self.c1.forward(x), SLOPE)),
            SLOPE,
        );
        let recon = self
            .dec2
            .forward(leaky_relu(self.dec1.forward(f.clone()), SLOPE));
        let h = leaky_relu(self.c3.forward(f), SLOPE);
        let logit = self.heads[k].forward(h).reshape([b as i32, -1]).mean_dim(1);
        (logit.reshape([b]), recon)
    }
}
