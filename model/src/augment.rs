//! DAG augmentations (Tran et al. 2021; Methods 1.2.3): k = 0 identity, 1 horizontal flip,
//! 2 vertical flip, 3 transpose (a 90° rotation composed with a flip). Volumes
//! `[B, 1, Q, M, M]` are transformed in the patch plane (the last two axes), the same way
//! as their patches, so V' and P' stay consistent.

use burn::tensor::Tensor;

/// Transformation `k` of patches `[B, C, M, M]`.
pub fn patch(x: Tensor<4>, k: usize) -> Tensor<4> {
    match k {
        0 => x,
        1 => x.flip([3]),
        2 => x.flip([2]),
        _ => x.swap_dims(2, 3),
    }
}

/// Transformation `k` of sub-volumes `[B, C, Q, M, M]`.
pub fn volume(x: Tensor<5>, k: usize) -> Tensor<5> {
    match k {
        0 => x,
        1 => x.flip([4]),
        2 => x.flip([3]),
        _ => x.swap_dims(3, 4),
    }
}
