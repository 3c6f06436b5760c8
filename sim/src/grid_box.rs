//! A box of whole voxels in a grid's index space: what tracers clip rays to and what
//! occupancy reports (it depends on nothing else in the crate).

/// A box of whole voxels `[lo, hi)` per axis, in grid coordinates (voxel indices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GridBox {
    /// First voxel index per axis.
    pub lo: [usize; 3],
    /// One past the last voxel index per axis.
    pub hi: [usize; 3],
}

impl GridBox {
    /// The whole grid of `dims` voxels.
    pub fn whole(dims: [usize; 3]) -> Self {
        Self {
            lo: [0; 3],
            hi: dims,
        }
    }

    /// The voxels in both boxes (`None`: none).
    pub fn intersect(&self, other: &GridBox) -> Option<GridBox> {
        let lo = std::array::from_fn(|a| self.lo[a].max(other.lo[a]));
        let hi = std::array::from_fn(|a| self.hi[a].min(other.hi[a]));
        (0..3).all(|a| lo[a] < hi[a]).then_some(GridBox { lo, hi })
    }
}
