//! Where a volume's non-zero values lie, row by row: for each row of voxels along the grid's
//! i axis (fixed j and k), its first and last non-zero voxel. Exact Siddon adds nothing
//! over zeros, so the renderer clips rays to the rows' bounding box ([`RowExtents::bounding_box`],
//! [`occupied`]) and the ray-sheet kernels skip groups of rays over
//! blocks of rows where every voxel they can meet is zero ([`crate::trace::sheet`]): in a
//! real CT, the air below −1000 HU (mu exactly 0) outside the body and the scanner's field
//! of view.

use crate::grid_box::GridBox;
use crate::volume::Volume;

/// The smallest box of voxels of `volume` holding every non-zero value, or `None` if all
/// are zero. Tracers that integrate the values may clip rays to it: outside it they add
/// nothing.
pub fn occupied(volume: &Volume) -> Option<GridBox> {
    RowExtents::of(volume).bounding_box()
}

/// Per row `j + ny·k` of a volume, the first and last non-zero voxel along i.
#[derive(Debug, Clone)]
pub struct RowExtents {
    dims: [usize; 3],
    /// First non-zero i per row; `u32::MAX` for a row of zeros.
    first: Vec<u32>,
    /// Last non-zero i per row; 0 for a row of zeros.
    last: Vec<u32>,
    /// `1 / nx`, to find a row from its first voxel's index without a division
    /// ([`RowExtents::row_from`]).
    per_row: f64,
}

/// Values tested at once by [`first_non_zero`] and [`last_non_zero`]: a fold over a
/// fixed-size block compiles to vector compares, where a per-value search does not.
const BLOCK: usize = 16;

/// Whether `block` holds a non-zero value (NaN included).
#[inline]
fn any_non_zero(block: &[f32; BLOCK]) -> bool {
    block.iter().fold(false, |any, &v| any | (v != 0.0))
}

/// The index of `row`'s first non-zero value (NaN included).
fn first_non_zero(row: &[f32]) -> Option<usize> {
    let (blocks, rest) = row.as_chunks::<BLOCK>();
    match blocks.iter().position(any_non_zero) {
        Some(b) => blocks[b]
            .iter()
            .position(|&v| v != 0.0)
            .map(|i| b * BLOCK + i),
        None => rest
            .iter()
            .position(|&v| v != 0.0)
            .map(|i| blocks.len() * BLOCK + i),
    }
}

/// The index of `row`'s last non-zero value (NaN included).
fn last_non_zero(row: &[f32]) -> Option<usize> {
    let (rest, blocks) = row.as_rchunks::<BLOCK>();
    match blocks.iter().rposition(any_non_zero) {
        Some(b) => blocks[b]
            .iter()
            .rposition(|&v| v != 0.0)
            .map(|i| rest.len() + b * BLOCK + i),
        None => rest.iter().rposition(|&v| v != 0.0),
    }
}

impl RowExtents {
    /// The extents of `vol`'s rows (one parallel pass over the voxels). Zero is `0.0` or
    /// `-0.0`; anything else, NaN included, counts as non-zero.
    pub fn of(vol: &Volume) -> Self {
        use rayon::prelude::*;
        let [nx, ny, nz] = vol.dims();
        let rows = ny * nz;
        let (mut first, mut last) = (vec![u32::MAX; rows], vec![0u32; rows]);
        if nx > 0 {
            vol.data()
                .par_chunks(nx * ny.max(1))
                .zip(first.par_chunks_mut(ny.max(1)))
                .zip(last.par_chunks_mut(ny.max(1)))
                .for_each(|((plane, first), last)| {
                    for ((row, f), l) in plane.chunks(nx).zip(first).zip(last) {
                        if let Some(i) = first_non_zero(row) {
                            *f = i as u32;
                            *l = last_non_zero(row).unwrap_or(i) as u32;
                        }
                    }
                });
        }
        Self {
            dims: vol.dims(),
            first,
            last,
            per_row: 1.0 / nx.max(1) as f64,
        }
    }

    /// The first and last non-zero voxel along i of row `(j, k)`, or `None` for a row of
    /// zeros.
    pub fn row(&self, j: usize, k: usize) -> Option<(usize, usize)> {
        let n = j + self.dims[1] * k;
        (self.first[n] != u32::MAX).then(|| (self.first[n] as usize, self.last[n] as usize))
    }

    /// As [`RowExtents::row`], for the row whose voxel `i = 0` has linear index `base`
    /// (`i + nx·(j + ny·k)`).
    pub fn row_at(&self, base: usize) -> Option<(usize, usize)> {
        self.extent(base / self.dims[0].max(1))
            .map(|(f, l)| (f as usize, l as usize))
    }

    /// As [`RowExtents::row_at`], for `base` held as a whole number in an f64 (as the ray
    /// sheets' segments hold it) and the extent in u32: the form called per segment of
    /// every ray sheet, with one conversion (each usize–f64 conversion is several
    /// instructions on x86-64).
    pub fn row_from(&self, base: f64) -> Option<(u32, u32)> {
        // base / nx, by the reciprocal: `base` is a whole multiple of nx below 2⁵³, so the
        // product is within far less than ½ of the quotient (an integer division cost
        // more than the rest of the lookup).
        self.extent((base * self.per_row + 0.5) as usize)
    }

    /// The first and last non-zero voxel of row `n` (`j + ny·k`), if it has any.
    fn extent(&self, n: usize) -> Option<(u32, u32)> {
        let first = *self.first.get(n)?;
        (first != u32::MAX).then(|| (first, self.last[n]))
    }

    /// The smallest box of voxels holding every non-zero value, or `None` if all are zero.
    pub fn bounding_box(&self) -> Option<GridBox> {
        let ny = self.dims[1];
        let mut b: Option<GridBox> = None;
        for (n, (&f, &l)) in self.first.iter().zip(&self.last).enumerate() {
            if f == u32::MAX {
                continue;
            }
            let (j, k) = (n % ny, n / ny);
            let e = b.get_or_insert(GridBox {
                lo: [f as usize, j, k],
                hi: [l as usize + 1, j + 1, k + 1],
            });
            e.lo = [e.lo[0].min(f as usize), e.lo[1].min(j), e.lo[2].min(k)];
            e.hi = [
                e.hi[0].max(l as usize + 1),
                e.hi[1].max(j + 1),
                e.hi[2].max(k + 1),
            ];
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DVec3};

    /// The block-wise searches find what a value-by-value search finds, for rows shorter
    /// and longer than a block, non-zero values (NaN among them) anywhere, and −0.0 as zero.
    #[test]
    fn block_searches_match_a_plain_search() {
        for len in 0..3 * BLOCK + 5 {
            for a in 0..=len {
                for b in a..=len {
                    // Non-zero at a and b (none where they are `len`), −0.0 elsewhere.
                    let mut row = vec![-0.0f32; len];
                    for (p, v) in [(a, 1.5f32), (b, f32::NAN)] {
                        if p < len {
                            row[p] = v;
                        }
                    }
                    let want_first = row.iter().position(|&v| v != 0.0);
                    let want_last = row.iter().rposition(|&v| v != 0.0);
                    assert_eq!(first_non_zero(&row), want_first, "len {len}, {a}, {b}");
                    assert_eq!(last_non_zero(&row), want_last, "len {len}, {a}, {b}");
                }
            }
        }
    }

    #[test]
    fn extents_and_box_match_a_plain_scan() {
        let dims = [7, 5, 4];
        // Non-zero voxels at a few places, a NaN-free −0.0 that counts as zero, and one
        // row and one slice of zeros.
        let mut data = vec![0.0f32; 7 * 5 * 4];
        for (i, j, k, v) in [
            (2, 1, 0, 1.0),
            (5, 1, 0, 0.5),
            (0, 3, 2, 2.0),
            (6, 4, 2, 1.0),
        ] {
            data[i + 7 * (j + 5 * k)] = v;
        }
        data[3 + 7 * (2 + 5 * 3)] = -0.0;
        let vol = Volume::new(dims, DVec3::ONE, DVec3::ZERO, DMat3::IDENTITY, data).unwrap();
        let rows = RowExtents::of(&vol);
        for k in 0..4 {
            for j in 0..5 {
                let nz: Vec<usize> = (0..7)
                    .filter(|&i| vol.data()[i + 7 * (j + 5 * k)] != 0.0)
                    .collect();
                let want = nz.first().map(|&f| (f, *nz.last().unwrap()));
                assert_eq!(rows.row(j, k), want, "row ({j}, {k})");
                assert_eq!(rows.row_at(7 * (j + 5 * k)), want);
            }
        }
        assert_eq!(
            rows.bounding_box(),
            Some(GridBox {
                lo: [0, 1, 0],
                hi: [7, 5, 3]
            })
        );
        let air = Volume::new(
            dims,
            DVec3::ONE,
            DVec3::ZERO,
            DMat3::IDENTITY,
            vec![0.0; 140],
        );
        assert_eq!(RowExtents::of(&air.unwrap()).bounding_box(), None);
    }
}
