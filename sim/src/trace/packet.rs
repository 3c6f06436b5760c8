//! Exact line integrals of a whole detector row at once (AVX2, four rays per vector).
//!
//! The same path as [`super::siddon`], organised for SIMD and for the cache. Rays that
//! share a dominant axis `m` and its direction are grouped four to a vector ("packet"),
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
//! Used by [`crate::render::Renderer`] when the CPU has AVX2 and FMA and the grid has
//! fewer than 2³¹ voxels; packets whose rays disagree on the dominant axis are left to the
//! scalar tracer.

use crate::ray::GridRay;

/// Whether this CPU can run the packet tracer.
pub fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Traces the rays of one row (`None`: the ray misses the grid). For each ray handled,
/// writes ∫mu ds to `out` and sets `handled`; rays left unhandled (their packet mixes
/// dominant axes or crosses fewer than `min_crossings` other-axis planes per layer, or the
/// CPU lacks AVX2/FMA, or the grid has ≥ 2³¹ voxels) are for the scalar tracer. `mu` is
/// indexed `i + nx·(j + ny·k)`.
pub fn trace_row(
    mu: &[f32],
    dims: [usize; 3],
    rays: &[Option<GridRay>],
    min_crossings: f64,
    out: &mut [f64],
    handled: &mut [bool],
) {
    handled.fill(false);
    if mu.len() >= (1 << 31) || !available() {
        return;
    }
    #[cfg(target_arch = "x86_64")]
    // SAFETY: AVX2 and FMA were detected above.
    unsafe {
        avx2::trace_row(mu, dims, rays, min_crossings, out, handled)
    }
}

/// ∫mu ds for four rays, or `None` when they cannot share a packet or the CPU lacks
/// AVX2/FMA. A convenience over [`trace_row`] for tests.
pub fn line_integrals4(
    mu: &[f32],
    dims: [usize; 3],
    rays: &[Option<GridRay>; 4],
) -> Option<[f64; 4]> {
    let mut out = [0.0; 4];
    let mut handled = [false; 4];
    trace_row(mu, dims, rays, 0.0, &mut out, &mut handled);
    handled.iter().all(|&h| h).then_some(out)
}

/// Plane crossings of the other two axes per voxel layer below which the renderer leaves
/// a packet to the scalar tracer: that one reports runs of whole layers at a fraction of
/// the packet's cost per layer, which wins while crossings are sparse (near-axial views).
/// Chosen by timing thresholds 0–0.7 on the chest-sized case with
/// `TG_PACKET_THRESHOLD=x cargo run --release -p tomograf-sim --example profile_ap θ`.
pub const MIN_CROSSINGS_PER_LAYER: f64 = 0.3;

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
mod avx2 {
    use super::packet_key;
    use crate::ray::GridRay;
    use std::arch::x86_64::*;

    /// Per-lane constants of one other axis.
    struct Axis {
        g0: __m256d,
        gd: __m256d,
        inv: __m256d,
        /// ±1 per lane (0 where the ray does not move along the axis).
        step: __m256d,
        /// max(step, 0): offset from a voxel index to the plane crossed next.
        ahead: __m256d,
    }

    /// Per-lane constants of a packet of four rays.
    struct Packet {
        g0m: __m256d,
        invm: __m256d,
        t_in: __m256d,
        t_out: __m256d,
        ax1: Axis,
        ax2: Axis,
    }

    /// Grid constants of the two other axes.
    struct Other {
        last: __m256d,
        stride: __m256d,
    }

    #[target_feature(enable = "avx2,fma")]
    fn lanes(rays: &[Option<GridRay>], f: impl Fn(&GridRay) -> f64) -> __m256d {
        let v: [f64; 4] =
            std::array::from_fn(|l| rays.get(l).and_then(Option::as_ref).map_or(0.0, &f));
        _mm256_setr_pd(v[0], v[1], v[2], v[3])
    }

    #[target_feature(enable = "avx2,fma")]
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
            // (it is blended away), so any finite value will do.
            inv: lanes(rays, |r| if r.gd[a] != 0.0 { r.inv[a] } else { 0.0 }),
            step,
            ahead: _mm256_max_pd(step, _mm256_setzero_pd()),
        }
    }

    /// Voxel index along an axis at parameter `t`, clamped into the grid.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn index_at(ax: &Axis, o: &Other, t: __m256d) -> __m256d {
        let p = _mm256_floor_pd(_mm256_fmadd_pd(t, ax.gd, ax.g0));
        _mm256_min_pd(_mm256_max_pd(p, _mm256_setzero_pd()), o.last)
    }

    /// For one other axis in one layer, from the index `a` at the entry: the parameter
    /// where the index changes (`t_b` if it does not) and the change of linear voxel index.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn cross(ax: &Axis, o: &Other, a: __m256d, t_a: __m256d, t_b: __m256d) -> (__m256d, __m256d) {
        let zero = _mm256_setzero_pd();
        let b = index_at(ax, o, t_b);
        let moved = _mm256_min_pd(
            _mm256_max_pd(_mm256_mul_pd(_mm256_sub_pd(b, a), ax.step), zero),
            _mm256_set1_pd(1.0),
        );
        let t_c = _mm256_mul_pd(_mm256_sub_pd(_mm256_add_pd(a, ax.ahead), ax.g0), ax.inv);
        let t_c = _mm256_min_pd(_mm256_max_pd(t_c, t_a), t_b);
        let t_c = _mm256_blendv_pd(t_b, t_c, _mm256_cmp_pd::<_CMP_GT_OQ>(moved, zero));
        (t_c, _mm256_mul_pd(_mm256_mul_pd(moved, ax.step), o.stride))
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn gather(mu: &[f32], index: __m256d) -> __m256d {
        let idx = _mm256_cvtpd_epi32(index);
        // SAFETY: every index is j·stride_m + a1·stride_1 + a2·stride_2 (+ one step of an
        // axis that stays in the grid) with each index clamped into the grid, so it is
        // below mu.len() < 2³¹.
        unsafe { _mm256_cvtps_pd(_mm_i32gather_ps::<4>(mu.as_ptr(), idx)) }
    }

    /// One packet's contribution from voxel layer `j` (entry plane `p_a`, exit `p_b`).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn layer(
        mu: &[f32],
        p: &Packet,
        o1: &Other,
        o2: &Other,
        p_a: __m256d,
        p_b: __m256d,
        base_m: __m256d,
    ) -> __m256d {
        let clamp_t = |t: __m256d| _mm256_min_pd(_mm256_max_pd(t, p.t_in), p.t_out);
        let t_a = clamp_t(_mm256_mul_pd(_mm256_sub_pd(p_a, p.g0m), p.invm));
        let t_b = clamp_t(_mm256_mul_pd(_mm256_sub_pd(p_b, p.g0m), p.invm));
        let a1 = index_at(&p.ax1, o1, t_a);
        let a2 = index_at(&p.ax2, o2, t_a);
        let (c1, d1) = cross(&p.ax1, o1, a1, t_a, t_b);
        let (c2, d2) = cross(&p.ax2, o2, a2, t_a, t_b);
        let base = _mm256_fmadd_pd(a1, o1.stride, _mm256_fmadd_pd(a2, o2.stride, base_m));
        let zero = _mm256_setzero_pd();
        let moved = _mm256_or_pd(
            _mm256_cmp_pd::<_CMP_NEQ_OQ>(d1, zero),
            _mm256_cmp_pd::<_CMP_NEQ_OQ>(d2, zero),
        );
        if _mm256_movemask_pd(moved) == 0 {
            // No lane leaves its voxel inside this layer: one segment per lane.
            return _mm256_mul_pd(gather(mu, base), _mm256_sub_pd(t_b, t_a));
        }
        let (ca, cb) = (_mm256_min_pd(c1, c2), _mm256_max_pd(c1, c2));
        let va = _mm256_add_pd(
            base,
            _mm256_blendv_pd(d2, d1, _mm256_cmp_pd::<_CMP_LE_OQ>(c1, c2)),
        );
        let vb = _mm256_add_pd(base, _mm256_add_pd(d1, d2));
        let s = _mm256_mul_pd(gather(mu, base), _mm256_sub_pd(ca, t_a));
        let s = _mm256_fmadd_pd(gather(mu, va), _mm256_sub_pd(cb, ca), s);
        _mm256_fmadd_pd(gather(mu, vb), _mm256_sub_pd(t_b, cb), s)
    }

    #[target_feature(enable = "avx2,fma")]
    pub(super) fn trace_row(
        mu: &[f32],
        dims: [usize; 3],
        rays: &[Option<GridRay>],
        min_crossings: f64,
        out: &mut [f64],
        handled: &mut [bool],
    ) {
        let strides = [1usize, dims[0], dims[0] * dims[1]];
        // Packets of four neighbouring rays, grouped by shared dominant axis and direction.
        let chunks: Vec<(usize, Option<(usize, bool)>)> = rays
            .chunks(4)
            .enumerate()
            .map(|(i, c)| (i * 4, packet_key(c, min_crossings)))
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
                    last: _mm256_set1_pd((dims[a] - 1) as f64),
                    stride: _mm256_set1_pd(strides[a] as f64),
                };
                let (oth1, oth2) = (other(o1), other(o2));
                let packets: Vec<Packet> = members
                    .iter()
                    .map(|&s| {
                        let r = &rays[s..(s + 4).min(rays.len())];
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
                    for r in rays[s..(s + 4).min(rays.len())].iter().flatten() {
                        for t in [r.t_enter, r.t_exit] {
                            let l = ((r.g0[m] + t * r.gd[m]).floor() as i64).clamp(0, n_m - 1);
                            lo = lo.min(l);
                            hi = hi.max(l);
                        }
                    }
                }
                let (first, last, dir) = if positive {
                    (lo, hi, 1i64)
                } else {
                    (hi, lo, -1i64)
                };
                let entry_plane = |j: i64| (if positive { j } else { j + 1 }) as f64;
                let mut sums = vec![_mm256_setzero_pd(); packets.len()];
                let mut j = first;
                loop {
                    let p_a = _mm256_set1_pd(entry_plane(j));
                    let p_b = _mm256_set1_pd(entry_plane(j + dir));
                    let base_m = _mm256_set1_pd((j as usize * strides[m]) as f64);
                    for (p, sum) in packets.iter().zip(sums.iter_mut()) {
                        *sum = _mm256_add_pd(*sum, layer(mu, p, &oth1, &oth2, p_a, p_b, base_m));
                    }
                    if j == last {
                        break;
                    }
                    j += dir;
                }
                for (&s, sum) in members.iter().zip(&sums) {
                    let mut v = [0.0f64; 4];
                    // SAFETY: writing four f64 into a local array.
                    unsafe { _mm256_storeu_pd(v.as_mut_ptr(), *sum) };
                    for l in 0..(rays.len() - s).min(4) {
                        out[s + l] = if rays[s + l].is_some() { v[l] } else { 0.0 };
                        handled[s + l] = true;
                    }
                }
            }
        }
        // Packets whose rays all miss: nothing to add.
        for (start, key) in &chunks {
            if key.is_none()
                && rays[*start..(*start + 4).min(rays.len())]
                    .iter()
                    .all(Option::is_none)
            {
                for l in *start..(*start + 4).min(rays.len()) {
                    out[l] = 0.0;
                    handled[l] = true;
                }
            }
        }
    }
}
