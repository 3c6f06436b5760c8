//! The patient's body alone: a mask that leaves out the couch, the scanner's padding
//! outside its reconstruction circle (−2048, −3024 HU…), blankets, cables and stray voxels
//! in the air, so that a real CT is cropped to the body the way a phantom is.
//!
//! [`body_mask`], on a volume in HU in the patient frame ([`crate::frame`]; the axial
//! planes are the `k`-planes):
//! 1. voxels above `threshold_hu` (default −500 HU: every tissue but lung and air; the
//!    padding values are far below it);
//! 2. an in-plane opening of radius `opening_mm` (a square of ⌈r/spacing⌉ voxels per side
//!    on each in-plane axis) to cut thin bridges — a cable, a sheet, a couch pad touching
//!    the back at a point;
//! 3. the largest 6-connected component of what is left — the body — and any other
//!    component of at least [`LIMB_FRACTION`] of its size that is not flat (an arm held
//!    apart from the chest; a couch top, tens of centimetres wide and a few thick, is flat:
//!    [`FLAT_RATIO`]);
//! 4. grown back by the same square and intersected with step 1, so the body's own
//!    outline is kept to the voxel;
//! 5. holes filled in every axial plane (lungs, airways, bowel gas: any region of
//!    the plane that the plane's border cannot reach through non-body voxels).
//!
//! [`isolate_body`] sets every voxel outside the mask to air (−1000 HU). Every step is a
//! fixed sequence of operations: the mask does not depend on the number of threads.

use crate::error::{DatasetError, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::Volume;

/// Value given to everything outside the body, HU (the phantoms' air).
pub const AIR_HU: f32 = -1000.0;

/// How the body is told from everything else.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BodySettings {
    /// Tissue threshold, HU.
    pub threshold_hu: f32,
    /// Radius of the in-plane opening, mm (0: none).
    pub opening_mm: f64,
}

impl Default for BodySettings {
    fn default() -> Self {
        Self {
            threshold_hu: -500.0,
            opening_mm: 3.0,
        }
    }
}

/// The fraction of the body's voxels in each of [`TISSUE_CLASSES`]: a coarse HU
/// histogram that says whether a CT looks like the population a model learned from.
pub type TissueFractions = [f64; 4];

/// Names and HU ranges of the classes of [`TissueFractions`]: lung and air below −400 HU,
/// fat −400…−50, soft tissue and blood −50…200, bone above 200.
pub const TISSUE_CLASSES: [(&str, f32, f32); 4] = [
    ("lung/air", f32::NEG_INFINITY, -400.0),
    ("fat", -400.0, -50.0),
    ("soft tissue", -50.0, 200.0),
    ("bone", 200.0, f32::INFINITY),
];

/// What a body mask found.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// One flag per voxel, in the volume's order.
    pub mask: Vec<bool>,
    /// Voxels in the mask.
    pub voxels: usize,
}

impl Body {
    /// The fraction of the grid inside the body.
    pub fn fraction(&self) -> f64 {
        self.voxels as f64 / self.mask.len().max(1) as f64
    }

    /// The fraction of the body's voxels of `hu` in each tissue class ([`TISSUE_CLASSES`]).
    pub fn tissue_fractions(&self, hu: &Volume) -> TissueFractions {
        let mut counts = [0usize; 4];
        for (&m, &v) in self.mask.iter().zip(hu.data()) {
            if m {
                let c = TISSUE_CLASSES
                    .iter()
                    .position(|&(_, lo, hi)| v >= lo && v < hi)
                    .unwrap_or(3);
                counts[c] += 1;
            }
        }
        counts.map(|c| c as f64 / self.voxels.max(1) as f64)
    }
}

/// The body mask of a volume in HU (module docs). Errors if the settings are not finite
/// or no voxel is above the threshold.
pub fn body_mask(volume: &Volume, settings: &BodySettings) -> Result<Body> {
    if !(settings.threshold_hu.is_finite()
        && settings.opening_mm.is_finite()
        && settings.opening_mm >= 0.0)
    {
        return Err(DatasetError::Invalid(format!(
            "body mask: threshold {} HU and opening {} mm must be finite (the opening ≥ 0)",
            settings.threshold_hu, settings.opening_mm
        )));
    }
    let dims = volume.dims();
    let tissue: Vec<bool> = volume
        .data()
        .par_iter()
        .map(|&v| v > settings.threshold_hu)
        .collect();
    let radius = [0, 1].map(|a| (settings.opening_mm / volume.spacing()[a]).ceil() as usize);
    let opened = erode(&tissue, dims, radius);
    let in_plane = [volume.spacing().x, volume.spacing().y];
    let Some(core) = body_components(&opened, dims, in_plane)
        .or_else(|| body_components(&tissue, dims, in_plane))
    else {
        let (min, max) = volume.min_max();
        return Err(DatasetError::Invalid(format!(
            "body mask: no voxel is above {} HU (values from {min} to {max}): there is no body \
             in this volume",
            settings.threshold_hu
        )));
    };
    let mut mask = dilate(&core, dims, radius);
    mask.par_iter_mut()
        .zip(tissue.par_iter())
        .for_each(|(m, &t)| *m &= t);
    fill_planes(&mut mask, dims);
    let voxels = mask.par_iter().filter(|&&m| m).count();
    Ok(Body { mask, voxels })
}

/// The volume with every voxel outside `body` set to [`AIR_HU`], in place (the volume is
/// consumed, not copied).
pub fn isolate_body(volume: Volume, body: &Body) -> Result<Volume> {
    let (dims, spacing, origin, direction) = (
        volume.dims(),
        volume.spacing(),
        volume.origin(),
        volume.direction(),
    );
    let mut data = volume.into_data();
    data.par_iter_mut()
        .zip(body.mask.par_iter())
        .for_each(|(v, &m)| {
            if !m {
                *v = AIR_HU;
            }
        });
    Volume::new(dims, spacing, origin, direction, data)
        .map_err(|e| DatasetError::Invalid(format!("isolate body: {e}")))
}

/// A min (`keep_all = true`) or max filter over a window of `2r + 1` along in-plane axis
/// `axis` (0 = i, 1 = j) of each k-plane; outside the grid counts as unset.
fn filter_axis(src: &[bool], dims: [usize; 3], axis: usize, r: usize, keep_all: bool) -> Vec<bool> {
    if r == 0 {
        return src.to_vec();
    }
    let [nx, ny, _] = dims;
    let mut out = vec![false; src.len()];
    out.par_chunks_mut(nx * ny)
        .zip(src.par_chunks(nx * ny))
        .for_each(|(o, s)| {
            let (len, lines, stride, line_step) = if axis == 0 {
                (nx, ny, 1, nx)
            } else {
                (ny, nx, nx, 1)
            };
            for line in 0..lines {
                let base = line * line_step;
                // Prefix sums of set flags along the line: a window is all set or any set.
                let mut prefix = vec![0usize; len + 1];
                for p in 0..len {
                    prefix[p + 1] = prefix[p] + usize::from(s[base + p * stride]);
                }
                for p in 0..len {
                    let (lo, hi) = (p.saturating_sub(r), (p + r).min(len - 1));
                    let set = prefix[hi + 1] - prefix[lo];
                    o[base + p * stride] = if keep_all {
                        p >= r && p + r < len && set == 2 * r + 1
                    } else {
                        set > 0
                    };
                }
            }
        });
    out
}

fn erode(mask: &[bool], dims: [usize; 3], r: [usize; 2]) -> Vec<bool> {
    let a = filter_axis(mask, dims, 0, r[0], true);
    filter_axis(&a, dims, 1, r[1], true)
}

fn dilate(mask: &[bool], dims: [usize; 3], r: [usize; 2]) -> Vec<bool> {
    let a = filter_axis(mask, dims, 0, r[0], false);
    filter_axis(&a, dims, 1, r[1], false)
}

/// A 6-connected component's size and in-plane extent (voxels along i and j).
#[derive(Debug, Clone, Copy)]
struct Component {
    voxels: usize,
    lo: [usize; 2],
    hi: [usize; 2],
}

impl Component {
    /// Its extent along j (antero-posterior) over its extent along i (left–right), in mm.
    fn flatness(&self, spacing: [f64; 2]) -> f64 {
        let e = [0, 1].map(|a| (self.hi[a] - self.lo[a] + 1) as f64 * spacing[a]);
        e[1] / e[0]
    }
}

/// The body's components of `mask`: the largest 6-connected one, and every other one
/// holding at least [`LIMB_FRACTION`] of its voxels that is not flat ([`Component::flatness`]
/// at least [`FLAT_RATIO`]: an arm beside the chest is kept, a couch is not). `None` when
/// nothing is set.
fn body_components(mask: &[bool], dims: [usize; 3], spacing: [f64; 2]) -> Option<Vec<bool>> {
    let [nx, ny, nz] = dims;
    let mut label = vec![0u32; mask.len()];
    let mut found: Vec<Component> = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    for seed in 0..mask.len() {
        if !mask[seed] || label[seed] != 0 {
            continue;
        }
        found.push(Component {
            voxels: 0,
            lo: [usize::MAX; 2],
            hi: [0; 2],
        });
        let id = found.len() as u32;
        let c = found.last_mut().expect("just pushed");
        label[seed] = id;
        stack.push(seed);
        while let Some(v) = stack.pop() {
            let (i, j, k) = (v % nx, v / nx % ny, v / (nx * ny));
            c.voxels += 1;
            c.lo = [c.lo[0].min(i), c.lo[1].min(j)];
            c.hi = [c.hi[0].max(i), c.hi[1].max(j)];
            let mut visit = |u: usize| {
                if mask[u] && label[u] == 0 {
                    label[u] = id;
                    stack.push(u);
                }
            };
            if i > 0 {
                visit(v - 1);
            }
            if i + 1 < nx {
                visit(v + 1);
            }
            if j > 0 {
                visit(v - nx);
            }
            if j + 1 < ny {
                visit(v + nx);
            }
            if k > 0 {
                visit(v - nx * ny);
            }
            if k + 1 < nz {
                visit(v + nx * ny);
            }
        }
    }
    // The first largest, in voxel order, on a tie.
    let largest = found
        .iter()
        .enumerate()
        .fold(None, |best: Option<(usize, usize)>, (n, c)| match best {
            Some((_, size)) if size >= c.voxels => best,
            _ => Some((n, c.voxels)),
        })?;
    let keep: Vec<bool> = found
        .iter()
        .enumerate()
        .map(|(n, c)| {
            n == largest.0
                || (c.voxels as f64 >= LIMB_FRACTION * largest.1 as f64
                    && c.flatness(spacing) >= FLAT_RATIO)
        })
        .collect();
    Some(
        label
            .par_iter()
            .map(|&l| l > 0 && keep[l as usize - 1])
            .collect(),
    )
}

/// Least size of a component kept beside the largest, as a fraction of the largest's.
pub const LIMB_FRACTION: f64 = 0.02;
/// Least antero-posterior over left–right extent of a component kept beside the largest:
/// a couch top or pad (a few cm thick, tens of cm wide) is below it, an arm is near 1.
pub const FLAT_RATIO: f64 = 0.4;

/// Fills, in every k-plane, the unset regions that the plane's border cannot reach through
/// unset pixels (4-connected).
fn fill_planes(mask: &mut [bool], dims: [usize; 3]) {
    let [nx, ny, _] = dims;
    mask.par_chunks_mut(nx * ny).for_each(|plane| {
        let mut outside = vec![false; nx * ny];
        let mut stack: Vec<usize> = Vec::new();
        let push = |p: usize, outside: &mut Vec<bool>, stack: &mut Vec<usize>| {
            if !plane[p] && !outside[p] {
                outside[p] = true;
                stack.push(p);
            }
        };
        for i in 0..nx {
            push(i, &mut outside, &mut stack);
            push(i + nx * (ny - 1), &mut outside, &mut stack);
        }
        for j in 0..ny {
            push(nx * j, &mut outside, &mut stack);
            push(nx - 1 + nx * j, &mut outside, &mut stack);
        }
        while let Some(p) = stack.pop() {
            let (i, j) = (p % nx, p / nx);
            if i > 0 {
                push(p - 1, &mut outside, &mut stack);
            }
            if i + 1 < nx {
                push(p + 1, &mut outside, &mut stack);
            }
            if j > 0 {
                push(p - nx, &mut outside, &mut stack);
            }
            if j + 1 < ny {
                push(p + nx, &mut outside, &mut stack);
            }
        }
        for (m, o) in plane.iter_mut().zip(outside) {
            *m = !o;
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erosion_and_dilation_are_windows() {
        let dims = [7, 1, 1];
        let m = [false, true, true, true, true, false, true];
        assert_eq!(
            filter_axis(&m, dims, 0, 1, true),
            [false, false, true, true, false, false, false]
        );
        assert_eq!(
            filter_axis(&m, dims, 0, 1, false),
            [true, true, true, true, true, true, true]
        );
    }

    #[test]
    fn a_ring_is_filled_and_the_largest_component_kept() {
        let (n, dims) = (40, [40, 40, 1]);
        let mut m = vec![false; n * n];
        for (p, v) in m.iter_mut().enumerate() {
            let (i, j) = (p % n, p / n);
            // a ring from 1 to 30 (116 voxels), and a lone voxel at (39, 39): under 2 % of it
            *v = ((1..=30).contains(&i) && (j == 1 || j == 30))
                || ((1..=30).contains(&j) && (i == 1 || i == 30))
                || (i == 39 && j == 39);
        }
        let mut c = body_components(&m, dims, [1.0, 1.0]).unwrap();
        assert!(!c[n * n - 1] && c[1 + n]);
        fill_planes(&mut c, dims);
        assert!(c[3 + n * 3], "the ring's inside is filled");
        assert_eq!(c.iter().filter(|&&x| x).count(), 900);
        // A second ring of a quarter the size is kept (an arm); a flat bar is not (a couch).
        let mut m2 = m.clone();
        for (p, v) in m2.iter_mut().enumerate() {
            let (i, j) = (p % n, p / n);
            *v |= ((33..=37).contains(&i) && (2..=6).contains(&j)) || (j == 36 && i <= 30);
        }
        let c2 = body_components(&m2, dims, [1.0, 1.0]).unwrap();
        assert!(c2[35 + n * 4] && !c2[10 + n * 36]);
    }
}
