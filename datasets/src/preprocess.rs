//! CT preprocessing for learning pipelines, after the TomoGRAF paper: "black-border
//! cropped … CT volumes interpolated to 128×128×128 … normalized to [0, 1]".
//!
//! A typical chain:
//!
//! ```no_run
//! # use tomograf_datasets::preprocess::{crop_black_border, pad_to_cube, resample, HuWindow};
//! # fn run(ct: &tomograf_sim::Volume) -> tomograf_datasets::Result<tomograf_sim::Volume> {
//! let body = crop_black_border(ct, -900.0)?; // drop the scanner's padding and air border
//! let cube = pad_to_cube(&body, -1024.0)?; // isotropic box, body centred
//! let small = resample(&cube, [128, 128, 128])?; // anti-aliased, mean-preserving
//! HuWindow::CHEST.normalize(&small) // [−1024, 2048] HU → [0, 1]
//! # }
//! ```
//!
//! Every function keeps the volume in the world: positions are LPS millimetres
//! ([`tomograf_sim::volume`] describes the frame), and a voxel that survives an operation
//! stays at the same world position. [`resample`] covers exactly the same physical box as
//! its input.

use crate::error::{DatasetError, Result};
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::Volume;
use tomograf_sim::volume::checked_voxel_count;

/// Wraps a volume-construction failure with the name of the operation that produced it.
fn build(
    op: &str,
    dims: [usize; 3],
    spacing: DVec3,
    origin: DVec3,
    like: &Volume,
    data: Vec<f32>,
) -> Result<Volume> {
    Volume::new(dims, spacing, origin, like.direction(), data)
        .map_err(|e| DatasetError::Invalid(format!("{op}: the result is not a valid volume: {e}")))
}

fn fmt_dims(d: [usize; 3]) -> String {
    format!("{}×{}×{}", d[0], d[1], d[2])
}

fn as_dvec(d: [usize; 3]) -> DVec3 {
    DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64)
}

// ---------------------------------------------------------------------------------------
// Cropping
// ---------------------------------------------------------------------------------------

/// Crops to the smallest box of voxels whose value exceeds `threshold` (HU), e.g. −900 to
/// drop the scanner's padding (−1024, −2000, −3024…) and the air around the patient
/// (the "black border").
///
/// Geometry is kept: spacing and direction are unchanged and the cropped volume's voxel
/// `(0, 0, 0)` is at the same world position as the voxel it was copied from, so every
/// kept voxel stays where it was.
///
/// Errors if `threshold` is not finite or if no voxel exceeds it.
pub fn crop_black_border(volume: &Volume, threshold: f32) -> Result<Volume> {
    if !threshold.is_finite() {
        return Err(DatasetError::Invalid(format!(
            "crop_black_border: threshold {threshold} HU is not finite"
        )));
    }
    let [nx, ny, _] = volume.dims();
    // Per k-plane bounding box, then a min/max reduction: the result does not depend on
    // how rayon splits the work.
    let found = volume
        .data()
        .par_chunks(nx * ny)
        .enumerate()
        .filter_map(|(k, plane)| {
            let mut b: Option<([usize; 3], [usize; 3])> = None;
            for (j, row) in plane.chunks(nx).enumerate() {
                let Some(first) = row.iter().position(|&v| v > threshold) else {
                    continue;
                };
                let last = row.iter().rposition(|&v| v > threshold).unwrap_or(first);
                let e = b.get_or_insert(([first, j, k], [last, j, k]));
                e.0[0] = e.0[0].min(first);
                e.1[0] = e.1[0].max(last);
                e.1[1] = j;
            }
            b
        })
        .reduce_with(|a, b| {
            (
                std::array::from_fn(|d| a.0[d].min(b.0[d])),
                std::array::from_fn(|d| a.1[d].max(b.1[d])),
            )
        });
    let Some((lo, hi)) = found else {
        let (min, max) = volume.min_max();
        return Err(DatasetError::Invalid(format!(
            "crop_black_border: no voxel of the {} volume exceeds the threshold {threshold} HU \
             (values range from {min} to {max}); the volume holds only border/padding",
            fmt_dims(volume.dims())
        )));
    };
    let dims: [usize; 3] = std::array::from_fn(|d| hi[d] - lo[d] + 1);
    if dims == volume.dims() {
        return Ok(volume.clone());
    }
    let mut data = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    let src = volume.data();
    for k in lo[2]..=hi[2] {
        for j in lo[1]..=hi[1] {
            let start = lo[0] + nx * (j + ny * k);
            data.extend_from_slice(&src[start..start + dims[0]]);
        }
    }
    let origin = volume.index_to_world(as_dvec(lo));
    build(
        "crop_black_border",
        dims,
        volume.spacing(),
        origin,
        volume,
        data,
    )
}

// ---------------------------------------------------------------------------------------
// Padding
// ---------------------------------------------------------------------------------------

/// Pads with `fill` (HU) to a cube whose side is the largest physical extent
/// `L = max(nₐ·sₐ)`, centred on the original box, so that the caller can then [`resample`]
/// to n³ and get isotropic voxels. Spacing and direction are unchanged and every original
/// voxel keeps its value and its world position.
///
/// Because the original voxels stay on the grid, an axis can only grow by whole voxels:
/// it gets the smallest count whose extent reaches `L`, so when `L` is not a whole number
/// of that axis's voxels the box overshoots `L` by less than one voxel (with isotropic
/// spacing it is an exact cube, nᵐᵃˣ voxels on every axis). The padding is split evenly,
/// the extra voxel of an odd split going to the high-index side, so the original box is
/// centred to within half a voxel.
///
/// Errors if `fill` is not finite or the cube would exceed
/// [`tomograf_sim::volume::MAX_VOXELS`].
pub fn pad_to_cube(volume: &Volume, fill: f32) -> Result<Volume> {
    if !fill.is_finite() {
        return Err(DatasetError::Invalid(format!(
            "pad_to_cube: fill value {fill} HU is not finite"
        )));
    }
    let n = volume.dims();
    let s = volume.spacing().to_array();
    let extent: [f64; 3] = std::array::from_fn(|d| n[d] as f64 * s[d]);
    let side = extent.iter().copied().fold(0.0, f64::max);
    let dims: [usize; 3] = std::array::from_fn(|d| {
        // Relative tolerance so that an axis whose extent equals the side up to rounding
        // does not gain a spurious voxel.
        let want = (side / s[d] * (1.0 - 1e-9)).ceil() as usize;
        want.max(n[d])
    });
    checked_voxel_count(dims).map_err(|e| {
        DatasetError::Invalid(format!(
            "pad_to_cube: cannot pad the {} volume to {}: {e}",
            fmt_dims(n),
            fmt_dims(dims)
        ))
    })?;
    if dims == n {
        return Ok(volume.clone());
    }
    let before: [usize; 3] = std::array::from_fn(|d| (dims[d] - n[d]) / 2);
    // Zeroed allocation (lazily mapped pages), then filled plane by plane in parallel.
    let mut data = vec![0.0f32; dims[0] * dims[1] * dims[2]];
    let src = volume.data();
    data.par_chunks_mut(dims[0] * dims[1])
        .enumerate()
        .for_each(|(k, plane)| {
            plane.fill(fill);
            let Some(ks) = k.checked_sub(before[2]).filter(|&ks| ks < n[2]) else {
                return;
            };
            for js in 0..n[1] {
                let j = js + before[1];
                let dst = before[0] + dims[0] * j;
                let from = n[0] * (js + n[1] * ks);
                plane[dst..dst + n[0]].copy_from_slice(&src[from..from + n[0]]);
            }
        });
    let origin = volume.index_to_world(-as_dvec(before));
    build("pad_to_cube", dims, volume.spacing(), origin, volume, data)
}

// ---------------------------------------------------------------------------------------
// Resampling
// ---------------------------------------------------------------------------------------

/// The input voxels (index, weight) that make one output voxel along one axis. Weights
/// sum to 1.
type Taps = Vec<(usize, f64)>;

/// Filter taps for resampling one axis from `n` to `m` voxels over the same extent.
///
/// In grid coordinates of the input (voxel `q` is `[q, q+1)`, the axis is `[0, n]`),
/// output voxel `p` is `[p·n/m, (p+1)·n/m)`.
fn axis_taps(n: usize, m: usize) -> Vec<Taps> {
    if m == n {
        return (0..n).map(|p| vec![(p, 1.0)]).collect();
    }
    let (nf, mf) = (n as f64, m as f64);
    if m < n {
        // Box filter: the length-weighted average of the input voxels the output voxel
        // overlaps (the integral of the piecewise-constant input over the output voxel,
        // divided by its length). Products p·n are integers, exact in f64.
        (0..m)
            .map(|p| {
                let lo = (p * n) as f64 / mf;
                let hi = ((p + 1) * n) as f64 / mf;
                let first = (lo.floor() as usize).min(n - 1);
                let last = ((hi.ceil() as usize).max(first + 1) - 1).min(n - 1);
                let mut taps: Taps = (first..=last)
                    .map(|q| {
                        let w = hi.min((q + 1) as f64) - lo.max(q as f64);
                        (q, w)
                    })
                    .filter(|&(_, w)| w > 0.0)
                    .collect();
                let total: f64 = taps.iter().map(|&(_, w)| w).sum();
                for t in &mut taps {
                    t.1 /= total;
                }
                taps
            })
            .collect()
    } else {
        // Linear interpolation between input voxel centres, clamped at the edges.
        (0..m)
            .map(|p| {
                if n == 1 {
                    return vec![(0, 1.0)];
                }
                // Output centre in input index coordinates (centres at integers).
                let x = ((2 * p + 1) * n) as f64 / (2.0 * mf) - 0.5;
                let x = x.clamp(0.0, nf - 1.0);
                let q0 = (x.floor() as usize).min(n - 2);
                let t = x - q0 as f64;
                if t == 0.0 {
                    vec![(q0, 1.0)]
                } else if t == 1.0 {
                    vec![(q0 + 1, 1.0)]
                } else {
                    vec![(q0, 1.0 - t), (q0 + 1, t)]
                }
            })
            .collect()
    }
}

/// Applies `taps` along `axis` of a `dims` volume stored `i` fastest. Every output value
/// is computed by one fixed sequence of f64 operations, so the result does not depend on
/// the number of threads.
fn apply_axis(src: &[f32], dims: [usize; 3], axis: usize, taps: &[Taps]) -> Vec<f32> {
    let n = dims[axis];
    let m = taps.len();
    let inner: usize = dims[..axis].iter().product();
    let outer: usize = dims[axis + 1..].iter().product();
    let mut out = vec![0.0f32; outer * m * inner];
    // Chunks of `inner` contiguous outputs (one output index p along the axis); group
    // small ones so that each rayon task has a useful amount of work.
    let min_len = (8192 / inner).max(1);
    out.par_chunks_mut(inner)
        .enumerate()
        .with_min_len(min_len)
        .for_each(|(c, chunk)| {
            let (o, p) = (c / m, c % m);
            let base = o * n * inner;
            let t = &taps[p];
            for (e, dst) in chunk.iter_mut().enumerate() {
                let mut acc = 0.0f64;
                for &(q, w) in t {
                    acc += w * f64::from(src[base + q * inner + e]);
                }
                *dst = acc as f32;
            }
        });
    out
}

/// Resamples to `dims` voxels covering the **same physical box** as the input: outer
/// voxel faces to outer voxel faces, so along each axis the new spacing is
/// `n·spacing / dims`, the direction is unchanged and the origin (centre of voxel
/// `(0, 0, 0)`) moves so that the boxes coincide.
///
/// The filter is separable; along each axis:
/// * **shrinking** (`dims < n`): each output voxel is the length-weighted average of the
///   input voxels its extent overlaps — a box filter, which is anti-aliased (structure
///   finer than the output voxel averages out instead of aliasing) and preserves the mean
///   (Σ output·volume = Σ input·volume);
/// * **enlarging** (`dims > n`): linear interpolation between input voxel centres; output
///   centres beyond the outermost input centres take the edge value (clamped);
/// * equal: the values are copied.
///
/// Axes are processed from the strongest reduction to the strongest enlargement (ties by
/// axis index), which keeps the intermediate volumes no larger than the input or the
/// output. Sums are accumulated in f64. The work is spread over rayon's current pool;
/// every value is computed the same way whatever the number of threads, so the bytes of
/// the result do not depend on it.
///
/// Errors if a target dimension is zero or the output would exceed
/// [`tomograf_sim::volume::MAX_VOXELS`].
pub fn resample(volume: &Volume, dims: [usize; 3]) -> Result<Volume> {
    let n = volume.dims();
    checked_voxel_count(dims).map_err(|e| {
        DatasetError::Invalid(format!(
            "resample: cannot resample the {} volume to {}: {e}",
            fmt_dims(n),
            fmt_dims(dims)
        ))
    })?;
    let spacing = volume.spacing() * as_dvec(n) / as_dvec(dims);
    // Output voxel 0 spans input grid [0, n/m): its centre is at input index n/(2m) − 0.5.
    let origin = volume.index_to_world(as_dvec(n) / (2.0 * as_dvec(dims)) - 0.5);
    if dims == n {
        return build(
            "resample",
            dims,
            volume.spacing(),
            volume.origin(),
            volume,
            volume.data().to_vec(),
        );
    }
    let mut order = [0usize, 1, 2];
    // Compare m_a/n_a as m_a·n_b vs m_b·n_a (exact in u128).
    order.sort_by(|&a, &b| {
        let ra = dims[a] as u128 * n[b] as u128;
        let rb = dims[b] as u128 * n[a] as u128;
        ra.cmp(&rb).then(a.cmp(&b))
    });
    let mut cur_dims = n;
    let mut cur: Option<Vec<f32>> = None;
    for axis in order {
        if dims[axis] == n[axis] {
            continue;
        }
        let taps = axis_taps(n[axis], dims[axis]);
        let src = cur.as_deref().unwrap_or(volume.data());
        let next = apply_axis(src, cur_dims, axis, &taps);
        cur_dims[axis] = dims[axis];
        cur = Some(next);
    }
    let data = cur.unwrap_or_else(|| volume.data().to_vec());
    build("resample", dims, spacing, origin, volume, data)
}

// ---------------------------------------------------------------------------------------
// Intensity window
// ---------------------------------------------------------------------------------------

/// A Hounsfield window `[lo, hi]` mapped linearly to `[0, 1]`; values outside clamp.
///
/// Deserialisation checks the window like [`HuWindow::new`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawHuWindow")]
pub struct HuWindow {
    /// HU value mapped to 0.
    pub lo: f32,
    /// HU value mapped to 1.
    pub hi: f32,
}

#[derive(Deserialize)]
struct RawHuWindow {
    lo: f32,
    hi: f32,
}

impl TryFrom<RawHuWindow> for HuWindow {
    type Error = DatasetError;
    fn try_from(r: RawHuWindow) -> Result<Self> {
        HuWindow::new(r.lo, r.hi)
    }
}

impl HuWindow {
    /// The default for chest CT data sets: **[−1024, 2048] HU**.
    ///
    /// * −1024 is the lowest value CT scanners store (12-bit data with rescale intercept
    ///   −1024): air (≈ −1000) and padding map to 0, so the cropped-away "black border"
    ///   and the air around the patient are exactly black, and lung parenchyma
    ///   (≈ −900…−500) stays resolved near the bottom of the range instead of being
    ///   clipped as a soft-tissue window would do.
    /// * 2048 keeps the whole bone range — cancellous bone (≈ +300), cortical bone of the
    ///   ribs, spine and sternum (up to ≈ +2000) — unclipped, so the attenuation of dense
    ///   bone, which dominates the X-ray projections, survives normalisation; only metal
    ///   and contrast saturate.
    /// * The width, 3072 HU, is 3/4 of the 12-bit range: 1 HU ≈ 3.3·10⁻⁴ of the unit range,
    ///   far above f32 resolution.
    pub const CHEST: HuWindow = HuWindow {
        lo: -1024.0,
        hi: 2048.0,
    };

    /// A window; errors unless `lo` and `hi` are finite and `lo < hi`.
    pub fn new(lo: f32, hi: f32) -> Result<Self> {
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(DatasetError::Invalid(format!(
                "HU window [{lo}, {hi}]: bounds must be finite"
            )));
        }
        if lo >= hi {
            return Err(DatasetError::Invalid(format!(
                "HU window [{lo}, {hi}]: the lower bound must be below the upper bound"
            )));
        }
        Ok(Self { lo, hi })
    }

    fn check(&self) -> Result<(f64, f64)> {
        Self::new(self.lo, self.hi)?;
        Ok((f64::from(self.lo), f64::from(self.hi) - f64::from(self.lo)))
    }

    /// Maps HU to `[0, 1]`: `(v − lo)/(hi − lo)` clamped to `[0, 1]` (computed in f64).
    /// Geometry is unchanged. Errors if the window is invalid (fields set by hand).
    pub fn normalize(&self, volume: &Volume) -> Result<Volume> {
        let (lo, width) = self.check()?;
        volume
            .map(|v| ((f64::from(v) - lo) / width).clamp(0.0, 1.0) as f32)
            .map_err(|e| DatasetError::Invalid(format!("HU window normalize: {e}")))
    }

    /// The inverse of [`HuWindow::normalize`] on `[0, 1]`: `lo + v·(hi − lo)` (not
    /// clamped; computed in f64). Clamped values come back as the window bounds.
    pub fn denormalize(&self, volume: &Volume) -> Result<Volume> {
        let (lo, width) = self.check()?;
        volume
            .map(|v| (lo + f64::from(v) * width) as f32)
            .map_err(|e| DatasetError::Invalid(format!("HU window denormalize: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sums(taps: &[Taps]) -> Vec<f64> {
        taps.iter()
            .map(|t| t.iter().map(|&(_, w)| w).sum())
            .collect()
    }

    #[test]
    fn box_taps_cover_each_input_voxel_once() {
        for (n, m) in [(37, 16), (40, 10), (5, 3), (7, 1), (512, 128)] {
            let taps = axis_taps(n, m);
            assert_eq!(taps.len(), m);
            for s in sums(&taps) {
                assert!((s - 1.0).abs() < 1e-12);
            }
            // Σ_p w_pq · (n/m) = 1 for every input voxel q: each is counted exactly once.
            let mut cover = vec![0.0f64; n];
            for t in &taps {
                for &(q, w) in t {
                    cover[q] += w * n as f64 / m as f64;
                }
            }
            for (q, c) in cover.iter().enumerate() {
                assert!((c - 1.0).abs() < 1e-12, "{n}→{m}: voxel {q} covered {c}");
            }
        }
    }

    #[test]
    fn linear_taps_interpolate_centres_and_clamp() {
        let taps = axis_taps(2, 4);
        // Output centres at input indices −0.25, 0.25, 0.75, 1.25.
        assert_eq!(taps[0], vec![(0, 1.0)]);
        assert_eq!(taps[1], vec![(0, 0.75), (1, 0.25)]);
        assert_eq!(taps[2], vec![(0, 0.25), (1, 0.75)]);
        assert_eq!(taps[3], vec![(1, 1.0)]);
        assert_eq!(axis_taps(1, 3), vec![vec![(0, 1.0)]; 3]);
        assert_eq!(axis_taps(3, 3)[1], vec![(1, 1.0)]);
    }

    #[test]
    fn axis_order_shrinks_first() {
        // Shrinking x and enlarging z must not go through a large intermediate: the
        // result equals the per-axis composition in any order (up to rounding).
        let v = Volume::new(
            [8, 3, 2],
            DVec3::ONE,
            DVec3::ZERO,
            glam::DMat3::IDENTITY,
            (0..48).map(|i| i as f32).collect(),
        )
        .unwrap();
        let r = resample(&v, [2, 3, 5]).unwrap();
        assert_eq!(r.dims(), [2, 3, 5]);
        // x shrink 8→2 averages 4 voxels: row j=0, k=0 gives mean(0..4) = 1.5.
        assert!((r.get(0, 0, 0) - 1.5).abs() < 1e-6);
    }
}
