//! Voxel volumes and the world frame.
//!
//! # World frame
//! tomograf works in the **DICOM patient frame, LPS**, in millimetres: +x points to the
//! patient's **L**eft, +y to **P**osterior, +z to **S**uperior (head). NIfTI files are RAS;
//! their affine is converted on load by negating its first two rows
//! (see `tomograf_datasets::nifti`). DICOM series are already LPS.
//!
//! # Voxel layout
//! A volume has dimensions `(nx, ny, nz)` along its three index axes `(i, j, k)`. Voxel
//! `(i, j, k)` is stored at `i + nx * (j + ny * k)` (i fastest, as in NIfTI and in
//! DICOM stacked slice by slice). The world position of the **centre** of voxel
//! `(i, j, k)` is
//!
//! ```text
//! p = origin + direction · (spacing ∘ (i, j, k))
//! ```
//!
//! where `direction` is an orthonormal 3×3 matrix whose columns are the world directions
//! of the index axes (DICOM's direction cosines; a reflection is allowed) and `spacing`
//! is in mm. Each voxel is the box of size `spacing` centred there, so the volume covers
//! index coordinates `[-0.5, n - 0.5]` on each axis.
//!
//! # Grid coordinates
//! Tracers work in *grid coordinates* `g = (i, j, k) + 0.5`, in which voxel `(i, j, k)` is
//! the half-open unit cube `[i, i+1) × [j, j+1) × [k, k+1)` and the volume is `[0, n]³`.
//! A world ray `p(t) = o + t·d` (t in mm, `d` a unit vector) maps to `g(t) = g0 + t·gd`
//! with the **same** parameter `t`, so segment lengths measured in `t` are millimetres.

use crate::error::{Result, SimError};
use glam::{DMat3, DVec3};

/// A scalar field sampled on a regular grid placed in the LPS world frame.
///
/// The meaning of the values depends on the producer: CT volumes hold HU,
/// [`crate::attenuation`] turns them into linear attenuation coefficients in mm⁻¹,
/// which is what every projector integrates.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume {
    dims: [usize; 3],
    spacing: DVec3,
    origin: DVec3,
    direction: DMat3,
    data: Vec<f32>,
}

/// Largest number of voxels a volume may hold (2³⁴ voxels = 64 GiB of f32). Larger
/// requests are refused before any allocation is attempted.
pub const MAX_VOXELS: usize = 1 << 34;

/// Largest |coordinate| of a volume's first voxel, mm (1 km): no scanner frame is larger,
/// and a header that says so has the wrong units or a corrupt affine.
pub const MAX_ORIGIN_MM: f64 = 1e6;

/// Largest voxel size, mm (10 m; the reconstruction grid's `--spacing` has the same bound).
pub const MAX_SPACING_MM: f64 = 1e4;

impl Volume {
    /// Builds a volume, checking every invariant.
    ///
    /// * `dims` — voxels along `(i, j, k)`, each ≥ 1.
    /// * `spacing` — voxel size in mm along `(i, j, k)`, each finite and > 0.
    /// * `origin` — world (LPS, mm) position of the centre of voxel `(0, 0, 0)`.
    /// * `direction` — columns are the world directions of the index axes; must be
    ///   orthonormal to 1e-4 (it is re-orthonormalised to f64 precision).
    /// * `data` — `nx·ny·nz` values, `i` fastest. NaN and ±Inf are refused.
    pub fn new(
        dims: [usize; 3],
        spacing: DVec3,
        origin: DVec3,
        direction: DMat3,
        data: Vec<f32>,
    ) -> Result<Self> {
        let count = checked_voxel_count(dims)?;
        if data.len() != count {
            return Err(SimError::InvalidVolume(format!(
                "dimensions {}×{}×{} need {count} voxels but {} values were given",
                dims[0],
                dims[1],
                dims[2],
                data.len()
            )));
        }
        for (axis, s) in spacing.to_array().iter().enumerate() {
            if !(s.is_finite() && *s > 0.0 && *s <= MAX_SPACING_MM) {
                return Err(SimError::InvalidVolume(format!(
                    "spacing along axis {axis} is {s} mm; it must be finite and > 0, and at \
                     most {MAX_SPACING_MM} mm"
                )));
            }
        }
        if !origin.is_finite() {
            return Err(SimError::InvalidVolume(format!(
                "origin {origin} is not finite"
            )));
        }
        if origin.abs().max_element() > MAX_ORIGIN_MM {
            return Err(SimError::InvalidVolume(format!(
                "the first voxel lies at {origin} mm, beyond ±{MAX_ORIGIN_MM:e} mm (1 km) of \
                 the world origin: check the file's affine (NIfTI sform/qform, DICOM \
                 ImagePositionPatient) and its units (mm)"
            )));
        }
        let direction = orthonormalise(direction)?;
        if let Some(pos) = first_non_finite(&data) {
            let [i, j, k] = unravel(pos, dims);
            return Err(SimError::NonFiniteVoxel {
                i,
                j,
                k,
                value: data[pos].to_string(),
            });
        }
        Ok(Self {
            dims,
            spacing,
            origin,
            direction,
            data,
        })
    }

    /// A volume with identity direction whose grid is centred on `centre` (world mm).
    pub fn centred(
        dims: [usize; 3],
        spacing: DVec3,
        centre: DVec3,
        data: Vec<f32>,
    ) -> Result<Self> {
        let half = (DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) - 1.0) * 0.5;
        Self::new(
            dims,
            spacing,
            centre - half * spacing,
            DMat3::IDENTITY,
            data,
        )
    }

    /// Voxels along `(i, j, k)`.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }
    /// Voxel size in mm along `(i, j, k)`.
    pub fn spacing(&self) -> DVec3 {
        self.spacing
    }
    /// World (LPS, mm) position of the centre of voxel `(0, 0, 0)`.
    pub fn origin(&self) -> DVec3 {
        self.origin
    }
    /// Orthonormal matrix whose columns are the world directions of the index axes.
    pub fn direction(&self) -> DMat3 {
        self.direction
    }
    /// The voxel values, `i` fastest.
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    /// Index (in memory order, `i` fastest) of the first voxel whose value `bad` holds
    /// for, scanning on every core; `None` if there is none.
    pub fn first_voxel_where(&self, bad: impl Fn(f32) -> bool + Sync) -> Option<usize> {
        first_where(&self.data, bad)
    }
    /// Consumes the volume and returns its values.
    pub fn into_data(self) -> Vec<f32> {
        self.data
    }
    /// A copy with every value replaced by `f(value)`; the result must stay finite.
    pub fn map(&self, f: impl Fn(f32) -> f32 + Sync) -> Result<Self> {
        self.clone().map_in_place(f)
    }
    /// Replaces every value with `f(value)` without copying; the result must stay finite.
    pub fn map_in_place(mut self, f: impl Fn(f32) -> f32 + Sync) -> Result<Self> {
        use rayon::prelude::*;
        // One pass: each block is mapped, then scanned while it is in cache.
        let first_bad = self
            .data
            .par_chunks_mut(SCAN_BLOCK)
            .enumerate()
            .filter_map(|(b, block)| {
                block.iter_mut().for_each(|v| *v = f(*v));
                if !holds_any(block, |v| !v.is_finite()) {
                    return None;
                }
                let at = block.iter().position(|v| !v.is_finite())?;
                Some(b * SCAN_BLOCK + at)
            })
            .min();
        if let Some(pos) = first_bad {
            let [i, j, k] = unravel(pos, self.dims);
            return Err(SimError::NonFiniteVoxel {
                i,
                j,
                k,
                value: self.data[pos].to_string(),
            });
        }
        Ok(self)
    }
    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.data.len()
    }
    /// Always false: a volume holds at least one voxel.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    /// Value of voxel `(i, j, k)`; panics if out of range.
    pub fn get(&self, i: usize, j: usize, k: usize) -> f32 {
        self.data[i + self.dims[0] * (j + self.dims[1] * k)]
    }
    /// World position (mm) of the centre of the volume.
    pub fn centre(&self) -> DVec3 {
        let n = DVec3::new(
            self.dims[0] as f64,
            self.dims[1] as f64,
            self.dims[2] as f64,
        );
        self.index_to_world((n - 1.0) * 0.5)
    }
    /// World position (mm) of continuous voxel index `idx` (voxel centres at integers).
    pub fn index_to_world(&self, idx: DVec3) -> DVec3 {
        self.origin + self.direction * (idx * self.spacing)
    }
    /// Continuous voxel index of world point `p` (mm); voxel centres are at integers.
    pub fn world_to_index(&self, p: DVec3) -> DVec3 {
        (self.direction.transpose() * (p - self.origin)) / self.spacing
    }
    /// Grid coordinates (see the module docs) of world point `p`: voxel `(i,j,k)` is
    /// `[i, i+1)³`.
    pub fn world_to_grid(&self, p: DVec3) -> DVec3 {
        self.world_to_index(p) + 0.5
    }
    /// Grid-coordinate change per mm along the world direction `d`.
    pub fn world_dir_to_grid(&self, d: DVec3) -> DVec3 {
        (self.direction.transpose() * d) / self.spacing
    }
    /// The eight world corners of the volume's bounding box (outer voxel faces).
    pub fn world_corners(&self) -> [DVec3; 8] {
        let n = DVec3::new(
            self.dims[0] as f64,
            self.dims[1] as f64,
            self.dims[2] as f64,
        );
        std::array::from_fn(|c| {
            let g = DVec3::new(
                if c & 1 == 0 { 0.0 } else { n.x },
                if c & 2 == 0 { 0.0 } else { n.y },
                if c & 4 == 0 { 0.0 } else { n.z },
            );
            self.index_to_world(g - 0.5)
        })
    }
    /// Smallest and largest value.
    pub fn min_max(&self) -> (f32, f32) {
        self.data
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            })
    }
}

/// Index of the first NaN or ±Inf value.
fn first_non_finite(data: &[f32]) -> Option<usize> {
    first_where(data, |v| !v.is_finite())
}

/// Index of the first value for which `bad` holds, scanning on every core (a CT is
/// 10⁷–10⁸ voxels) in blocks (rayon's per-item `position_first` measured 20× slower than
/// one core here). A block is searched only when [`holds_any`] finds such a value in it.
fn first_where(data: &[f32], bad: impl Fn(f32) -> bool + Sync) -> Option<usize> {
    use rayon::prelude::*;
    data.par_chunks(SCAN_BLOCK)
        .enumerate()
        .find_map_first(|(b, block)| {
            if !holds_any(block, &bad) {
                return None;
            }
            let at = block.iter().position(|&v| bad(v))?;
            Some(b * SCAN_BLOCK + at)
        })
}

/// Whether `bad` holds for some value of `block`: tested on every value, without stopping
/// early, which the compiler vectorises (a search that stops at the first is several times
/// slower where, as usual, there is none).
#[inline]
fn holds_any(block: &[f32], bad: impl Fn(f32) -> bool) -> bool {
    block.iter().fold(false, |any, &v| any | bad(v))
}

/// Voxels per parallel task of the whole-volume passes.
const SCAN_BLOCK: usize = 1 << 16;

/// `nx·ny·nz`, refusing zero sizes, overflow, volumes above [`MAX_VOXELS`] and volumes
/// whose f32 values would not fit in the memory a job may take ([`crate::memory`]).
pub fn checked_voxel_count(dims: [usize; 3]) -> Result<usize> {
    let count = voxel_count_within_max(dims)?;
    crate::memory::check(
        count as u128 * 4,
        &format!(
            "a {}×{}×{} volume ({count} voxels of f32)",
            dims[0], dims[1], dims[2]
        ),
    )?;
    Ok(count)
}

fn voxel_count_within_max(dims: [usize; 3]) -> Result<usize> {
    if dims.contains(&0) {
        return Err(SimError::InvalidVolume(format!(
            "dimensions {}×{}×{} contain a zero",
            dims[0], dims[1], dims[2]
        )));
    }
    dims.iter()
        .try_fold(1usize, |acc, &n| acc.checked_mul(n))
        .filter(|&n| n <= MAX_VOXELS)
        .ok_or_else(|| {
            SimError::InvalidVolume(format!(
                "dimensions {}×{}×{} exceed the limit of {MAX_VOXELS} voxels ({} GiB as f32)",
                dims[0],
                dims[1],
                dims[2],
                (MAX_VOXELS * 4) >> 30
            ))
        })
}

fn unravel(pos: usize, dims: [usize; 3]) -> [usize; 3] {
    [
        pos % dims[0],
        (pos / dims[0]) % dims[1],
        pos / (dims[0] * dims[1]),
    ]
}

/// Checks that `m` is orthonormal to 1e-4 and returns it re-orthonormalised (Gram–Schmidt,
/// keeping its handedness) so that transforms are exact to f64 precision.
fn orthonormalise(m: DMat3) -> Result<DMat3> {
    if !m.is_finite() {
        return Err(SimError::InvalidVolume(format!(
            "direction matrix {m} is not finite"
        )));
    }
    let cols = [m.x_axis, m.y_axis, m.z_axis];
    for (a, c) in cols.iter().enumerate() {
        if (c.length() - 1.0).abs() > 1e-4 {
            return Err(SimError::InvalidVolume(format!(
                "direction column {a} = {c} is not a unit vector (length {})",
                c.length()
            )));
        }
    }
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let d = cols[a].dot(cols[b]);
        if d.abs() > 1e-4 {
            return Err(SimError::InvalidVolume(format!(
                "direction columns {a} and {b} are not orthogonal (dot product {d}); sheared grids are not supported"
            )));
        }
    }
    let x = cols[0].normalize();
    let y = (cols[1] - x * x.dot(cols[1])).normalize();
    let z_right = x.cross(y);
    let z = if z_right.dot(cols[2]) >= 0.0 {
        z_right
    } else {
        -z_right
    };
    Ok(DMat3::from_cols(x, y, z))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(n: usize) -> Vec<f32> {
        vec![0.0; n * n * n]
    }

    #[test]
    fn rejects_bad_spacing_and_values() {
        let id = DMat3::IDENTITY;
        let e = Volume::new(
            [2, 2, 2],
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::ZERO,
            id,
            cube(2),
        );
        assert!(e.unwrap_err().to_string().contains("spacing along axis 1"));
        let e = Volume::new(
            [2, 2, 2],
            DVec3::new(1.0, -1.0, 1.0),
            DVec3::ZERO,
            id,
            cube(2),
        );
        assert!(
            e.unwrap_err()
                .to_string()
                .contains("must be finite and > 0")
        );
        let e = Volume::new(
            [2, 2, 2],
            DVec3::new(1.0, 2e4, 1.0),
            DVec3::ZERO,
            id,
            cube(2),
        );
        assert!(e.unwrap_err().to_string().contains("at most 10000 mm"));
        let far = DVec3::new(0.0, -2e6, 0.0);
        let e = Volume::new([2, 2, 2], DVec3::ONE, far, id, cube(2));
        assert!(e.unwrap_err().to_string().contains("beyond ±1e6 mm"));
        let mut d = cube(2);
        d[5] = f32::NAN;
        let e = Volume::new([2, 2, 2], DVec3::ONE, DVec3::ZERO, id, d).unwrap_err();
        assert_eq!(
            e,
            SimError::NonFiniteVoxel {
                i: 1,
                j: 0,
                k: 1,
                value: "NaN".into()
            }
        );
        let e = Volume::new([0, 2, 2], DVec3::ONE, DVec3::ZERO, id, vec![]).unwrap_err();
        assert!(e.to_string().contains("contain a zero"));
        let e = checked_voxel_count([1 << 20, 1 << 20, 1 << 20]).unwrap_err();
        assert!(e.to_string().contains("exceed the limit"));
        let sheared = DMat3::from_cols(DVec3::X, DVec3::new(0.1, 1.0, 0.0).normalize(), DVec3::Z);
        let e = Volume::new([2, 2, 2], DVec3::ONE, DVec3::ZERO, sheared, cube(2)).unwrap_err();
        assert!(e.to_string().contains("not orthogonal"));
    }

    /// The first bad voxel in memory order is the one reported, wherever the others lie
    /// (several in one scanning block, others in later blocks), on any number of threads.
    #[test]
    fn the_first_non_finite_voxel_is_reported() {
        let n = 5 * (1 << 16) + 3;
        let mut d = vec![1.0f32; n];
        for (at, v) in [
            (4 * (1 << 16) + 2, f32::NAN),
            (70_001, f32::INFINITY),
            (70_005, f32::NAN),
            (200_000, f32::NEG_INFINITY),
        ] {
            d[at] = v;
        }
        for threads in [1, 2, 5] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            assert_eq!(pool.install(|| first_non_finite(&d)), Some(70_001));
        }
        assert_eq!(first_non_finite(&d[..70_001]), None);
        // The fused map-and-scan of map_in_place reports the same voxel.
        let bad_at = |v: f32| {
            if d[v as usize].is_finite() {
                v
            } else {
                f32::NAN
            }
        };
        let idx = Volume::new(
            [n, 1, 1],
            DVec3::ONE,
            DVec3::ZERO,
            DMat3::IDENTITY,
            (0..n).map(|i| i as f32).collect(),
        )
        .unwrap();
        let e = idx.map_in_place(bad_at).unwrap_err();
        assert!(
            matches!(e, SimError::NonFiniteVoxel { i: 70_001, .. }),
            "{e}"
        );
        let e = Volume::new([n, 1, 1], DVec3::ONE, DVec3::ZERO, DMat3::IDENTITY, d).unwrap_err();
        assert!(
            matches!(e, SimError::NonFiniteVoxel { i: 70_001, .. }),
            "{e}"
        );
    }

    #[test]
    fn index_world_round_trip_with_rotation_and_reflection() {
        let r = DMat3::from_rotation_z(0.3) * DMat3::from_diagonal(DVec3::new(1.0, -1.0, 1.0));
        let v = Volume::new(
            [3, 4, 5],
            DVec3::new(0.5, 0.7, 2.5),
            DVec3::new(10.0, -20.0, 5.0),
            r,
            vec![0.0; 60],
        )
        .unwrap();
        let idx = DVec3::new(1.25, 2.5, 3.75);
        let back = v.world_to_index(v.index_to_world(idx));
        assert!((back - idx).length() < 1e-12);
        // Voxel (0,0,0) centre is the origin.
        assert!((v.index_to_world(DVec3::ZERO) - v.origin()).length() < 1e-12);
    }

    #[test]
    fn centred_volume_centre() {
        let v = Volume::centred(
            [4, 5, 6],
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(1.0, 2.0, 3.0),
            vec![0.0; 120],
        )
        .unwrap();
        assert!((v.centre() - DVec3::new(1.0, 2.0, 3.0)).length() < 1e-12);
    }
}
