//! The kernel body shared by every instruction set (`packet_kernel!`).

/// The kernel body, instantiated per instruction set. The caller supplies the set's lanes
/// (`avx2_lanes!()` or `avx512_lanes!()`, `super::super::lanes`: the types `V` and `M`,
/// `LANES`, the arithmetic, masks and voxel reads) and `prefetch` (bring the cache lines of
/// some lanes' voxels towards L1, through [`prefetch_at`]), all `#[inline]` with the set's
/// target `$features`.
#[cfg(target_arch = "x86_64")]
macro_rules! packet_kernel {
    ($features:literal, { $($prims:item)* }) => {
        use super::packet_key;
        use crate::ray::GridRay;
        #[allow(unused_imports)]
        use std::arch::x86_64::*;

        /// Voxel layers ahead of the one being traced whose voxels a packet prefetches:
        /// consecutive layers lie a row or a slice apart in memory, a stride the hardware
        /// prefetchers do not follow for gathers (docs/projector.md, "Against the ≤ 19 ms target").
        const PREFETCH_LAYERS: i64 = 4;

        /// Hints that `field[index]` will be read soon. The callers' indices lie inside
        /// `field` (indices clamped into the grid); a prefetch never faults in any case,
        /// so the address is not checked.
        #[inline]
        fn prefetch_at(field: &[f32], index: i32) {
            let p = field.as_ptr().wrapping_offset(index as isize);
            // SAFETY: a prefetch reads nothing architecturally and never faults.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.cast()) };
        }

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
            /// (ahead − g0)·inv, so that the plane after voxel `a` is crossed at
            /// `a·inv + next` (+∞ where the ray does not move along the axis).
            next: V,
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
                // in `cross` (it is selected away), so any finite value will do there; their
                // next crossing is at +∞.
                inv: lanes(rays, |r| if r.gd[a] != 0.0 { r.inv[a] } else { 0.0 }),
                step,
                ahead: max(step, zero()),
                next: lanes(rays, |r| {
                    if r.gd[a] != 0.0 {
                        (f64::from(r.gd[a] > 0.0) - r.g0[a]) * r.inv[a]
                    } else {
                        f64::INFINITY
                    }
                }),
            }
        }

        /// Voxel index along an axis at parameter `t`, clamped into the grid.
        #[inline]
        #[target_feature(enable = $features)]
        fn index_at(ax: &Axis, o: &Other, t: V) -> V {
            min(max(floor(fmadd(t, ax.gd, ax.g0)), zero()), o.last)
        }

        /// For one other axis in a layer where some lane changes voxel, from the indices
        /// `a` at the entry and `b` at the exit: the parameter where the index changes
        /// (`t_b` if it does not) and the change of linear index.
        #[inline]
        #[target_feature(enable = $features)]
        fn cross(ax: &Axis, o: &Other, a: V, b: V, t_a: V, t_b: V) -> (V, V) {
            // Indices are whole numbers: the lane moved iff (b − a)·step ≥ 1, and then by
            // one step (at most one plane per layer).
            let moved = gt(mul(sub(b, a), ax.step), zero());
            let t_c = mul(sub(add(a, ax.ahead), ax.g0), ax.inv);
            let t_c = min(max(t_c, t_a), t_b);
            (select(moved, t_c, t_b), select(moved, mul(ax.step, o.stride), zero()))
        }

        /// Where a packet stands at a layer's entry plane: the (clamped) parameter, the
        /// other axes' voxel indices there, their part of the linear voxel index, and the
        /// parameter where the ray crosses the next other-axis plane. That parameter only
        /// chooses the code path of a layer (one segment, or the indices at the layer's
        /// exit decide); should rounding put it a hair after a crossing that ends a layer,
        /// a sliver of that size goes to the voxel before the plane, as elsewhere.
        #[derive(Clone, Copy)]
        struct Entry {
            t: V,
            a1: V,
            a2: V,
            offset: V,
            t_next: V,
        }

        #[inline]
        #[target_feature(enable = $features)]
        fn entry_at(p: &Packet, o1: &Other, o2: &Other, t: V, a1: V, a2: V) -> Entry {
            Entry {
                t,
                a1,
                a2,
                offset: fmadd(a1, o1.stride, mul(a2, o2.stride)),
                t_next: min(fmadd(a1, p.ax1.inv, p.ax1.next), fmadd(a2, p.ax2.inv, p.ax2.next)),
            }
        }

        #[inline]
        #[target_feature(enable = $features)]
        fn entry(p: &Packet, o1: &Other, o2: &Other, plane: V) -> Entry {
            let t = min(max(mul(sub(plane, p.g0m), p.invm), p.t_in), p.t_out);
            entry_at(p, o1, o2, t, index_at(&p.ax1, o1, t), index_at(&p.ax2, o2, t))
        }

        /// Adds one packet's contribution from the voxel layer entered at `e` and left at
        /// plane `p_b` (`base_m`: the layer's part of the linear voxel index) to `sums`; `e`
        /// becomes the next layer's entry (the same values a fresh [`entry`] would compute).
        /// `PACKED`: `field` is a packed composition and `sums` the packet's composition
        /// state ([`add_material`]); otherwise `field` is mu and `sums[0]` the line integral.
        #[inline]
        #[target_feature(enable = $features)]
        #[allow(clippy::too_many_arguments)]
        fn layer<const PACKED: bool, const LOADS: bool>(
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
            let base = add(e.offset, base_m);
            if none(and(gt(t_b, e.t_next), gt(t_b, t_a))) {
                // No lane reaches another-axis plane inside this layer: one segment per
                // lane, in the voxel it entered.
                e.t = t_b;
                let len = sub(t_b, t_a);
                // SAFETY (here and below): every index is a sum of clamped in-grid voxel
                // indices times strides, so below field.len() < 2³¹ (checked by `trace_row`).
                if PACKED {
                    let (rho, label) = unpack(unsafe { gather_raw::<false>(field, base) });
                    add_material(sums, label, mul(rho, len));
                } else {
                    let mu = unsafe { gather::<LOADS>(field, base) };
                    sums[0] = add(sums[0], mul(mu, len));
                }
                return;
            }
            // Some lane may change voxel: the indices at the exit decide (an index moving
            // against the ray's direction, which only rounding could cause, counts as no
            // change).
            let (a1, a2) = (e.a1, e.a2);
            let (b1, b2) = (index_at(&p.ax1, o1, t_b), index_at(&p.ax2, o2, t_b));
            *e = entry_at(p, o1, o2, t_b, b1, b2);
            let (c1, d1) = cross(&p.ax1, o1, a1, b1, t_a, t_b);
            let (c2, d2) = cross(&p.ax2, o2, a2, b2, t_a, t_b);
            let (ca, cb) = (min(c1, c2), max(c1, c2));
            let va = add(base, select(le(c1, c2), d1, d2));
            let vb = add(base, add(d1, d2));
            let (l0, l1, l2) = (sub(ca, t_a), sub(cb, ca), sub(t_b, cb));
            if PACKED {
                // SAFETY: as above, for the voxels entered at the layer's crossings too.
                let ((r0, m0), (r1, m1), (r2, m2)) = unsafe {
                    (
                        unpack(gather_raw::<false>(field, base)),
                        unpack(gather_raw::<false>(field, va)),
                        unpack(gather_raw::<false>(field, vb)),
                    )
                };
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
                // SAFETY: as above, for the voxels entered at the layer's crossings too.
                let (mu0, mu1, mu2) = unsafe {
                    (
                        gather::<LOADS>(field, base),
                        gather::<LOADS>(field, va),
                        gather::<LOADS>(field, vb),
                    )
                };
                let v = mul(mu0, l0);
                let v = fmadd(mu1, l1, v);
                sums[0] = add(sums[0], fmadd(mu2, l2, v));
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
        pub(super) fn trace_row<const PACKED: bool, const LOADS: bool>(
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
                        let ahead = (j + PREFETCH_LAYERS * dir).clamp(0, n_m - 1);
                        let base_ahead = splat((ahead as usize * strides[m]) as f64);
                        for ((p, sum), e) in packets.iter().zip(sums.chunks_mut(slot)).zip(entries.iter_mut()) {
                            // The voxels this packet meets PREFETCH_LAYERS layers on, if it
                            // crosses no other-axis plane until then.
                            prefetch(field, add(e.offset, base_ahead));
                            layer::<PACKED, LOADS>(field, p, &oth1, &oth2, e, p_b, base_m, sum);
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
