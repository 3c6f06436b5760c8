//! Exact line integrals of a whole detector row at once (SIMD: eight rays per vector with
//! AVX-512, four with AVX2).
//!
//! The same path as [`super::siddon`], organised for SIMD and for the cache. Rays that
//! share a dominant axis `m` and its direction are grouped into vectors ("packets"),
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
//! * the other axes' voxel indices at both ends from the ray's position there (`floor`),
//!   clamped into the grid and to one step per layer in the ray's direction;
//! * each crossing's parameter from its plane, clamped into the layer;
//! * the voxel values (gathered) times the lengths, summed in f64.
//!
//! Nothing is carried from layer to layer but the sums. Rounding can only move a sliver
//! of the order of 1e-16 of a voxel between neighbours, as in the scalar tracer; results
//! agree with the brute-force reference to 1e-9 relative (`sim/tests/packet.rs`).
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
        match kernel {
            Kernel::Avx512 => {
                avx512::trace_row::<PACKED>(field, dims, rays, min_crossings, k, out, handled)
            }
            Kernel::Avx2 => {
                avx2::trace_row::<PACKED>(field, dims, rays, min_crossings, k, out, handled)
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
    /// Eight rays per vector (AVX-512F).
    Avx512,
}

/// The widest kernel this CPU supports, if any.
pub fn kernel() -> Option<Kernel> {
    #[cfg(target_arch = "x86_64")]
    {
        static K: std::sync::OnceLock<Option<Kernel>> = std::sync::OnceLock::new();
        *K.get_or_init(|| {
            let avx2 =
                std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
            if avx2 && std::is_x86_feature_detected!("avx512f") {
                Some(Kernel::Avx512)
            } else {
                avx2.then_some(Kernel::Avx2)
            }
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        None
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

/// The kernel body, instantiated per instruction set. The caller supplies the vector and
/// mask types, the lane count and the primitives (all `#[inline]` with the set's target
/// features): `splat`, `zero`, `min`, `max`, `add`, `sub`, `mul`, `fmadd` (a·b + c),
/// `floor`, `gt`, `le`, `ne` (lane masks), `or` (of masks), `none` (no lane set),
/// `select` (mask ? a : b), `load`/`store` (from/to `[f64; LANES]`), `gather` (f32
/// values at f64-valued indices, widened to f64), and for compositions `gather_packed`
/// (density and material index of packed values), `eq`, `and` and `add_where` (s + w where
/// the mask is set).
#[cfg(target_arch = "x86_64")]
macro_rules! packet_kernel {
    ($features:literal, $lanes:literal, $vec:ty, $mask:ty, { $($prims:item)* }) => {
        use super::packet_key;
        /// The label bits of a packed composition value (`crate::composition`).
        const LABEL_MASK: i32 = crate::composition::MAX_MATERIALS as i32 - 1;
        use crate::ray::GridRay;
        #[allow(unused_imports)]
        use std::arch::x86_64::*;

        type V = $vec;
        type M = $mask;
        const LANES: usize = $lanes;

        $($prims)*

        /// Per-lane constants of one other axis.
        struct Axis {
            g0: V,
            gd: V,
            inv: V,
            /// ±1 per lane (0 where the ray does not move along the axis).
            step: V,
            /// max(step, 0): offset from a voxel index to the plane crossed next.
            ahead: V,
        }

        /// Per-lane constants of a packet of rays.
        struct Packet {
            g0m: V,
            invm: V,
            t_in: V,
            t_out: V,
            ax1: Axis,
            ax2: Axis,
        }

        /// Grid constants of one other axis.
        struct Other {
            last: V,
            stride: V,
        }

        #[target_feature(enable = $features)]
        fn lanes(rays: &[Option<GridRay>], f: impl Fn(&GridRay) -> f64) -> V {
            load(std::array::from_fn(|l| rays.get(l).and_then(Option::as_ref).map_or(0.0, &f)))
        }

        #[target_feature(enable = $features)]
        fn axis(rays: &[Option<GridRay>], a: usize) -> Axis {
            let step = lanes(rays, |r| {
                if r.gd[a] > 0.0 {
                    1.0
                } else if r.gd[a] < 0.0 {
                    -1.0
                } else {
                    0.0
                }
            });
            Axis {
                g0: lanes(rays, |r| r.g0[a]),
                gd: lanes(rays, |r| r.gd[a]),
                // Lanes that do not move along the axis never use their crossing parameter
                // (it is selected away), so any finite value will do.
                inv: lanes(rays, |r| if r.gd[a] != 0.0 { r.inv[a] } else { 0.0 }),
                step,
                ahead: max(step, zero()),
            }
        }

        /// Voxel index along an axis at parameter `t`, clamped into the grid.
        #[inline]
        #[target_feature(enable = $features)]
        fn index_at(ax: &Axis, o: &Other, t: V) -> V {
            min(max(floor(fmadd(t, ax.gd, ax.g0)), zero()), o.last)
        }

        /// For one other axis in one layer, from the index `a` at the entry: the index at
        /// the exit, the parameter where the index changes (`t_b` if it does not) and the
        /// change of linear index.
        #[inline]
        #[target_feature(enable = $features)]
        fn cross(ax: &Axis, o: &Other, a: V, t_a: V, t_b: V) -> (V, V, V) {
            let b = index_at(ax, o, t_b);
            let moved = min(max(mul(sub(b, a), ax.step), zero()), splat(1.0));
            let t_c = mul(sub(add(a, ax.ahead), ax.g0), ax.inv);
            let t_c = min(max(t_c, t_a), t_b);
            (b, select(gt(moved, zero()), t_c, t_b), mul(mul(moved, ax.step), o.stride))
        }

        /// Where a packet stands at a layer's entry plane: the (clamped) parameter and the
        /// other axes' voxel indices there.
        #[derive(Clone, Copy)]
        struct Entry {
            t: V,
            a1: V,
            a2: V,
        }

        #[inline]
        #[target_feature(enable = $features)]
        fn entry(p: &Packet, o1: &Other, o2: &Other, plane: V) -> Entry {
            let t = min(max(mul(sub(plane, p.g0m), p.invm), p.t_in), p.t_out);
            Entry { t, a1: index_at(&p.ax1, o1, t), a2: index_at(&p.ax2, o2, t) }
        }

        /// Adds one packet's contribution from the voxel layer entered at `e` and left at
        /// plane `p_b` (`base_m`: the layer's part of the linear voxel index) to `sums`; `e`
        /// becomes the next layer's entry (the same values a fresh [`entry`] would compute).
        /// `PACKED`: `field` is a packed composition and `sums` the packet's composition
        /// state ([`add_material`]); otherwise `field` is mu and `sums[0]` the line integral.
        #[inline]
        #[target_feature(enable = $features)]
        #[allow(clippy::too_many_arguments)]
        fn layer<const PACKED: bool>(
            field: &[f32],
            p: &Packet,
            o1: &Other,
            o2: &Other,
            e: &mut Entry,
            p_b: V,
            base_m: V,
            sums: &mut [V],
        ) {
            let t_a = e.t;
            let t_b = min(max(mul(sub(p_b, p.g0m), p.invm), p.t_in), p.t_out);
            let (b1, c1, d1) = cross(&p.ax1, o1, e.a1, t_a, t_b);
            let (b2, c2, d2) = cross(&p.ax2, o2, e.a2, t_a, t_b);
            let base = fmadd(e.a1, o1.stride, fmadd(e.a2, o2.stride, base_m));
            *e = Entry { t: t_b, a1: b1, a2: b2 };
            if none(or(ne(d1, zero()), ne(d2, zero()))) {
                // No lane leaves its voxel inside this layer: one segment per lane.
                let len = sub(t_b, t_a);
                if PACKED {
                    let (rho, label) = gather_packed(field, base);
                    add_material(sums, label, mul(rho, len));
                } else {
                    sums[0] = add(sums[0], mul(gather(field, base), len));
                }
                return;
            }
            let (ca, cb) = (min(c1, c2), max(c1, c2));
            let va = add(base, select(le(c1, c2), d1, d2));
            let vb = add(base, add(d1, d2));
            let (l0, l1, l2) = (sub(ca, t_a), sub(cb, ca), sub(t_b, cb));
            if PACKED {
                let (r0, m0) = gather_packed(field, base);
                let (r1, m1) = gather_packed(field, va);
                let (r2, m2) = gather_packed(field, vb);
                let (w0, w1, w2) = (mul(r0, l0), mul(r1, l1), mul(r2, l2));
                if all(and(eq(m0, m1), eq(m1, m2))) {
                    // Each lane stays in one material over the layer (the usual case).
                    add_material(sums, m0, add(add(w0, w1), w2));
                } else {
                    add_material(sums, m0, w0);
                    add_material(sums, m1, w1);
                    add_material(sums, m2, w2);
                }
            } else {
                let v = mul(gather(field, base), l0);
                let v = fmadd(gather(field, va), l1, v);
                sums[0] = add(sums[0], fmadd(gather(field, vb), l2, v));
            }
        }

        /// Adds ρ·ℓ `w` of material `label` (per lane) to a packet's composition state
        /// `[current material, its running sum, sum of material 0, 1, …]`: while a lane
        /// stays in one material its contributions go to the running sum; when it changes
        /// material the running sum is moved to the old material's sum. So the cost per
        /// segment does not grow with the number of materials, only per change.
        #[inline]
        #[target_feature(enable = $features)]
        fn add_material(state: &mut [V], label: V, w: V) {
            let (cur, run) = (state[0], state[1]);
            let change = ne(label, cur);
            if none(change) {
                state[1] = add(run, w);
                return;
            }
            for (m, s) in state[2..].iter_mut().enumerate() {
                *s = add_where(and(change, eq(cur, splat(m as f64))), *s, run);
            }
            state[1] = select(change, w, add(run, w));
            state[0] = select(change, label, cur);
        }

        /// Moves the running sums of a packet's composition state to their materials.
        #[inline]
        #[target_feature(enable = $features)]
        fn flush_materials(state: &mut [V]) {
            let (cur, run) = (state[0], state[1]);
            for (m, s) in state[2..].iter_mut().enumerate() {
                *s = add_where(eq(cur, splat(m as f64)), *s, run);
            }
            state[1] = zero();
        }

        /// Traces a row: `k` sums per ray into `out[n·k..(n+1)·k]` (see [`layer`]).
        #[target_feature(enable = $features)]
        pub(super) fn trace_row<const PACKED: bool>(
            field: &[f32],
            dims: [usize; 3],
            rays: &[Option<GridRay>],
            min_crossings: f64,
            k: usize,
            out: &mut [f64],
            handled: &mut [bool],
        ) {
            let strides = [1usize, dims[0], dims[0] * dims[1]];
            let span = |s: usize| s..(s + LANES).min(rays.len());
            // Packets of neighbouring rays, grouped by shared dominant axis and direction.
            let chunks: Vec<(usize, Option<(usize, bool)>)> = rays
                .chunks(LANES)
                .enumerate()
                .map(|(i, c)| (i * LANES, packet_key(c, min_crossings)))
                .collect();
            for m in 0..3 {
                for positive in [true, false] {
                    let members: Vec<usize> = chunks
                        .iter()
                        .filter(|(_, k)| *k == Some((m, positive)))
                        .map(|(start, _)| *start)
                        .collect();
                    if members.is_empty() {
                        continue;
                    }
                    let (o1, o2) = ((m + 1) % 3, (m + 2) % 3);
                    let other = |a: usize| Other {
                        last: splat((dims[a] - 1) as f64),
                        stride: splat(strides[a] as f64),
                    };
                    let (oth1, oth2) = (other(o1), other(o2));
                    let packets: Vec<Packet> = members
                        .iter()
                        .map(|&s| {
                            let r = &rays[span(s)];
                            Packet {
                                g0m: lanes(r, |g| g.g0[m]),
                                invm: lanes(r, |g| g.inv[m]),
                                t_in: lanes(r, |g| g.t_enter),
                                t_out: lanes(r, |g| g.t_exit),
                                ax1: axis(r, o1),
                                ax2: axis(r, o2),
                            }
                        })
                        .collect();
                    // Voxel layers along m that any ray of the group touches.
                    let n_m = dims[m] as i64;
                    let (mut lo, mut hi) = (n_m, -1i64);
                    for &s in &members {
                        for r in rays[span(s)].iter().flatten() {
                            for t in [r.t_enter, r.t_exit] {
                                let l = ((r.g0[m] + t * r.gd[m]).floor() as i64).clamp(0, n_m - 1);
                                lo = lo.min(l);
                                hi = hi.max(l);
                            }
                        }
                    }
                    let (first, last, dir) = if positive { (lo, hi, 1i64) } else { (hi, lo, -1i64) };
                    let entry_plane = |j: i64| (if positive { j } else { j + 1 }) as f64;
                    // Per packet: the line integral, or the composition state of `add_material`
                    // (current material — none yet —, running sum, k material sums).
                    let slot = if PACKED { k + 2 } else { 1 };
                    let mut sums = vec![zero(); packets.len() * slot];
                    if PACKED {
                        sums.chunks_mut(slot).for_each(|s| s[0] = splat(-1.0));
                    }
                    let start = splat(entry_plane(first));
                    let mut entries: Vec<Entry> =
                        packets.iter().map(|p| entry(p, &oth1, &oth2, start)).collect();
                    let mut j = first;
                    loop {
                        let p_b = splat(entry_plane(j + dir));
                        let base_m = splat((j as usize * strides[m]) as f64);
                        for ((p, sum), e) in packets.iter().zip(sums.chunks_mut(slot)).zip(entries.iter_mut()) {
                            layer::<PACKED>(field, p, &oth1, &oth2, e, p_b, base_m, sum);
                        }
                        if j == last {
                            break;
                        }
                        j += dir;
                    }
                    for (&s, sum) in members.iter().zip(sums.chunks_mut(slot)) {
                        let sum = if PACKED {
                            flush_materials(sum);
                            &sum[2..]
                        } else {
                            &sum[..]
                        };
                        for (m, sum) in sum.iter().enumerate() {
                            let v = store(*sum);
                            for n in span(s) {
                                out[n * k + m] = if rays[n].is_some() { v[n - s] } else { 0.0 };
                            }
                        }
                        for n in span(s) {
                            handled[n] = true;
                        }
                    }
                }
            }
            // Packets whose rays all miss: nothing to add.
            for (start, key) in &chunks {
                if key.is_none() && rays[span(*start)].iter().all(Option::is_none) {
                    for n in span(*start) {
                        out[n * k..(n + 1) * k].fill(0.0);
                        handled[n] = true;
                    }
                }
            }
        }
    };
}

/// Four lanes of f64 (AVX2 + FMA).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    packet_kernel!("avx2,fma", 4, __m256d, __m256d, {
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn splat(x: f64) -> V {
            _mm256_set1_pd(x)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn zero() -> V {
            _mm256_setzero_pd()
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn min(a: V, b: V) -> V {
            _mm256_min_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn max(a: V, b: V) -> V {
            _mm256_max_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn add(a: V, b: V) -> V {
            _mm256_add_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn sub(a: V, b: V) -> V {
            _mm256_sub_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn mul(a: V, b: V) -> V {
            _mm256_mul_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn fmadd(a: V, b: V, c: V) -> V {
            _mm256_fmadd_pd(a, b, c)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn floor(a: V) -> V {
            _mm256_floor_pd(a)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn gt(a: V, b: V) -> M {
            _mm256_cmp_pd::<_CMP_GT_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn le(a: V, b: V) -> M {
            _mm256_cmp_pd::<_CMP_LE_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn ne(a: V, b: V) -> M {
            _mm256_cmp_pd::<_CMP_NEQ_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn eq(a: V, b: V) -> M {
            _mm256_cmp_pd::<_CMP_EQ_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn add_where(m: M, s: V, w: V) -> V {
            _mm256_add_pd(s, _mm256_and_pd(m, w))
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn and(a: M, b: M) -> M {
            _mm256_and_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn all(m: M) -> bool {
            _mm256_movemask_pd(m) == 0xF
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn or(a: M, b: M) -> M {
            _mm256_or_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn none(m: M) -> bool {
            _mm256_movemask_pd(m) == 0
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn select(m: M, a: V, b: V) -> V {
            _mm256_blendv_pd(b, a, m)
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn load(v: [f64; LANES]) -> V {
            _mm256_setr_pd(v[0], v[1], v[2], v[3])
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn store(a: V) -> [f64; LANES] {
            let mut v = [0.0; LANES];
            // SAFETY: LANES f64 into a local array of that size.
            unsafe { _mm256_storeu_pd(v.as_mut_ptr(), a) };
            v
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn gather(mu: &[f32], index: V) -> V {
            // SAFETY: every index is a sum of clamped in-grid voxel indices times strides,
            // so below mu.len() < 2³¹ (checked by `trace_row`).
            unsafe {
                _mm256_cvtps_pd(_mm_i32gather_ps::<4>(
                    mu.as_ptr(),
                    _mm256_cvtpd_epi32(index),
                ))
            }
        }
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        fn gather_packed(field: &[f32], index: V) -> (V, V) {
            // SAFETY: as for `gather`.
            let g = unsafe {
                _mm_i32gather_epi32::<4>(field.as_ptr().cast(), _mm256_cvtpd_epi32(index))
            };
            let mask = _mm_set1_epi32(LABEL_MASK);
            let rho = _mm_castsi128_ps(_mm_andnot_si128(mask, g));
            (
                _mm256_cvtps_pd(rho),
                _mm256_cvtepi32_pd(_mm_and_si128(mask, g)),
            )
        }
    });
}

/// Eight lanes of f64 (AVX-512F; its masks are bit masks).
#[cfg(target_arch = "x86_64")]
mod avx512 {
    packet_kernel!("avx512f,avx2,fma", 8, __m512d, __mmask8, {
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn splat(x: f64) -> V {
            _mm512_set1_pd(x)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn zero() -> V {
            _mm512_setzero_pd()
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn min(a: V, b: V) -> V {
            _mm512_min_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn max(a: V, b: V) -> V {
            _mm512_max_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn add(a: V, b: V) -> V {
            _mm512_add_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn sub(a: V, b: V) -> V {
            _mm512_sub_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn mul(a: V, b: V) -> V {
            _mm512_mul_pd(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn fmadd(a: V, b: V, c: V) -> V {
            _mm512_fmadd_pd(a, b, c)
        }
        // Round towards −∞, exceptions suppressed.
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn floor(a: V) -> V {
            _mm512_roundscale_pd::<0x09>(a)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn gt(a: V, b: V) -> M {
            _mm512_cmp_pd_mask::<_CMP_GT_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn le(a: V, b: V) -> M {
            _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn ne(a: V, b: V) -> M {
            _mm512_cmp_pd_mask::<_CMP_NEQ_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn eq(a: V, b: V) -> M {
            _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a, b)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn add_where(m: M, s: V, w: V) -> V {
            _mm512_mask_add_pd(s, m, s, w)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn and(a: M, b: M) -> M {
            a & b
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn all(m: M) -> bool {
            m == 0xFF
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn or(a: M, b: M) -> M {
            a | b
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn none(m: M) -> bool {
            m == 0
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn select(m: M, a: V, b: V) -> V {
            _mm512_mask_blend_pd(m, b, a)
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn load(v: [f64; LANES]) -> V {
            // SAFETY: LANES f64 from a local array of that size.
            unsafe { _mm512_loadu_pd(v.as_ptr()) }
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn store(a: V) -> [f64; LANES] {
            let mut v = [0.0; LANES];
            // SAFETY: LANES f64 into a local array of that size.
            unsafe { _mm512_storeu_pd(v.as_mut_ptr(), a) };
            v
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn gather(mu: &[f32], index: V) -> V {
            // SAFETY: as for AVX2: every index is inside `mu`.
            unsafe {
                _mm512_cvtps_pd(_mm256_i32gather_ps::<4>(
                    mu.as_ptr(),
                    _mm512_cvtpd_epi32(index),
                ))
            }
        }
        #[inline]
        #[target_feature(enable = "avx512f,avx2,fma")]
        fn gather_packed(field: &[f32], index: V) -> (V, V) {
            // SAFETY: as for `gather`.
            let g = unsafe {
                _mm256_i32gather_epi32::<4>(field.as_ptr().cast(), _mm512_cvtpd_epi32(index))
            };
            let mask = _mm256_set1_epi32(LABEL_MASK);
            let rho = _mm256_castsi256_ps(_mm256_andnot_si256(mask, g));
            (
                _mm512_cvtps_pd(rho),
                _mm512_cvtepi32_pd(_mm256_and_si256(mask, g)),
            )
        }
    });
}
