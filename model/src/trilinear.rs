//! Trilinear sampling of a volume held as a tensor, built from `gather` (burn has no
//! `grid_sample_3d`); differentiable with respect to the voxel values.
//!
//! The field is sim's (`tomograf_sim::trace::trilinear`): values at voxel centres
//! (grid coordinates `i + 0.5`), trilinear between centres, clamped in the outer half voxel,
//! zero outside the grid box `[0, n]³`.

use burn::tensor::{Device, Int, Tensor, TensorData};

/// A volume's values as a flat tensor, `i` fastest.
#[derive(Debug, Clone)]
pub struct VolumeTensor {
    /// `nx·ny·nz` values.
    pub values: Tensor<1>,
    /// Voxels along (i, j, k).
    pub dims: [usize; 3],
}

impl VolumeTensor {
    /// A tensor of `data` (`i` fastest) on `device`.
    pub fn new(data: Vec<f32>, dims: [usize; 3], device: &Device) -> Self {
        let n = data.len();
        Self {
            values: Tensor::from_data(TensorData::new(data, [n]), device),
            dims,
        }
    }

    /// The field at grid points `g` (grid coordinates), shape `[g.len()]`.
    pub fn sample(&self, g: &[[f64; 3]]) -> Tensor<1> {
        let (idx, w) = corner_weights(self.dims, g);
        let device = self.values.device();
        let p = g.len();
        let idx = Tensor::<1, Int>::from_data(TensorData::new(idx, [8 * p]), &device);
        let w = Tensor::<2>::from_data(TensorData::new(w, [p, 8]), &device);
        let v = self.values.clone().gather(0, idx).reshape([p, 8]);
        (v * w).sum_dim(1).reshape([p])
    }
}

/// The 8 corner indices (`i + nx·j + nx·ny·k`) and weights of each point; weights are 0
/// outside the grid box.
pub fn corner_weights(dims: [usize; 3], g: &[[f64; 3]]) -> (Vec<i64>, Vec<f32>) {
    let mut idx = Vec::with_capacity(8 * g.len());
    let mut wts = Vec::with_capacity(8 * g.len());
    let (nx, nxy) = (dims[0], dims[0] * dims[1]);
    for p in g {
        let inside = (0..3).all(|a| p[a] >= 0.0 && p[a] <= dims[a] as f64);
        let mut base = [0usize; 3];
        let mut next = [0usize; 3];
        let mut frac = [0.0f64; 3];
        for a in 0..3 {
            let last = (dims[a] - 1) as f64;
            let q = (p[a] - 0.5).clamp(0.0, last);
            let i0 = (q.floor() as usize).min(dims[a].saturating_sub(2));
            base[a] = i0;
            next[a] = (i0 + 1).min(dims[a] - 1);
            frac[a] = q - i0 as f64;
        }
        for corner in 0..8 {
            let pick = |a: usize| (corner >> a) & 1 == 1;
            let mut w = 1.0;
            let mut id = 0;
            for (a, stride) in [1, nx, nxy].into_iter().enumerate() {
                let (i, f) = if pick(a) {
                    (next[a], frac[a])
                } else {
                    (base[a], 1.0 - frac[a])
                };
                w *= f;
                id += i * stride;
            }
            idx.push(id as i64);
            wts.push(if inside { w as f32 } else { 0.0 });
        }
    }
    (idx, wts)
}
