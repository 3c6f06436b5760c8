//! Exact tracing of a *ray sheet*: rays that share one path in the plane of two grid axes
//! and fan out along the third.
//!
//! The rays of one detector row of an AP or lateral view do: the source and the row's
//! pixels lie in one plane that contains the row's direction, a grid axis `a`, so seen
//! along `a` (in the plane of the other two axes `b` and `c`) every ray of the row follows
//! the same line. That line crosses the `b` and `c` grid planes at the same places for all
//! of them, so those crossings are found once per row (a 2-D Siddon walk, [`Sheet`]), and
//! between two of them every ray stays in one line of voxels along `a` (contiguous in memory
//! when `a` is the grid's fastest axis). What is left per ray and segment is where the ray
//! is along `a` at the segment's two ends: one voxel, or two with the plane between them
//! (a ray moves less than one voxel along `a` per segment, which the sheet requires).
//!
//! The integral is Siddon's, exact: the same voxels with the same lengths as
//! [`crate::trace::siddon`], up to rounding (both match the brute-force reference to 1e-9
//! relative, `sim/tests/sheet.rs`). Rows are parametrised by the grid coordinate `b` rather
//! than by distance: ∫mu dt = (dt/db) · ∫mu db.
//!
//! One case no f64 tracer settles: a ray within ~1e-13 voxels of a plane of `a` at a slope
//! of ~1e-15 (the rounding of a view's basis, e.g. the central column of an odd-width
//! detector over a grid of even width, centred). Where it crosses that plane is then
//! uncertain by a voxel, and the sheet and the per-ray tracers may split its length between
//! the two voxels differently.
//!
//! A group of rays is a sheet when, for every ray, the line it follows in the `b`–`c`
//! plane, `c = C + m_c·b`, is the group's within 1e-10 voxels over the box, and its slope
//! along `a`, `|da/db|`, is below 1. The sheet uses its middle ray's line for all rays,
//! so the tolerance bounds the error at 1e-10 voxels of plane position (≈ 1e-13 relative
//! for a chest-sized path).

#[cfg(target_arch = "x86_64")]
#[macro_use]
mod kernel;
#[cfg(target_arch = "x86_64")]
mod ahead;
#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod materials;
mod rays;
mod walk;

#[cfg(target_arch = "x86_64")]
use ahead::Ahead;
use materials::MaterialSums;
use rays::{Block, Pass, Rays};
use walk::walk;

use crate::grid_box::GridBox;
use crate::occupancy::RowExtents;
use crate::ray::GridRay;
use crate::trace::packet::{self, Kernel as Simd};

/// Segments handled together per group of rays in the SIMD kernels: the group's rays stay
/// in registers over the block, and inside the group's range each segment's exit is the
/// next one's entry.
const BLOCK: usize = 8;

/// Largest difference between a ray's line in the `b`–`c` plane and its sheet's, in voxels
/// anywhere in the box, for the ray to belong to the sheet.
const LINE_TOLERANCE: f64 = 1e-10;

/// The line shared by a sheet's rays in the plane of axes `b` and `c`, and the segments
/// into which the grid planes of `b` and `c` cut it.
#[derive(Debug, Clone)]
pub struct Sheet {
    /// The axis the rays fan out along (the voxel lines' axis).
    a: usize,
    /// Segments: `[b_start, b_end]` in grid units of `b` and the linear index of the voxel
    /// at `a = 0` of the line of voxels the segment runs through.
    segments: Vec<Segment>,
    /// Per ray: where it is along `a`, and its range along `b` (as the kernels read them).
    rays: Rays,
    /// Per ray: mm of path per unit of `b`.
    mm_per_b: Vec<f64>,
    /// The rays' positions in the caller's list (those that hit the box).
    slots: Vec<usize>,
    /// Length of the caller's list.
    len: usize,
}

#[derive(Debug, Clone, Copy)]
struct Segment {
    b0: f64,
    b1: f64,
    /// `b1 - b0`.
    db: f64,
    base: f64,
    /// Where along `a` the segment's line of voxels may be non-zero: every voxel whose
    /// cube lies below `nz_lo` or from `nz_hi` on is zero, and so is every voxel a ray
    /// clamped into the box reads there (±∞: no such knowledge; see [`Sheet::skip_zeros`]).
    nz_lo: f64,
    nz_hi: f64,
}

/// How many (group of rays, block of segments) pairs the SIMD kernels take each way
/// ([`Sheet::passes`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Passes {
    /// Skipped: no ray of the group meets the block.
    pub missed: usize,
    /// Skipped: every voxel the group can meet there is zero ([`Sheet::skip_zeros`]).
    pub zeros: usize,
    /// Every ray inside the block and its positions rising (no slope negative) or falling
    /// (none positive) within the box, leaving out its last voxel: the shortest path.
    pub rising: usize,
    pub falling: usize,
    /// Every ray inside the block, otherwise.
    pub inside: usize,
    /// Some ray's range ends inside the block.
    pub clipped: usize,
}

/// One ray of a sheet: `a = a0 + slope·b` for `b ∈ [b_lo, b_hi]`; `mm_per_b` converts
/// the integral over `b` to one over distance (mm).
#[derive(Debug, Clone, Copy)]
struct SheetRay {
    a0: f64,
    slope: f64,
    /// `1 / slope`, or 0 when the slope is 0 (no plane of `a` is ever crossed).
    inv_slope: f64,
    b_lo: f64,
    b_hi: f64,
    mm_per_b: f64,
}

impl Sheet {
    /// The sheet of `rays` (already clipped to `bounds`, the box the renderer integrates
    /// over; `None`: the ray misses) in a grid of `dims` voxels, if they form one: see the
    /// module documentation. Rays that miss are left out (their integral is 0).
    pub fn new(rays: &[Option<GridRay>], dims: [usize; 3], bounds: &GridBox) -> Option<Self> {
        let hits: Vec<(usize, &GridRay)> = rays
            .iter()
            .enumerate()
            .filter_map(|(n, r)| r.as_ref().map(|r| (n, r)))
            .collect();
        let (_, reference) = *hits.get(hits.len() / 2)?;
        (0..3).find_map(|a| Self::along(a, reference, &hits, rays.len(), dims, bounds))
    }

    /// The sheet fanning out along axis `a`, if the rays form one.
    fn along(
        a: usize,
        reference: &GridRay,
        hits: &[(usize, &GridRay)],
        hits_len: usize,
        dims: [usize; 3],
        bounds: &GridBox,
    ) -> Option<Self> {
        let (p, q) = ((a + 1) % 3, (a + 2) % 3);
        // b: the axis of the plane along which the reference ray advances faster.
        let (b, c) = if reference.gd[p].abs() >= reference.gd[q].abs() {
            (p, q)
        } else {
            (q, p)
        };
        let line = |r: &GridRay| {
            let m = r.gd[c] / r.gd[b];
            (r.g0[c] - r.g0[b] * m, m)
        };
        if reference.gd[b] == 0.0 {
            return None;
        }
        let (c0, mc) = line(reference);
        let b_far = (bounds.lo[b] as f64).abs().max(bounds.hi[b] as f64);
        let mut sheet_rays = Vec::with_capacity(hits.len());
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (_, r) in hits {
            if r.gd[b] == 0.0 {
                return None;
            }
            let (rc0, rmc) = line(r);
            // Distance between the ray's line and the sheet's at the box's ends along b.
            let off = (rc0 - c0).abs() + (rmc - mc).abs() * b_far;
            let slope = r.gd[a] / r.gd[b];
            if !(off <= LINE_TOLERANCE && slope.abs() < 1.0) {
                return None;
            }
            let (e, x) = (r.g0[b] + r.t_enter * r.gd[b], r.g0[b] + r.t_exit * r.gd[b]);
            let (b_lo, b_hi) = (e.min(x), e.max(x));
            lo = lo.min(b_lo);
            hi = hi.max(b_hi);
            sheet_rays.push(SheetRay {
                a0: r.g0[a] - r.g0[b] * slope,
                slope,
                inv_slope: if slope == 0.0 { 0.0 } else { 1.0 / slope },
                b_lo,
                b_hi,
                mm_per_b: 1.0 / r.gd[b].abs(),
            });
        }
        let strides = [1, dims[0], dims[0] * dims[1]];
        let segments = walk(lo, hi, c0, mc, b, c, bounds, strides);
        Some(Self {
            a,
            segments,
            rays: Rays::new(&sheet_rays),
            mm_per_b: sheet_rays.iter().map(|r| r.mm_per_b).collect(),
            slots: hits.iter().map(|(n, _)| *n).collect(),
            len: hits_len,
        })
    }

    /// Writes each ray's ∫mu ds (mu per mm, lengths in mm) into `out` (one value per ray
    /// given to [`Sheet::new`]; 0 for rays that miss). `field` is indexed
    /// `i + nx·(j + ny·k)` over `dims` voxels and `bounds` is the box the rays were clipped
    /// to. Uses the widest SIMD kernel the CPU has ([`packet::kernel`]).
    pub fn line_integrals(
        &self,
        field: &[f32],
        dims: [usize; 3],
        bounds: &GridBox,
        out: &mut [f64],
    ) {
        self.line_integrals_with(packet::kernel(), field, dims, bounds, out);
    }

    /// As [`Sheet::line_integrals`], with the given SIMD kernel (eight rays at a time
    /// with AVX-512, four with AVX2) or, for `None` or a kernel the CPU lacks
    /// ([`packet::supported`]), the portable one: all give the same bits
    /// (`sim/tests/sheet.rs`).
    pub fn line_integrals_with(
        &self,
        simd: Option<Simd>,
        field: &[f32],
        dims: [usize; 3],
        bounds: &GridBox,
        out: &mut [f64],
    ) {
        self.sums_with(simd, field, dims, bounds, None, out);
    }

    /// Writes each ray's Σρ·ℓ per material (g/cm³ · mm) over a composition's packed values
    /// (`packed`, indexed as in [`Sheet::line_integrals`]; [`crate::composition`]) into
    /// `out`: materials `0..k` of the n-th ray given to [`Sheet::new`] at `out[n·k..]`
    /// (zeros for rays that miss). Every material index in `packed` is below `k`.
    pub fn material_sums(
        &self,
        packed: &[f32],
        dims: [usize; 3],
        bounds: &GridBox,
        k: usize,
        out: &mut [f64],
    ) {
        self.material_sums_with(packet::kernel(), packed, dims, bounds, k, out);
    }

    /// As [`Sheet::material_sums`], with the given kernel, as for
    /// [`Sheet::line_integrals_with`]: all give the same bits.
    pub fn material_sums_with(
        &self,
        simd: Option<Simd>,
        packed: &[f32],
        dims: [usize; 3],
        bounds: &GridBox,
        k: usize,
        out: &mut [f64],
    ) {
        self.sums_with(simd, packed, dims, bounds, Some(k), out);
    }

    /// The line integrals (`materials`: `None`) or the sums of materials `0..k` (`Some(k)`)
    /// of every ray into `out`, with the given kernel.
    fn sums_with(
        &self,
        simd: Option<Simd>,
        field: &[f32],
        dims: [usize; 3],
        bounds: &GridBox,
        materials: Option<usize>,
        out: &mut [f64],
    ) {
        assert_eq!(
            field.len(),
            dims.iter().product::<usize>(),
            "field and dims disagree"
        );
        let per_ray = materials.unwrap_or(1);
        assert_eq!(
            out.len(),
            self.len * per_ray,
            "one sum per ray given to Sheet::new (per material)"
        );
        let stride = [1, dims[0], dims[0] * dims[1]][self.a] as f64;
        let (a_lo, a_hi) = (bounds.lo[self.a] as f64, (bounds.hi[self.a] - 1) as f64);
        let ray = &self.rays;
        let mut acc = vec![0.0f64; if materials.is_some() { 0 } else { ray.len() }];
        let mut state = materials.map(|k| MaterialSums::new(ray.len(), k));
        let kernel = Kernel {
            field,
            stride,
            a_lo,
            a_hi,
        };
        // The kernels this CPU runs: the widest and the narrower (`packet::supported`).
        let runs = |k: &Simd| match packet::kernel() {
            Some(Simd::Avx512) => true,
            Some(Simd::Avx2) => *k == Simd::Avx2,
            None => false,
        };
        let simd = simd.filter(|k| field.len() < (1 << 31) && runs(k));
        let segments = &self.segments;
        match (simd, state.as_mut()) {
            // SAFETY: the CPU has the kernel's features (`packet::supported`), and the
            // field fewer than 2³¹ values.
            #[cfg(target_arch = "x86_64")]
            (Some(Simd::Avx512), m) => unsafe {
                avx512::integrate(&kernel, segments, ray, &mut acc, m)
            },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            (Some(Simd::Avx2), m) => unsafe {
                avx2::integrate(&kernel, segments, ray, &mut acc, m)
            },
            (_, None) => kernel.integrate(segments, ray, &mut acc),
            (_, Some(m)) => kernel.integrate_materials(segments, ray, m),
        }
        out.fill(0.0);
        for (r, slot) in self.slots.iter().enumerate() {
            let scale = self.mm_per_b[r];
            match state.as_mut() {
                None => out[*slot] = acc[r] * scale,
                Some(m) => {
                    for (k, o) in out[slot * per_ray..(slot + 1) * per_ray]
                        .iter_mut()
                        .enumerate()
                    {
                        *o = m.sum(r, k) * scale;
                    }
                }
            }
        }
    }

    /// Lets the SIMD kernels skip a group of rays over a block of segments where every
    /// voxel those rays can meet is zero, from where each row of voxels along i holds
    /// non-zero values (`rows`, of the field the sheet will integrate; `bounds`, the box its
    /// rays were clipped to). The skipped pieces are exact zeros, so the results are the
    /// same bits. Only sheets along i (axis 0) take it; others are left as they are.
    pub fn skip_zeros(&mut self, rows: &RowExtents, bounds: &GridBox) {
        if self.a != 0 {
            return;
        }
        // As u32, like the extents (a grid's axis is below 2³² voxels).
        let (a_lo, a_hi) = (bounds.lo[0] as u32, bounds.hi[0].saturating_sub(1) as u32);
        for s in &mut self.segments {
            (s.nz_lo, s.nz_hi) = match rows.row_from(s.base) {
                None => (f64::INFINITY, f64::NEG_INFINITY),
                // A ray clamped into the box reads its first or last voxel wherever it
                // stands beyond them: no zeros to count on at a side where those are not.
                Some((first, last)) => (
                    if first <= a_lo {
                        f64::NEG_INFINITY
                    } else {
                        f64::from(first)
                    },
                    if last >= a_hi {
                        f64::INFINITY
                    } else {
                        f64::from(last) + 1.0
                    },
                ),
            };
        }
    }

    /// How the SIMD kernels take each (group of `lanes` rays, block of segments) pair when
    /// they integrate lines in a box whose first and last voxel along the sheet's axis are
    /// `bounds`' (for tests and benchmarks; `lanes` 4 or 8). As the kernels, only sheets
    /// along i (contiguous lines, read in pairs) take [`Passes::rising`] and `falling`.
    pub fn passes(&self, lanes: usize, bounds: &GridBox) -> Passes {
        let spans = self.rays.spans(lanes.max(Rays::GROUP));
        let (a_lo, a_hi) = (bounds.lo[self.a], bounds.hi[self.a] - 1);
        let monotone = (self.a == 0 && a_hi > a_lo).then_some((a_lo as f64, a_hi as f64));
        let mut n = Passes::default();
        for block in self.segments.chunks(BLOCK) {
            let block = Block::of(block);
            for span in &spans {
                *match span.pass(&block, monotone) {
                    Pass::Miss => &mut n.missed,
                    Pass::Zeros => &mut n.zeros,
                    Pass::Monotone { rising: true } => &mut n.rising,
                    Pass::Monotone { rising: false } => &mut n.falling,
                    Pass::Inside => &mut n.inside,
                    Pass::Clipped => &mut n.clipped,
                } += 1;
            }
        }
        n
    }

    /// Number of segments of the shared line (for tests and benchmarks).
    pub fn segments(&self) -> usize {
        self.segments.len()
    }

    /// The axis the rays fan out along (0, 1, 2 = i, j, k).
    pub fn axis(&self) -> usize {
        self.a
    }
}

/// What the per-segment arithmetic reads: the field, the voxel lines' stride, and the box's
/// first and last voxel along `a`.
struct Kernel<'a> {
    field: &'a [f32],
    stride: f64,
    a_lo: f64,
    a_hi: f64,
}

impl Kernel<'_> {
    /// Σ over segments of ∫mu db for every ray (portable; the SIMD kernels compute the
    /// same operations, fused multiply-adds included, so give the same bits).
    fn integrate(&self, segments: &[Segment], rays: &Rays, acc: &mut [f64]) {
        for s in segments {
            for (r, sum) in acc.iter_mut().enumerate() {
                *sum += self.piece(s, rays, r);
            }
        }
    }

    /// ∫mu db of ray `r` over segment `s`: the ray enters at `x0` and leaves at `x1` along
    /// `a`; if those lie in different voxels, the plane between them (`max` of the two
    /// floors) splits the segment, and `w` (in units of b) is the part before it.
    #[inline(always)]
    fn piece(&self, s: &Segment, rays: &Rays, r: usize) -> f64 {
        let (mu0, mu1, w, db) = self.voxels(s, rays, r);
        let (mu0, mu1) = (f64::from(mu0), f64::from(mu1));
        w.mul_add(mu0 - mu1, db * mu1)
    }

    /// The values of the voxels ray `r` meets at its entry into and exit from segment `s`,
    /// the length before the plane between them, `w`, and the segment's length `db` (both
    /// in units of b, clipped to the ray's range).
    #[inline(always)]
    fn voxels(&self, s: &Segment, rays: &Rays, r: usize) -> (f32, f32, f64, f64) {
        let lo = s.b0.max(rays.b_lo[r]);
        let hi = s.b1.min(rays.b_hi[r]);
        let db = (hi - lo).max(0.0);
        let x0 = rays.slope[r].mul_add(lo, rays.a0[r]);
        let x1 = rays.slope[r].mul_add(hi, rays.a0[r]);
        let (f0, f1) = (x0.floor(), x1.floor());
        let i0 = f0.max(self.a_lo).min(self.a_hi);
        let i1 = f1.max(self.a_lo).min(self.a_hi);
        let v0 = self.field[i0.mul_add(self.stride, s.base) as usize];
        let v1 = self.field[i1.mul_add(self.stride, s.base) as usize];
        let w = ((f0.max(f1) - x0) * rays.inv_slope[r]).max(0.0).min(db);
        (v0, v1, w, db)
    }
}
