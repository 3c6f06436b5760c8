//! The brick occupancy map: the voxel grid cut into cubes of `size³` voxels, each marked
//! occupied when the field a tracer integrates may be non-zero somewhere inside it.
//!
//! A brick is occupied when any voxel within `dilate` voxels of its box (per axis, i.e. in
//! the box grown by `dilate` on every side) satisfies the occupancy predicate. For exact
//! Siddon the predicate is "value ≠ 0" and `dilate = 0`: a voxel of value 0 adds exactly 0.
//! The trilinear field at a grid point `g` reads only the voxels whose centres lie less
//! than one voxel away per axis, so it is exactly 0 wherever all voxels within one voxel
//! are 0: `dilate = 1` makes every point of an unoccupied brick a zero of the field.
//!
//! The predicate is a parameter so that per-material tracing can ask "does this brick hold
//! material m" with the same code.

use crate::error::{Result, SimError};
use crate::grid_box::GridBox;
use crate::volume::Volume;
use rayon::prelude::*;

/// Which bricks of a grid may hold something to integrate.
#[derive(Debug, Clone, PartialEq)]
pub struct BrickMap {
    dims: [usize; 3],
    size: usize,
    bricks: [usize; 3],
    occupied: Vec<bool>,
}

/// The runs of linear voxel indices (`i + nx·(j + ny·k)`, one per row of constant `j`, `k`)
/// of brick number `b` (bricks `x`-fastest in a grid of `bricks`) of `size³` voxels grown
/// by `dilate` voxels on every side, clamped to a grid of `dims` voxels.
pub fn brick_rows(
    b: usize,
    bricks: [usize; 3],
    size: usize,
    dilate: usize,
    dims: [usize; 3],
) -> impl Iterator<Item = std::ops::Range<usize>> {
    let bi = [
        b % bricks[0],
        (b / bricks[0]) % bricks[1],
        b / (bricks[0] * bricks[1]),
    ];
    let lo: [usize; 3] = std::array::from_fn(|a| (bi[a] * size).saturating_sub(dilate));
    let hi: [usize; 3] = std::array::from_fn(|a| ((bi[a] + 1) * size + dilate).min(dims[a]));
    (lo[2]..hi[2]).flat_map(move |k| {
        (lo[1]..hi[1]).map(move |j| {
            let row = (k * dims[1] + j) * dims[0];
            row + lo[0]..row + hi[0]
        })
    })
}

impl BrickMap {
    /// Marks the bricks of `size³` voxels of `volume` holding a voxel within `dilate` voxels
    /// for which `occupied(value)` is true. `size` must be ≥ 1.
    pub fn build<P>(volume: &Volume, size: usize, dilate: usize, occupied: P) -> Result<Self>
    where
        P: Fn(f32) -> bool + Sync,
    {
        if size == 0 {
            return Err(SimError::OutOfRange(
                "brick size is 0 voxels; it must be ≥ 1".into(),
            ));
        }
        let dims = volume.dims();
        let bricks = dims.map(|d| d.div_ceil(size));
        let data = volume.data();
        let count = bricks[0] * bricks[1] * bricks[2];
        let occupied: Vec<bool> = (0..count)
            .into_par_iter()
            .map(|b| {
                brick_rows(b, bricks, size, dilate, dims)
                    .any(|r| data[r].iter().any(|&v| occupied(v)))
            })
            .collect();
        Ok(Self {
            dims,
            size,
            bricks,
            occupied,
        })
    }

    /// Bricks holding any non-zero value (exact Siddon: nothing else adds anything).
    pub fn nonzero(volume: &Volume, size: usize) -> Result<Self> {
        Self::build(volume, size, 0, |v| v != 0.0)
    }

    /// Bricks where the trilinear field of `volume` may be non-zero (non-zero voxels
    /// dilated by one voxel).
    pub fn trilinear_support(volume: &Volume, size: usize) -> Result<Self> {
        Self::build(volume, size, 1, |v| v != 0.0)
    }

    /// Edge length of a brick, voxels.
    pub fn size(&self) -> usize {
        self.size
    }

    /// Voxel grid dimensions.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Number of bricks per axis (the last may be partial).
    pub fn brick_dims(&self) -> [usize; 3] {
        self.bricks
    }

    /// Whether brick `(bi, bj, bk)` is occupied.
    #[inline(always)]
    pub fn is_occupied(&self, b: [usize; 3]) -> bool {
        self.occupied[b[0] + self.bricks[0] * (b[1] + self.bricks[1] * b[2])]
    }

    /// Number of occupied bricks.
    pub fn occupied_count(&self) -> usize {
        self.occupied.iter().filter(|&&o| o).count()
    }

    /// Total number of bricks.
    pub fn brick_count(&self) -> usize {
        self.occupied.len()
    }

    /// The voxel box of brick `b` (clipped to the grid).
    pub fn brick_box(&self, b: [usize; 3]) -> GridBox {
        GridBox {
            lo: std::array::from_fn(|a| b[a] * self.size),
            hi: std::array::from_fn(|a| ((b[a] + 1) * self.size).min(self.dims[a])),
        }
    }

    /// The voxel boxes of all occupied bricks, in storage order.
    pub fn occupied_boxes(&self) -> Vec<GridBox> {
        let [bx, by, _] = self.bricks;
        self.occupied
            .iter()
            .enumerate()
            .filter(|&(_, &o)| o)
            .map(|(b, _)| self.brick_box([b % bx, (b / bx) % by, b / (bx * by)]))
            .collect()
    }

    /// The smallest voxel box holding every occupied brick (`None`: none is occupied).
    pub fn occupied_box(&self) -> Option<GridBox> {
        let mut lo = [usize::MAX; 3];
        let mut hi = [0; 3];
        for b in self.occupied_boxes() {
            for a in 0..3 {
                lo[a] = lo[a].min(b.lo[a]);
                hi[a] = hi[a].max(b.hi[a]);
            }
        }
        (lo[0] < hi[0]).then_some(GridBox { lo, hi })
    }

    /// Heap bytes held by the map.
    pub fn memory_bytes(&self) -> usize {
        self.occupied.capacity() * std::mem::size_of::<bool>()
    }
}
