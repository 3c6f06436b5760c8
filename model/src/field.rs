//! Positional encoding γ and the conditional radiance field
//! g = d(h(γ(x), z_sh), γ(ξ), z_a) → δ ≥ 0 (Methods 1.2.1, eqs. 1–6).

use crate::config::ModelConfig;
use burn::module::{Module, Param};
use burn::nn::{Linear, LinearConfig};
use burn::tensor::activation::{relu, softplus};
use burn::tensor::{Device, Tensor, TensorData};

/// γ(p) = (p, sin(2^k π p), cos(2^k π p)) for k < `freqs`, per coordinate; `p` is `[N, 3]`,
/// the result `[N, 3 + 6·freqs]`.
pub fn encode(p: Tensor<2>, freqs: usize) -> Tensor<2> {
    let [n, d] = p.dims();
    if freqs == 0 {
        return p;
    }
    let scales: Vec<f32> = (0..freqs)
        .map(|k| std::f32::consts::PI * (1u64 << k) as f32)
        .collect();
    let s = Tensor::<3>::from_data(TensorData::new(scales, [1, freqs, 1]), &p.device());
    let arg = p.clone().unsqueeze_dim::<3>(1) * s; // [N, F, D]
    let sin = arg.clone().sin().reshape([n, freqs * d]);
    let cos = arg.cos().reshape([n, freqs * d]);
    Tensor::cat(vec![p, sin, cos], 1)
}

/// Encoded width of `d` coordinates with `freqs` frequencies.
pub fn encoded_dims(d: usize, freqs: usize) -> usize {
    d * (1 + 2 * freqs)
}

/// The conditional radiance field (generator network).
#[derive(Module, Debug)]
pub struct RadianceField {
    /// Shape encoder h: hidden layers on (γ(x), z_sh).
    shape: Vec<Linear>,
    /// Density head d: (h, γ(ξ), z_a) → hidden/2 → 1.
    head: Linear,
    out: Linear,
    freq_x: usize,
    freq_pose: usize,
}

impl RadianceField {
    /// A freshly initialised field for `config` on `device` (seed the device first).
    pub fn new(config: &ModelConfig, device: &Device) -> Self {
        let w = config.hidden;
        let mut shape = Vec::with_capacity(config.depth);
        let mut inp = encoded_dims(3, config.freq_x) + config.z_shape;
        for _ in 0..config.depth {
            shape.push(LinearConfig::new(inp, w).init(device));
            inp = w;
        }
        let head_in = w + encoded_dims(3, config.freq_pose) + config.z_app;
        let half = (w / 2).max(1);
        Self {
            shape,
            head: LinearConfig::new(head_in, half).init(device),
            out: LinearConfig::new(half, 1).init(device),
            freq_x: config.freq_x,
            freq_pose: config.freq_pose,
        }
    }

    /// Density δ ≥ 0 (softplus) at `points` `[B, N, 3]` (grid coordinates normalised to
    /// [−1, 1]) for poses `pose` `[B, 3]` (unit isocentre-to-source vectors) and codes
    /// `z_sh` `[B, M_sh]`, `z_a` `[B, M_a]`. Returns `[B, N]`.
    pub fn density(
        &self,
        points: Tensor<3>,
        pose: Tensor<2>,
        z_sh: Tensor<2>,
        z_a: Tensor<2>,
    ) -> Tensor<2> {
        let [b, n, _] = points.dims();
        let x = encode(points.reshape([b * n, 3]), self.freq_x);
        let expand = |z: Tensor<2>| {
            let m = z.dims()[1];
            z.unsqueeze_dim::<3>(1)
                .expand([b, n, m])
                .reshape([b * n, m])
        };
        let mut h = Tensor::cat(vec![x, expand(z_sh)], 1);
        for layer in &self.shape {
            h = relu(layer.forward(h));
        }
        let xi = encode(pose, self.freq_pose);
        let h = Tensor::cat(vec![h, expand(xi), expand(z_a)], 1);
        let h = relu(self.head.forward(h));
        softplus(self.out.forward(h), 1.0).reshape([b, n])
    }
}

/// Shape and appearance codes of a batch, as parameters so inference can tune them.
#[derive(Module, Debug)]
pub struct Codes {
    /// z_sh, `[B, M_sh]`.
    pub shape: Param<Tensor<2>>,
    /// z_a, `[B, M_a]`.
    pub app: Param<Tensor<2>>,
}

impl Codes {
    /// Codes from values (row-major `[batch, size]`).
    pub fn new(shape: Vec<f32>, app: Vec<f32>, batch: usize, device: &Device) -> Self {
        let ms = shape.len() / batch.max(1);
        let ma = app.len() / batch.max(1);
        Self {
            shape: Param::from_tensor(Tensor::from_data(
                TensorData::new(shape, [batch, ms]),
                device,
            )),
            app: Param::from_tensor(Tensor::from_data(TensorData::new(app, [batch, ma]), device)),
        }
    }
}

/// The generator and the codes it is tuned with at inference.
#[derive(Module, Debug)]
pub struct Tuned {
    /// The radiance field.
    pub field: RadianceField,
    /// The codes.
    pub codes: Codes,
}
