//! Positional encoding γ and the conditional radiance field
//! g = d(h(γ(x), z_sh), [γ(ξ),] z_a) (Methods 1.2.1, eqs. 1–6).
//!
//! By default the field is a **residual on a prior**: δ(x) = m(x) + g(…), where m is the mean
//! training volume sampled with sim's trilinear field (given with the points, see
//! [`crate::prior`]) and g's last layer starts at zero, so an untrained field renders the mean
//! volume exactly; density does not depend on the view. The paper's form — δ = softplus(g),
//! with γ(ξ) in the head — is selected by `mean_anchor = false`, `view_dependent = true`.

use crate::config::ModelConfig;
use burn::module::{Module, Param};
use burn::nn::{Initializer, Linear, LinearConfig};
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

pub use crate::config::encoded_dims;

/// The conditional radiance field (generator network).
#[derive(Module, Debug)]
pub struct RadianceField {
    /// Shape encoder h: hidden layers on (γ(x), z_sh).
    shape: Vec<Linear>,
    /// Density head d: (h, [γ(ξ),] z_a) → hidden/2 → 1.
    head: Linear,
    out: Linear,
    freq_x: usize,
    freq_pose: usize,
    view_dependent: bool,
    mean_anchor: bool,
}

impl RadianceField {
    /// A freshly initialised field for `config` on `device` (seed the device first). With
    /// `mean_anchor` the last layer starts at zero (weights and bias).
    pub fn new(config: &ModelConfig, device: &Device) -> Self {
        let w = config.hidden;
        let mut shape = Vec::with_capacity(config.depth);
        let mut inp = encoded_dims(3, config.freq_x) + config.z_shape;
        for _ in 0..config.depth {
            shape.push(LinearConfig::new(inp, w).init(device));
            inp = w;
        }
        let pose_dims = if config.view_dependent {
            encoded_dims(3, config.freq_pose)
        } else {
            0
        };
        let head_in = w + pose_dims + config.z_app;
        let half = (w / 2).max(1);
        let out = LinearConfig::new(half, 1);
        let out = if config.mean_anchor {
            out.with_initializer(Initializer::Zeros)
        } else {
            out
        };
        Self {
            shape,
            head: LinearConfig::new(head_in, half).init(device),
            out: out.init(device),
            freq_x: config.freq_x,
            freq_pose: config.freq_pose,
            view_dependent: config.view_dependent,
            mean_anchor: config.mean_anchor,
        }
    }

    /// Whether density is the prior plus a residual (else softplus, the paper's form).
    pub fn mean_anchor(&self) -> bool {
        self.mean_anchor
    }

    /// Normalised density at `points` `[B, N, 3]` (grid coordinates normalised to [−1, 1])
    /// for poses `pose` `[B, 3]` (unit isocentre-to-source vectors; used only by a
    /// view-dependent field) and codes `z_sh` `[B, M_sh]`, `z_a` `[B, M_a]`. `prior` `[B, N]`
    /// holds the mean training volume at the points; with the mean anchor δ = prior + g,
    /// otherwise δ = softplus(g) ≥ 0 and `prior` is ignored. Returns `[B, N]`.
    pub fn density(
        &self,
        points: Tensor<3>,
        prior: Tensor<2>,
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
        let h = if self.view_dependent {
            let xi = encode(pose, self.freq_pose);
            Tensor::cat(vec![h, expand(xi), expand(z_a)], 1)
        } else {
            Tensor::cat(vec![h, expand(z_a)], 1)
        };
        let g = self.out.forward(relu(self.head.forward(h))).reshape([b, n]);
        if self.mean_anchor {
            prior + g
        } else {
            softplus(g, 1.0)
        }
    }
}

/// Shape and appearance codes, as parameters so training (one row per item) and inference
/// (one row) can tune them.
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

impl Codes {
    /// Rows `rows` of the table: `(z_sh, z_a)`, `[rows.len(), M]` each; gradients flow back
    /// to the selected rows.
    pub fn rows(&self, rows: &[usize]) -> (Tensor<2>, Tensor<2>) {
        let device = self.shape.val().device();
        let idx: Vec<i64> = rows.iter().map(|&r| r as i64).collect();
        let idx =
            Tensor::<1, burn::tensor::Int>::from_data(TensorData::new(idx, [rows.len()]), &device);
        (
            self.shape.val().select(0, idx.clone()),
            self.app.val().select(0, idx),
        )
    }

    /// The table's values, row-major: `(z_sh, z_a, rows)`.
    pub fn values(&self) -> (Vec<f32>, Vec<f32>, usize) {
        let read = |t: Tensor<2>| t.into_data().try_to_vec::<f32>().expect("f32 codes");
        let rows = self.shape.val().dims()[0];
        (read(self.shape.val()), read(self.app.val()), rows)
    }
}

/// The generator and the codes it is tuned with at inference. The codes are whitened:
/// z = μ + σ ⊙ u with μ, σ the training codes' per-dimension mean and spread
/// ([`crate::prior::CodeStats`]), so u ~ N(0, I) under the prior and u = 0 is the mean code.
#[derive(Module, Debug)]
pub struct Tuned {
    /// The radiance field.
    pub field: RadianceField,
    /// The whitened codes u (one row).
    pub codes: Codes,
}
