//! Exact line integrals of a whole detector row at once (SIMD: eight rays per vector with
//! AVX-512, four with AVX2).
//!
//! The same path as [`super::siddon`], organised for SIMD and for the cache. Rays that
//! share a dominant axis `m` and its direction are grouped into vectors ("packets": small
//! tiles of neighbouring detector pixels, see [`trace_rows_with`]),
//! and the row is traced **slab by slab**: for each voxel layer along `m`, every packet of
//! the row adds that layer's contribution. The voxels one layer holds for one row stay in
//! L1 while all packets use them, and the packets are independent, so they pipeline.
//!
//! In a layer each ray crosses at most one plane of each other axis (|gd_o| ≤ |gd_m|), so
//! its path there is at most three segments, computed without branches:
//!
//! * the layer's entry and exit parameters from its two m-planes, clamped to the ray's
//!   own `[t_enter, t_exit]` (outside it every length is zero, so rays that start later,
//!   end sooner or miss the volume add nothing);
//! * if no lane's next other-axis crossing (kept from the layer where it last changed
//!   voxel) falls inside the layer — most layers —, one segment per lane in the voxel
//!   it entered;
//! * otherwise the other axes' voxel indices at the exit from the ray's position there
//!   (`floor`), clamped into the grid and to one step per layer in the ray's direction;
//!   each crossing's parameter from its plane, clamped into the layer;
//! * the voxel values (a gather, or eight scalar loads: [`scalar_voxel_loads`]) times the
//!   lengths, summed in f64.
//!
//! Layer to layer a packet carries its sums and where it stands: the entry parameter,
//! the other axes' indices and the next crossing's parameter, each recomputed from plane
//! positions wherever a lane changes voxel (never accumulated). Rounding can only move a
//! sliver of the order of 1e-16 of a voxel between neighbours, as in the scalar tracer;
//! results agree with the brute-force reference to 1e-9 relative (`sim/tests/packet.rs`).
//!
//! Used by [`crate::render::Renderer`] when the CPU has AVX2 and FMA (or AVX-512F) and
//! the grid has fewer than 2³¹ voxels; packets whose rays disagree on the dominant axis are
//! left to the scalar tracer. One kernel body (the `packet_kernel!` macro) is instantiated
//! for each instruction set with that set's primitives.

use crate::ray::GridRay;

/// Whether this CPU can run the packet tracer.
pub fn available() -> bool {
    kernel().is_some()
}

/// Traces the rays of one row (`None`: the ray misses the grid) with the widest kernel
/// this CPU supports. For each ray handled, writes ∫mu ds to `out` and sets `handled`; rays
/// left unhandled (their packet mixes dominant axes or crosses fewer than
/// `min_crossings` other-axis planes per layer, or the CPU has no SIMD kernel, or the grid
/// has ≥ 2³¹ voxels) are for the scalar tracer. `mu` is indexed `i + nx·(j + ny·k)`.
pub fn trace_row(
    mu: &[f32],
    dims: [usize; 3],
    rays: &[Option<GridRay>],
    min_crossings: f64,
    out: &mut [f64],
    handled: &mut [bool],
) {
    handled.fill(false);
    if let Some(k) = kernel() {
        trace_row_with(k, mu, dims, rays, min_crossings, out, handled);
    }
}

/// Every kernel this CPU can run (for tests and benchmarks).
pub fn supported() -> Vec<Kernel> {
    match kernel() {
        Some(Kernel::Avx512) => vec![Kernel::Avx2, Kernel::Avx512],
        Some(Kernel::Avx2) => vec![Kernel::Avx2],
        None => vec![],
    }
}

/// As [`trace_row`] with a given kernel; does nothing unless the CPU supports it.
pub fn trace_row_with(
    kernel: Kernel,
    mu: &[f32],
    dims: [usize; 3],
    rays: &[Option<GridRay>],
    min_crossings: f64,
    out: &mut [f64],
    handled: &mut [bool],
) {
    dispatch::<false>(kernel, mu, dims, rays, min_crossings, 1, out, handled);
}

/// Per-material sums of ρ·ℓ (g/cm³ · mm) over a packed composition grid
/// ([`crate::composition`]) for the rays of one row, with `kernel`: materials `0..k` of ray
/// `n` go to `out[n·k..(n+1)·k]`. Which rays are handled follows the rules of
/// [`trace_row`]; the grid is visited once whatever `k` is.
#[allow(clippy::too_many_arguments)]
pub fn trace_row_materials_with(
    kernel: Kernel,
    packed: &[f32],
    dims: [usize; 3],
    rays: &[Option<GridRay>],
    min_crossings: f64,
    k: usize,
    out: &mut [f64],
    handled: &mut [bool],
) {
    dispatch::<true>(kernel, packed, dims, rays, min_crossings, k, out, handled);
}

/// As [`trace_row_with`] and [`trace_row_materials_with`] (`k` = 0: the line integral of
/// a mu grid) for several detector rows at once: `rays` holds whole rows of `cols` rays.
/// [`TILE_ROWS`] rows are traced together, each packet a tile of `TILE_ROWS` rows ×
/// `LANES / TILE_ROWS` columns: the rays of one column cross the planes of one axis
/// together and those of one row the planes of the other, so a square-ish tile meets
/// fewer layers with a crossing in some lane — the layers that need three segments —
/// than a packet of one row's lanes (docs/projector.md, "Packet tiles").
/// Detector rows traced together by [`trace_rows_with`].
pub const TILE_ROWS: usize = 4;
/// Most rays [`trace_rows_with`] walks through the layers together (a multiple of every
/// kernel's lane count).
const GROUP_RAYS: usize = 128;

#[allow(clippy::too_many_arguments)]
pub fn trace_rows_with(
    kernel: Kernel,
    field: &[f32],
    dims: [usize; 3],
    rays: &[Option<GridRay>],
    cols: usize,
    min_crossings: f64,
    k: usize,
    out: &mut [f64],
    handled: &mut [bool],
) {
    let width = k.max(1);
    assert!(
        cols > 0 && rays.len().is_multiple_of(cols),
        "whole rows of rays"
    );
    assert_eq!(
        out.len(),
        rays.len() * width,
        "one output per ray and material"
    );
    let lanes = match kernel {
        Kernel::Avx512 => 8,
        Kernel::Avx2 => 4,
    };
    let rows = rays.len() / cols;
    let mut order = Vec::with_capacity(rays.len());
    for r0 in (0..rows).step_by(TILE_ROWS) {
        let group = r0..rows.min(r0 + TILE_ROWS);
        let width = lanes / group.len();
        for block in (0..cols).step_by(width) {
            for r in group.clone() {
                order.extend((block..(block + width).min(cols)).map(|c| r * cols + c));
            }
        }
    }
    let tiled: Vec<Option<GridRay>> = order.iter().map(|&n| rays[n]).collect();
    let mut tiled_out = vec![0.0; out.len()];
    let mut tiled_handled = vec![false; rays.len()];
    // Traced in groups of at most GROUP_RAYS rays: a group walks its layers together, and
    // when the layers are i-planes (x-dominant rays) each ray keeps its own cache line
    // from layer to layer, so a group's lines must fit in L1.
    let chunks = tiled
        .chunks(GROUP_RAYS)
        .zip(tiled_out.chunks_mut(GROUP_RAYS * width))
        .zip(tiled_handled.chunks_mut(GROUP_RAYS));
    for ((rays, out), handled) in chunks {
        if k == 0 {
            dispatch::<false>(kernel, field, dims, rays, min_crossings, 1, out, handled);
        } else {
            dispatch::<true>(kernel, field, dims, rays, min_crossings, k, out, handled);
        }
    }
    for (i, &n) in order.iter().enumerate() {
        out[n * width..(n + 1) * width].copy_from_slice(&tiled_out[i * width..(i + 1) * width]);
        handled[n] = tiled_handled[i];
    }
}

#[allow(clippy::too_many_arguments)]
fn dispatch<const PACKED: bool>(
    kernel: Kernel,
    field: &[f32],
    dims: [usize; 3],
    rays: &[Option<GridRay>],
    min_crossings: f64,
    k: usize,
    out: &mut [f64],
    handled: &mut [bool],
) {
    handled.fill(false);
    assert_eq!(out.len(), rays.len() * k, "one output per ray and material");
    if field.len() >= (1 << 31) || !supported().contains(&kernel) {
        return;
    }
    #[cfg(target_arch = "x86_64")]
    // SAFETY: the kernel's CPU features were detected (`supported`).
    unsafe {
        let (f, r) = (field, rays);
        match (kernel, scalar_voxel_loads()) {
            (Kernel::Avx512, true) => {
                avx512::trace_row::<PACKED, true>(f, dims, r, min_crossings, k, out, handled)
            }
            (Kernel::Avx512, false) => {
                avx512::trace_row::<PACKED, false>(f, dims, r, min_crossings, k, out, handled)
            }
            (Kernel::Avx2, true) => {
                avx2::trace_row::<PACKED, true>(f, dims, r, min_crossings, k, out, handled)
            }
            (Kernel::Avx2, false) => {
                avx2::trace_row::<PACKED, false>(f, dims, r, min_crossings, k, out, handled)
            }
        }
    }
}

/// ∫mu ds for four rays with `kernel`, or `None` when they cannot share a packet or the
/// CPU lacks the kernel. A convenience over [`trace_row_with`] for tests.
pub fn line_integrals4(
    kernel: Kernel,
    mu: &[f32],
    dims: [usize; 3],
    rays: &[Option<GridRay>; 4],
) -> Option<[f64; 4]> {
    let mut out = [0.0; 4];
    let mut handled = [false; 4];
    trace_row_with(kernel, mu, dims, rays, 0.0, &mut out, &mut handled);
    handled.iter().all(|&h| h).then_some(out)
}

/// Plane crossings of the other two axes per voxel layer below which the renderer leaves
/// a packet to the scalar tracer, which reports runs of whole layers cheaply and so wins
/// while crossings are sparse (near-axial views) — unless the packets are eight wide.
/// Chosen by timing thresholds 0–0.7 on the chest-sized case with
/// `TG_PACKET_THRESHOLD=x cargo run --release -p tomograf-sim --example profile_ap θ`:
/// with AVX-512 packets win everywhere (0), with AVX2 from 0.3 crossings per layer.
pub fn default_threshold() -> f64 {
    if kernel() == Some(Kernel::Avx512) {
        0.0
    } else {
        0.3
    }
}

/// The SIMD kernel this CPU runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    /// Four rays per vector (AVX2 + FMA).
    Avx2,
    /// Eight rays per vector (AVX-512F and DQ).
    Avx512,
}

/// The widest kernel this CPU supports, if any. `TG_KERNEL=avx2` (on an AVX-512 CPU) or
/// `TG_KERNEL=none` (the scalar tracer only) narrows the choice, for measuring the kernels
/// on one machine (read once; a kernel the CPU lacks, or any other value, is ignored). The
/// results are the same bits with every kernel.
pub fn kernel() -> Option<Kernel> {
    #[cfg(target_arch = "x86_64")]
    {
        static K: std::sync::OnceLock<Option<Kernel>> = std::sync::OnceLock::new();
        *K.get_or_init(|| {
            let avx2 =
                std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
            // The sheet kernel uses AVX-512DQ too, which every AVX-512 CPU but Xeon Phi has.
            let avx512 = std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512dq");
            let widest = if avx2 && avx512 {
                Some(Kernel::Avx512)
            } else {
                avx2.then_some(Kernel::Avx2)
            };
            match (std::env::var("TG_KERNEL").as_deref(), widest) {
                (Ok("none"), _) => None,
                (Ok("avx2"), Some(_)) => Some(Kernel::Avx2),
                _ => widest,
            }
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        None
    }
}

/// Whether the kernels read a packet's voxel values with scalar loads (eight with
/// AVX-512, four with AVX2) rather than one `vgatherdps`. Measured on an AMD Zen 4 (EPYC),
/// the loads are faster with AVX-512 (chest-sized AP view, `profile_ap`: docs/projector.md,
/// "Session 10"), and on an AVX2-only AMD EPYC with AVX2 (docs/projector.md, "AVX2"), so
/// they are the default on AMD CPUs; elsewhere the gather stays (docs/projector.md says
/// what was measured on Intel). `TG_VOXEL_LOADS=scalar` or `=gather` overrides the choice (read once; any
/// other value keeps the default), for measuring other CPUs; the values read, and so the
/// results, are the same either way.
pub fn scalar_voxel_loads() -> bool {
    static SCALAR: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *SCALAR.get_or_init(|| match std::env::var("TG_VOXEL_LOADS").as_deref() {
        Ok("scalar") => true,
        Ok("gather") => false,
        _ => cpu_is_amd(),
    })
}

fn cpu_is_amd() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        // cpuid leaf 0 exists on every x86-64 CPU.
        let id = std::arch::x86_64::__cpuid(0);
        // The vendor string "AuthenticAMD", four bytes each in ebx, edx, ecx.
        let word = |s: &[u8; 4]| u32::from_le_bytes(*s);
        [id.ebx, id.edx, id.ecx] == [word(b"Auth"), word(b"enti"), word(b"cAMD")]
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The dominant axis and direction shared by a packet's rays, if they share one and
/// cross at least `threshold` other-axis planes per layer.
fn packet_key(rays: &[Option<GridRay>], threshold: f64) -> Option<(usize, bool)> {
    let first = rays.iter().flatten().next()?;
    let m = first.dominant_axis();
    let positive = first.gd[m] > 0.0;
    rays.iter()
        .flatten()
        .all(|r| {
            let (o1, o2) = ((m + 1) % 3, (m + 2) % 3);
            let crossings = (r.gd[o1].abs() + r.gd[o2].abs()) / r.gd[m].abs();
            r.dominant_axis() == m && (r.gd[m] > 0.0) == positive && crossings >= threshold
        })
        .then_some((m, positive))
}

#[cfg(target_arch = "x86_64")]
#[macro_use]
mod kernel;

/// Four lanes of f64 (AVX2 + FMA).
#[cfg(target_arch = "x86_64")]
mod avx2;

/// Eight lanes of f64 (AVX-512F; its masks are bit masks).
#[cfg(target_arch = "x86_64")]
mod avx512;

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::grid_box::GridBox;
    use rand::{Rng, SeedableRng};

    /// Each kernel's two ways of reading voxels (a gather, or scalar loads) give the same
    /// bits (both read the same f32 values), on random rows of rays through a random grid.
    #[test]
    fn scalar_loads_equal_the_gather() {
        let kernels = supported();
        if kernels.is_empty() {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        }
        for kernel in kernels {
            compare_loads(kernel);
        }
    }

    fn compare_loads(kernel: Kernel) {
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(40);
        let dims = [37, 29, 23];
        let mu: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|_| r.random_range(0.0..0.05))
            .collect();
        let mut traced = 0;
        for _ in 0..50 {
            let m = r.random_range(0..3);
            let rays: Vec<Option<GridRay>> = (0..64)
                .map(|_| {
                    let mut g0 = [0.0; 3];
                    let mut gd = [0.0; 3];
                    for a in 0..3 {
                        g0[a] = r.random_range(-5.0..dims[a] as f64 + 5.0);
                        gd[a] = r.random_range(-0.9..0.9);
                    }
                    gd[m] = 1.0;
                    g0[m] = -10.0;
                    GridRay::clip_box(&GridBox::whole(dims), g0, gd, 0.0, 100.0)
                })
                .collect();
            let n = rays.len();
            let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
            let (mut ha, mut hb) = (vec![false; n], vec![false; n]);
            // SAFETY: the kernel's CPU features were detected (`supported`).
            unsafe {
                match kernel {
                    Kernel::Avx512 => {
                        avx512::trace_row::<false, true>(&mu, dims, &rays, 0.0, 1, &mut a, &mut ha);
                        avx512::trace_row::<false, false>(
                            &mu, dims, &rays, 0.0, 1, &mut b, &mut hb,
                        );
                    }
                    Kernel::Avx2 => {
                        avx2::trace_row::<false, true>(&mu, dims, &rays, 0.0, 1, &mut a, &mut ha);
                        avx2::trace_row::<false, false>(&mu, dims, &rays, 0.0, 1, &mut b, &mut hb);
                    }
                }
            }
            assert_eq!(ha, hb, "{kernel:?}");
            for i in 0..n {
                assert_eq!(
                    a[i].to_bits(),
                    b[i].to_bits(),
                    "{kernel:?}, ray {i}: {} vs {}",
                    a[i],
                    b[i]
                );
            }
            traced += ha.iter().filter(|&&h| h).count();
        }
        assert!(traced > 1000, "{kernel:?}: only {traced} rays traced");
    }
}
