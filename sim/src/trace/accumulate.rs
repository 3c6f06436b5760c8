//! What a tracer does with each piece of path: the "integrator" half of a projector.
//!
//! A tracer reports the voxels a ray crosses as single segments and as *runs* — `count`
//! voxels `first, first + stride, …` each crossed over the same length (whole voxels along
//! the ray's dominant axis). Accumulators decide what to sum: the line integral of one
//! attenuation field today; per-material path lengths or a differentiable renderer's
//! weights later, with no change to the tracer.

use crate::composition::{MAX_MATERIALS, unpack};

/// Receives the path of one ray through the grid. Voxel indices are linear
/// (`i + nx·(j + ny·k)`); lengths are in mm and never negative by more than rounding.
pub trait PathAccumulator {
    /// The ray crosses `voxel` over `length_mm`.
    fn segment(&mut self, voxel: usize, length_mm: f64);

    /// Three consecutive segments (a slab crossed by up to two other planes; unused
    /// segments have length 0). Accumulators may combine them before adding, to keep
    /// their dependency chain short. The default forwards to `segment`.
    #[inline(always)]
    fn segments3(&mut self, voxels: [usize; 3], lengths_mm: [f64; 3]) {
        for (v, l) in voxels.into_iter().zip(lengths_mm) {
            self.segment(v, l);
        }
    }

    /// The ray crosses `count` voxels `first + m·stride` (m = 0..count), each over
    /// `length_mm`. The default forwards to [`PathAccumulator::segment`].
    #[inline]
    fn run(&mut self, first: usize, stride: usize, count: usize, length_mm: f64) {
        for m in 0..count {
            self.segment(first + m * stride, length_mm);
        }
    }
}

/// Sums `mu · length` along the ray: the line integral ∫mu ds (dimensionless when mu is in
/// mm⁻¹ and lengths in mm).
///
/// Precision: every product and sum is formed in f64 (voxel values are exact in f64), and
/// runs are summed as Σmu first, then multiplied once by the run's voxel length, so a
/// 10⁴-voxel path loses no more than ~10⁻¹² relative — far below f32's resolution.
#[derive(Debug)]
pub struct LineIntegral<'a> {
    mu: &'a [f32],
    sum: f64,
}

impl<'a> LineIntegral<'a> {
    /// Accumulates over the attenuation values `mu` (mm⁻¹), indexed as the grid is.
    pub fn new(mu: &'a [f32]) -> Self {
        Self { mu, sum: 0.0 }
    }
    /// The line integral so far.
    pub fn value(&self) -> f64 {
        self.sum
    }
}

impl PathAccumulator for LineIntegral<'_> {
    #[inline(always)]
    fn segment(&mut self, voxel: usize, length_mm: f64) {
        self.sum += f64::from(self.mu[voxel]) * length_mm;
    }

    #[inline(always)]
    fn segments3(&mut self, v: [usize; 3], l: [f64; 3]) {
        let (a, b, c) = (self.mu[v[0]], self.mu[v[1]], self.mu[v[2]]);
        self.sum += f64::from(a) * l[0] + (f64::from(b) * l[1] + f64::from(c) * l[2]);
    }

    #[inline(always)]
    fn run(&mut self, first: usize, stride: usize, count: usize, length_mm: f64) {
        // One bounds check for the whole run; four independent sums hide add latency.
        let span = &self.mu[first..=first + (count - 1) * stride];
        let mut acc = [0.0f64; 4];
        let quads = count / 4;
        for q in 0..quads {
            let b = 4 * q * stride;
            // SAFETY: b + 3·stride ≤ (count − 1)·stride = span.len() − 1, checked by the
            // slice above.
            unsafe {
                acc[0] += f64::from(*span.get_unchecked(b));
                acc[1] += f64::from(*span.get_unchecked(b + stride));
                acc[2] += f64::from(*span.get_unchecked(b + 2 * stride));
                acc[3] += f64::from(*span.get_unchecked(b + 3 * stride));
            }
        }
        for m in 4 * quads..count {
            acc[0] += f64::from(span[m * stride]);
        }
        self.sum += ((acc[0] + acc[1]) + (acc[2] + acc[3])) * length_mm;
    }
}

/// Sums `density · length` per material along the ray, over a packed
/// [`crate::composition::Composition`] grid: Σρ_m·ℓ for each material m, in g/cm³ · mm
/// (divide by 10 for mass thickness in g/cm²). Sums are f64, as for [`LineIntegral`].
#[derive(Debug)]
pub struct MaterialPaths<'a> {
    packed: &'a [f32],
    sums: [f64; MAX_MATERIALS],
}

impl<'a> MaterialPaths<'a> {
    /// Accumulates over the packed grid values, indexed as the grid is.
    pub fn new(packed: &'a [f32]) -> Self {
        Self {
            packed,
            sums: [0.0; MAX_MATERIALS],
        }
    }

    /// Σρ·ℓ per material index so far (g/cm³ · mm).
    pub fn sums(&self) -> &[f64; MAX_MATERIALS] {
        &self.sums
    }
}

impl PathAccumulator for MaterialPaths<'_> {
    #[inline(always)]
    fn segment(&mut self, voxel: usize, length_mm: f64) {
        let (rho, m) = unpack(self.packed[voxel]);
        self.sums[m] += f64::from(rho) * length_mm;
    }
}

/// Records every `(voxel, length)` pair; for tests and for tools that need the path itself.
#[derive(Debug, Default, Clone)]
pub struct PathRecorder {
    /// `(voxel, length_mm)` in the order the tracer reported them (runs expanded).
    pub segments: Vec<(usize, f64)>,
}

impl PathAccumulator for PathRecorder {
    fn segment(&mut self, voxel: usize, length_mm: f64) {
        self.segments.push((voxel, length_mm));
    }
}
