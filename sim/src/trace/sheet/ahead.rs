//! What the SIMD kernels prefetch: the next block's voxel lines.

use super::{BLOCK, Kernel, Segment};

/// The cache lines of the next block's voxel lines over the box's extent, which the SIMD
/// kernels ask for a few per group of rays, so that few are in flight at once: the kernel
/// waits on memory without them (a block's lines lie a line of the grid apart). Listed
/// once per block, as working out each address per group cost more than the kernel saved
/// (docs/projector.md, "Session 26").
pub(super) struct Ahead {
    /// First voxel of a line's span inside the box, from the line's `a = 0` voxel.
    start: usize,
    /// Addresses per line: its cache lines where lines are contiguous, its voxels
    /// otherwise.
    lines: usize,
    /// Voxels between consecutive addresses of a line.
    step: usize,
    list: Vec<usize>,
}

impl Ahead {
    pub(super) fn new(kernel: &Kernel) -> Self {
        let span = (kernel.a_lo * kernel.stride) as usize..=(kernel.a_hi * kernel.stride) as usize;
        let step = if kernel.stride == 1.0 {
            16
        } else {
            kernel.stride as usize
        };
        let lines = span.clone().step_by(step).count();
        Self {
            start: *span.start(),
            lines,
            step,
            list: Vec::with_capacity(BLOCK * lines),
        }
    }

    /// Lists the addresses of the block after block `n` of `segments`: every line's whole
    /// span in the box. (Leaving out the spans known to be zero, [`Segment::nz_lo`], was
    /// measured slower: the groups at their edges then wait for those zeros.)
    pub(super) fn list(&mut self, segments: &[Segment], n: usize) {
        let next = segments.get((n + 1) * BLOCK..).unwrap_or(&[]);
        self.list.clear();
        for s in &next[..next.len().min(BLOCK)] {
            let from = s.base as usize + self.start;
            // `0..lines` compiles to a tight loop (a stepped inclusive range measured 15 %
            // slower over the whole render).
            self.list
                .extend((0..self.lines).map(|l| from + l * self.step));
        }
    }

    /// The listed addresses, in one share per group of rays.
    pub(super) fn asks(&self, groups: usize) -> std::slice::Chunks<'_, usize> {
        self.list
            .chunks(self.list.len().div_ceil(groups.max(1)).max(1))
    }
}
