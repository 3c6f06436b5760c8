//! The ray-sheet tracer (whole detector rows whose rays share one path in the plane of two
//! grid axes) against the brute-force reference, and the renderer with and without it.
//! Tolerance 1e-9 relative, as for the other exact tracers: the sheet replaces each ray's
//! own line in that plane by the sheet's, which it accepts only within 1e-10 voxels.

mod common;

use common::*;
use glam::DVec3;
use tomograf_sim::trace::{packet, sheet::Sheet};
use tomograf_sim::{
    Beam, Detector, Geometry, GridRay, Pose, Projector, Ray, Renderer, Volume, grid_box::GridBox,
};

/// The rays of row `row` of `view`, clipped to the whole grid.
fn row_rays(
    vol: &Volume,
    view: &tomograf_sim::View,
    row: usize,
) -> (Vec<Ray>, Vec<Option<GridRay>>) {
    let world: Vec<Ray> = (0..view.cols)
        .map(|c| view.ray(row as f64, c as f64))
        .collect();
    let clipped = world.iter().map(|w| GridRay::clip(vol, w)).collect();
    (world, clipped)
}

fn check_row(vol: &Volume, world: &[Ray], sheet: &Sheet) {
    let dims = vol.dims();
    let mut out = vec![f64::NAN; world.len()];
    sheet.line_integrals(vol.data(), dims, &GridBox::whole(dims), &mut out);
    // Every SIMD kernel the CPU has and the portable one give the same bits.
    let mut portable = vec![f64::NAN; world.len()];
    sheet.line_integrals_with(None, vol.data(), dims, &GridBox::whole(dims), &mut portable);
    for kernel in packet::supported() {
        let mut simd = vec![f64::NAN; world.len()];
        sheet.line_integrals_with(
            Some(kernel),
            vol.data(),
            dims,
            &GridBox::whole(dims),
            &mut simd,
        );
        for (c, (a, b)) in simd.iter().zip(&portable).enumerate() {
            assert_eq!(
                a.to_bits(),
                b.to_bits(),
                "column {c}: {kernel:?} {a} vs portable {b}"
            );
        }
    }
    for (c, w) in world.iter().enumerate() {
        let reference = brute_force(vol, w);
        assert!(
            rel_err(out[c], reference) <= 1e-9 || (out[c] - reference).abs() < 1e-13,
            "column {c}: sheet {} vs reference {reference} for {w:?}",
            out[c]
        );
    }
}

/// A cone-beam geometry whose isocentre is a little off the volume's centre. (At the
/// centre, a view's basis holds ~1e-16 where it should hold 0, so the central column of a
/// grid with an even number of voxels would run within 1e-13 voxels of a plane at a slope of
/// 1e-15. Where such a ray crosses that plane is uncertain by a voxel in any f64 tracer, so
/// no two tracers agree to 1e-9 on it; `sim/tests/packet.rs` leaves such rays out too.)
fn geometry(vol: &Volume, sad: f64, sid: f64, rows: usize, cols: usize, pitch: f64) -> Geometry {
    Geometry {
        beam: Beam::Cone {
            sad_mm: sad,
            sid_mm: sid,
        },
        detector: Detector::new(rows, cols, pitch),
        isocentre: vol.centre() + DVec3::new(0.0123, 0.0456, 0.0078),
    }
}

#[test]
fn ap_and_lateral_rows_are_sheets_and_match_reference() {
    let mut r = rng(71);
    let mut sheets = 0;
    for case in 0..4 {
        let dims = [23 + case, 19, 11 + 3 * case];
        let vol = random_volume(&mut r, dims, false);
        for (pose, axis) in [
            (Pose::AP, 0),
            (Pose::LATERAL, 1),
            (Pose::new(180.0, 0.0), 0),
        ] {
            // Pitches small and large: rays inside, across and outside the grid's sides.
            for pitch in [0.7, 2.9] {
                let view = geometry(&vol, 200.0, 320.0, 13, 31, pitch)
                    .view(pose)
                    .unwrap();
                for row in 0..view.rows {
                    let (world, clipped) = row_rays(&vol, &view, row);
                    let Some(sheet) = Sheet::new(&clipped, dims, &GridBox::whole(dims)) else {
                        assert!(clipped.iter().all(Option::is_none), "{pose:?} row {row}");
                        continue;
                    };
                    assert_eq!(sheet.axis(), axis, "{pose:?}");
                    check_row(&vol, &world, &sheet);
                    sheets += 1;
                }
            }
        }
    }
    assert!(sheets > 250, "only {sheets} rows formed sheets");
}

#[test]
fn oblique_rows_are_not_sheets() {
    // At 30° the rows' direction is along no grid axis: their rays follow different lines
    // in every plane of two axes, except the row in the source's axial plane (its rays all
    // keep one k), which is a sheet along i and must be right.
    let mut r = rng(72);
    let vol = random_volume(&mut r, [20, 21, 9], false);
    let dims = vol.dims();
    let view = geometry(&vol, 200.0, 320.0, 9, 17, 2.0)
        .view(Pose::new(30.0, 0.0))
        .unwrap();
    let mut sheets = 0;
    for row in 0..view.rows {
        let (world, clipped) = row_rays(&vol, &view, row);
        if let Some(sheet) = Sheet::new(&clipped, dims, &GridBox::whole(dims)) {
            assert_eq!(row, view.rows / 2);
            check_row(&vol, &world, &sheet);
            sheets += 1;
        }
    }
    assert!(sheets <= 1);
}

#[test]
fn degenerate_sheets_match_reference() {
    // Hand-made rows in grid coordinates: lines lying in grid planes (the voxel above
    // them counts), through voxel edges and corners, parallel to an axis (zero slopes),
    // crossing a plane of c exactly at a plane of b, starting and ending inside the grid,
    // and fanning out so that rays leave through the sides.
    let mut r = rng(73);
    let dims = [9, 12, 7];
    let vol = random_volume(&mut r, dims, false);
    let mut tested = 0;
    for (c_at, mc) in [
        (3.0, 0.0),
        (2.5, 0.0),
        (0.0, 0.5),
        (1.0, 0.25),
        (6.0, -0.5),
        (7.0, 0.0),
    ] {
        for (a_at, spread) in [
            (4.0, 0.0),
            (4.5, 0.1),
            (0.0, 0.3),
            (9.0, -0.3),
            (2.0, 1.0 / 12.0),
        ] {
            for (b_from, b_to) in [(-5.0, 17.0), (2.5, 9.0), (17.0, -5.0), (0.0, 12.0)] {
                // Rays from one point through a row of points along axis 0.
                let world: Vec<Ray> = (0..7)
                    .map(|n| {
                        let slope = spread * (n as f64 - 3.0);
                        let p =
                            |b: f64| DVec3::new(a_at + slope * (b - 6.0), b, c_at + mc * (b - 6.0));
                        Ray::segment(grid_to_world(&vol, p(b_from)), grid_to_world(&vol, p(b_to)))
                    })
                    .collect();
                let clipped: Vec<Option<GridRay>> =
                    world.iter().map(|w| GridRay::clip(&vol, w)).collect();
                if let Some(sheet) = Sheet::new(&clipped, dims, &GridBox::whole(dims)) {
                    check_row(&vol, &world, &sheet);
                    tested += 1;
                }
            }
        }
    }
    assert!(tested > 90, "only {tested} rows formed sheets");
}

#[test]
fn renderer_with_and_without_sheets_agree() {
    // Whole images over a sub-box of non-zero voxels (rays clipped to it), rows that miss.
    let mut r = rng(74);
    let mut vol = random_volume(&mut r, [40, 33, 21], false);
    let dims = vol.dims();
    let data: Vec<f32> = vol
        .data()
        .iter()
        .enumerate()
        .map(|(n, &v)| {
            let (i, j, k) = (n % dims[0], n / dims[0] % dims[1], n / (dims[0] * dims[1]));
            if (3..35).contains(&i) && (5..30).contains(&j) && (2..19).contains(&k) {
                v
            } else {
                0.0
            }
        })
        .collect();
    vol = Volume::new(dims, vol.spacing(), vol.origin(), vol.direction(), data).unwrap();
    for pose in [
        Pose::AP,
        Pose::LATERAL,
        Pose::new(270.0, 0.0),
        Pose::new(33.0, 12.0),
    ] {
        let view = geometry(&vol, 300.0, 450.0, 29, 37, 3.0)
            .view(pose)
            .unwrap();
        let render = |sheets: bool| {
            Renderer::new(&vol, Projector::Siddon)
                .unwrap()
                .with_sheets(sheets)
                .render(&view)
                .unwrap()
        };
        let (plain, sheets) = (render(false), render(true));
        assert!(plain.data.iter().any(|&v| v > 0.0) && plain.data.contains(&0.0));
        for (n, (a, b)) in plain.data.iter().zip(&sheets.data).enumerate() {
            assert!(
                (a - b).abs() <= 1e-6 * a.abs().max(1e-6),
                "{pose:?}, pixel ({}, {}): without sheets {a}, with {b}",
                n / view.cols,
                n % view.cols
            );
        }
    }
}

#[test]
fn long_sheets_of_few_rays_match_reference() {
    // Many more segments than rays (a kernel indexing rays by segment would read and write
    // past them), rows of 1 to 9 rays (partial groups of four), along each axis.
    let mut r = rng(75);
    for (dims, axis, b) in [([5, 90, 7], 0, 1), ([4, 9, 70], 1, 2), ([80, 6, 8], 2, 0)] {
        let vol = random_volume(&mut r, dims, false);
        for rays in 1..10 {
            let world: Vec<Ray> = (0..rays)
                .map(|n| {
                    let mut from = DVec3::splat(2.3);
                    let mut to = DVec3::splat(2.6);
                    from[b] = -3.0;
                    to[b] = dims[b] as f64 + 3.0;
                    to[axis] += 0.4 * n as f64;
                    Ray::segment(grid_to_world(&vol, from), grid_to_world(&vol, to))
                })
                .collect();
            let clipped: Vec<Option<GridRay>> =
                world.iter().map(|w| GridRay::clip(&vol, w)).collect();
            let sheet = Sheet::new(&clipped, dims, &GridBox::whole(dims)).expect("a sheet");
            if rays > 1 {
                assert_eq!(sheet.axis(), axis);
            }
            assert!(sheet.segments() > 60);
            check_row(&vol, &world, &sheet);
        }
    }
}

/// A volume whose values are zero outside an elliptic cylinder about k (as a CT's air below
/// −1000 HU and the scanner's field of view), with a slice of zeros and a few isolated
/// non-zero voxels in the air.
fn body_in_air(r: &mut rand_chacha::ChaCha8Rng, dims: [usize; 3]) -> Volume {
    use rand::Rng;
    let [nx, ny, nz] = dims;
    let mut data = vec![0.0f32; nx * ny * nz];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let (u, v) = (
                    (i as f64 + 0.5 - nx as f64 / 2.0) / (0.4 * nx as f64),
                    (j as f64 + 0.5 - ny as f64 / 2.0) / (0.35 * ny as f64),
                );
                let body = u * u + v * v <= 1.0 && k != nz / 2;
                if body || r.random_bool(0.002) {
                    data[i + nx * (j + ny * k)] = r.random_range(0.005f32..0.05);
                }
            }
        }
    }
    Volume::new(
        dims,
        DVec3::new(0.8, 0.8, 2.0),
        DVec3::ZERO,
        glam::DMat3::IDENTITY,
        data,
    )
    .unwrap()
}

/// The rows of `view` that form sheets over `vol`'s grid, their rays clipped to `bounds`:
/// (row, its world rays, its sheet).
fn sheet_rows(
    vol: &Volume,
    view: &tomograf_sim::View,
    bounds: &GridBox,
) -> Vec<(usize, Vec<Ray>, Sheet)> {
    (0..view.rows)
        .filter_map(|row| {
            let world: Vec<Ray> = (0..view.cols)
                .map(|c| view.ray(row as f64, c as f64))
                .collect();
            let clipped: Vec<_> = world
                .iter()
                .map(|w| GridRay::clip_to(vol, w, bounds))
                .collect();
            let sheet = Sheet::new(&clipped, vol.dims(), bounds)?;
            Some((row, world, sheet))
        })
        .collect()
}

/// The portable kernel's `n` sums of `plain` (through `sums`), after checking that every
/// SIMD kernel the CPU has gives the same bits for `plain` and for `skipping` (the same
/// sheet after `Sheet::skip_zeros`).
fn same_bits_from_every_kernel(
    plain: &Sheet,
    skipping: &Sheet,
    n: usize,
    sums: impl Fn(&Sheet, Option<packet::Kernel>, &mut [f64]),
) -> Vec<f64> {
    let mut reference = vec![f64::NAN; n];
    sums(plain, None, &mut reference);
    for kernel in packet::supported() {
        for sheet in [plain, skipping] {
            let mut out = vec![f64::NAN; n];
            sums(sheet, Some(kernel), &mut out);
            for (i, (a, b)) in out.iter().zip(&reference).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "{kernel:?}, sum {i}: {a} vs {b}");
            }
        }
    }
    reference
}

#[test]
fn skipping_zeros_changes_no_bits() {
    // The kernels skip groups of rays over blocks of segments where every voxel they can
    // meet is zero (`Sheet::skip_zeros`): the sums must be the same bits as without, for
    // every kernel, and match the reference; and the skip must actually be taken.
    let mut r = rng(75);
    let mut skipped = [0usize; 2];
    for dims in [[64, 48, 10], [41, 57, 7]] {
        let vol = body_in_air(&mut r, dims);
        let rows = tomograf_sim::occupancy::RowExtents::of(&vol);
        let bounds = rows.bounding_box().unwrap();
        for pose in [Pose::AP, Pose::new(180.0, 0.0)] {
            let view = geometry(&vol, 150.0, 260.0, 12, 61, 0.9)
                .view(pose)
                .unwrap();
            for (row, world, plain) in sheet_rows(&vol, &view, &bounds) {
                assert_eq!(plain.axis(), 0);
                let mut skipping = plain.clone();
                skipping.skip_zeros(&rows, &bounds);
                skipped[0] += skipping.passes(4, &bounds).zeros;
                skipped[1] += skipping.passes(8, &bounds).zeros;
                let reference =
                    same_bits_from_every_kernel(&plain, &skipping, world.len(), |s, k, out| {
                        s.line_integrals_with(k, vol.data(), dims, &bounds, out)
                    });
                for (c, w) in world.iter().enumerate() {
                    let exact = brute_force(&vol, w);
                    assert!(
                        rel_err(reference[c], exact) <= 1e-9
                            || (reference[c] - exact).abs() < 1e-13,
                        "row {row} column {c}: {} vs {exact}",
                        reference[c]
                    );
                }
            }
        }
    }
    assert!(
        skipped.iter().all(|&n| n > 500),
        "the zero skip was taken too rarely to be tested: {skipped:?}"
    );
}

/// A composition of `k` materials over `vol`'s grid: material from a coarse pattern (runs of
/// several voxels, as tissues are), density from the volume's values (0 where they are 0,
/// and in scattered voxels inside: holes of exact zeros that a ray's pieces skip).
fn composition_of(vol: &Volume, k: usize) -> tomograf_sim::composition::Composition {
    let [nx, ny, _] = vol.dims();
    let labels: Vec<f32> = (0..vol.data().len())
        .map(|n| {
            let (i, j, kk) = (n % nx, n / nx % ny, n / (nx * ny));
            ((i / 5 + 2 * (j / 3) + kk) % k) as f32
        })
        .collect();
    let grid = |data: Vec<f32>| {
        Volume::new(
            vol.dims(),
            vol.spacing(),
            vol.origin(),
            vol.direction(),
            data,
        )
        .unwrap()
    };
    let density: Vec<f32> = (vol.data().iter().enumerate())
        .map(|(n, &v)| if n % 13 == 0 { 0.0 } else { v * 20.0 })
        .collect();
    tomograf_sim::composition::Composition::from_labels(
        &grid(labels),
        &grid(density),
        (0..k).map(|m| format!("m{m}")).collect(),
    )
    .unwrap()
}

#[test]
fn material_sheets_match_reference_with_every_kernel() {
    // Per-material mass thickness through sheets: every kernel gives the portable
    // kernel's bits, with and without the zero skip, and each material's sum matches the
    // brute-force integral of that material's (unpacked) density to 1e-9.
    use tomograf_sim::composition::unpack;
    let mut r = rng(76);
    let mut rows_checked = 0;
    let mut skipped = 0;
    for (dims, k) in [([64, 48, 10], 3), ([41, 57, 7], 7)] {
        let vol = body_in_air(&mut r, dims);
        let comp = composition_of(&vol, k);
        let packed = comp.packed();
        let rows = tomograf_sim::occupancy::RowExtents::of(packed);
        let bounds = rows.bounding_box().unwrap();
        // Each material's density alone, for the reference.
        let alone: Vec<Volume> = (0..k)
            .map(|m| {
                let data = packed
                    .data()
                    .iter()
                    .map(|&v| {
                        let (rho, label) = unpack(v);
                        if label == m { rho } else { 0.0 }
                    })
                    .collect();
                Volume::new(
                    dims,
                    packed.spacing(),
                    packed.origin(),
                    packed.direction(),
                    data,
                )
                .unwrap()
            })
            .collect();
        for pose in [Pose::AP, Pose::new(180.0, 0.0)] {
            let view = geometry(packed, 150.0, 260.0, 10, 53, 1.0)
                .view(pose)
                .unwrap();
            for (row, world, plain) in sheet_rows(packed, &view, &bounds) {
                let mut skipping = plain.clone();
                skipping.skip_zeros(&rows, &bounds);
                skipped += skipping.passes(8, &bounds).zeros;
                let n = world.len() * k;
                let reference =
                    same_bits_from_every_kernel(&plain, &skipping, n, |s, kernel, out| {
                        s.material_sums_with(kernel, packed.data(), dims, &bounds, k, out)
                    });
                for (c, w) in world.iter().enumerate() {
                    for (m, vol_m) in alone.iter().enumerate() {
                        let (got, exact) = (reference[c * k + m], brute_force(vol_m, w));
                        assert!(
                            rel_err(got, exact) <= 1e-9 || (got - exact).abs() < 1e-12,
                            "row {row} column {c} material {m}: {got} vs {exact}"
                        );
                    }
                }
                rows_checked += 1;
            }
        }
    }
    assert!(
        rows_checked > 20 && skipped > 100,
        "{rows_checked} rows, {skipped} skips"
    );
}

#[test]
fn monotone_blocks_change_no_bits() {
    // The kernels' shortest path (`Passes::rising` and `falling`): a group of rays inside
    // a block of segments whose positions along the fan's axis move one way and stay in
    // the box. Cone-beam AP and PA rows (slopes of both signs, the central groups of both),
    // parallel-beam rows (slopes of 0 or nearly), and hand-made rows of zero and tiny
    // slopes starting on voxel planes: every SIMD kernel must give the portable kernel's
    // bits and match the reference, and the path must be taken often, both ways.
    let mut r = rng(77);
    let mut taken = [[0usize; 2]; 2];
    let mut count = |sheet: &Sheet, bounds: &GridBox| {
        for (n, lanes) in [4, 8].into_iter().enumerate() {
            let p = sheet.passes(lanes, bounds);
            taken[n][0] += p.rising;
            taken[n][1] += p.falling;
        }
    };
    for dims in [[64, 40, 9], [37, 52, 6]] {
        let vol = random_volume(&mut r, dims, false);
        let bounds = GridBox::whole(dims);
        for beam in [
            Beam::Cone {
                sad_mm: 150.0,
                sid_mm: 260.0,
            },
            Beam::Parallel,
        ] {
            for pose in [Pose::AP, Pose::new(180.0, 0.0)] {
                let mut geometry = geometry(&vol, 150.0, 260.0, 6, 45, 0.6);
                geometry.beam = beam;
                let view = geometry.view(pose).unwrap();
                for (_, world, sheet) in sheet_rows(&vol, &view, &bounds) {
                    count(&sheet, &bounds);
                    check_row(&vol, &world, &sheet);
                }
            }
        }
    }
    // Rays along j through points on planes of i, at slopes of 0, nearly 0 and small, over
    // 16 voxels of i.
    let dims = [20, 30, 5];
    let vol = random_volume(&mut r, dims, false);
    let bounds = GridBox::whole(dims);
    for slope in [0.0, 1e-300, -1e-300, 0.01, -0.01] {
        let world: Vec<Ray> = (0..16)
            .map(|n| {
                let a = 2.0 + n as f64;
                let p = |b: f64| DVec3::new(a + slope * b, b, 2.5);
                Ray::segment(grid_to_world(&vol, p(-4.0)), grid_to_world(&vol, p(34.0)))
            })
            .collect();
        let clipped: Vec<Option<GridRay>> = world.iter().map(|w| GridRay::clip(&vol, w)).collect();
        let sheet = Sheet::new(&clipped, dims, &bounds).expect("a sheet");
        let p = sheet.passes(8, &bounds);
        assert!(p.rising + p.falling > 0, "slope {slope}: {p:?}");
        count(&sheet, &bounds);
        check_row(&vol, &world, &sheet);
    }
    assert!(
        taken.iter().flatten().all(|&n| n > 100),
        "the shortest path was taken too rarely to be tested: {taken:?}"
    );
}
