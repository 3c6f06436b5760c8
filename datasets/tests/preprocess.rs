//! CT preprocessing: resampling against analytic fields (linear fields, a sphere), mean
//! preservation, anti-aliasing, world-box preservation, determinism across thread counts;
//! black-border cropping, padding to a cube and HU windowing.

use glam::{DMat3, DVec3};
use tomograf_datasets::DatasetError;
use tomograf_datasets::preprocess::{HuWindow, crop_black_border, pad_to_cube, resample};
use tomograf_sim::Volume;

fn rotated() -> DMat3 {
    DMat3::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 0.8)
}

fn reflected() -> DMat3 {
    DMat3::from_rotation_x(0.4) * DMat3::from_diagonal(DVec3::new(1.0, -1.0, 1.0))
}

/// A volume whose voxel values are `f(world centre)`.
fn sampled(
    dims: [usize; 3],
    spacing: DVec3,
    origin: DVec3,
    direction: DMat3,
    f: impl Fn(DVec3) -> f64,
) -> Volume {
    let geo = Volume::new(
        dims,
        spacing,
        origin,
        direction,
        vec![0.0; dims[0] * dims[1] * dims[2]],
    )
    .unwrap();
    let mut data = Vec::with_capacity(geo.len());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = geo.index_to_world(DVec3::new(i as f64, j as f64, k as f64));
                data.push(f(p) as f32);
            }
        }
    }
    Volume::new(dims, spacing, origin, direction, data).unwrap()
}

fn idx(i: usize, j: usize, k: usize) -> DVec3 {
    DVec3::new(i as f64, j as f64, k as f64)
}

/// A linear field of world position, of order 1 over the test boxes.
fn linear(p: DVec3) -> f64 {
    0.3 + 0.011 * p.x - 0.007 * p.y + 0.013 * p.z
}

fn world_box(v: &Volume) -> [DVec3; 8] {
    let n = DVec3::new(v.dims()[0] as f64, v.dims()[1] as f64, v.dims()[2] as f64);
    std::array::from_fn(|c| {
        let g = DVec3::new(
            if c & 1 == 0 { 0.0 } else { n.x },
            if c & 2 == 0 { 0.0 } else { n.y },
            if c & 4 == 0 { 0.0 } else { n.z },
        );
        v.index_to_world(g - 0.5)
    })
}

/// Σ value · voxel volume / box volume.
fn mean(v: &Volume) -> f64 {
    v.data().iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64
}

#[test]
fn enlarging_reproduces_a_linear_field_at_interior_centres() {
    for direction in [DMat3::IDENTITY, rotated(), reflected()] {
        let v = sampled(
            [8, 8, 8],
            DVec3::new(2.5, 3.0, 4.0),
            DVec3::new(-10.0, 5.0, -7.0),
            direction,
            linear,
        );
        let r = resample(&v, [20, 20, 20]).unwrap();
        assert_eq!(r.dims(), [20, 20, 20]);
        let mut checked = 0;
        let mut worst = 0.0f64;
        for k in 0..20 {
            for j in 0..20 {
                for i in 0..20 {
                    let p = r.index_to_world(idx(i, j, k));
                    let q = v.world_to_index(p);
                    let interior = q.min_element() >= 0.0 && q.max_element() <= 7.0;
                    if !interior {
                        continue;
                    }
                    checked += 1;
                    let err = (f64::from(r.get(i, j, k)) - linear(p)).abs();
                    worst = worst.max(err);
                }
            }
        }
        // 8→20: output centres at input index (p+0.5)·0.4 − 0.5, interior for p = 1..=18.
        assert_eq!(checked, 18 * 18 * 18);
        assert!(worst < 1e-5, "worst error {worst}");
        // The clamped border holds the edge values, not an extrapolation.
        let corner = f64::from(r.get(0, 0, 0));
        assert!((corner - f64::from(v.get(0, 0, 0))).abs() < 1e-6);
    }
}

#[test]
fn shrinking_gives_the_voxel_mean_of_a_linear_field() {
    // 40→10 per axis: each output voxel averages exactly 4×4×4 input voxels, so its value
    // is the mean of f over its box, which for a linear f is f at its centre (no border
    // effect: box filtering never clamps).
    for direction in [DMat3::IDENTITY, rotated()] {
        let v = sampled(
            [40, 40, 40],
            DVec3::new(0.75, 1.0, 1.25),
            DVec3::new(3.0, -8.0, 12.0),
            direction,
            linear,
        );
        let r = resample(&v, [10, 10, 10]).unwrap();
        assert!(
            (r.spacing() - DVec3::new(3.0, 4.0, 5.0))
                .abs()
                .max_element()
                < 1e-12
        );
        let mut worst = 0.0f64;
        for k in 0..10 {
            for j in 0..10 {
                for i in 0..10 {
                    let p = r.index_to_world(idx(i, j, k));
                    worst = worst.max((f64::from(r.get(i, j, k)) - linear(p)).abs());
                }
            }
        }
        assert!(worst < 1e-4, "worst error {worst}");
        assert!(
            worst < 1e-5,
            "worst error {worst} (f32 rounding only expected)"
        );
    }
}

#[test]
fn shrinking_by_a_non_integer_factor_preserves_the_mean() {
    let n = [37, 37, 37];
    let data: Vec<f32> = (0..37 * 37 * 37)
        .map(|i: usize| ((i * 7919) % 1013) as f32 * 0.5 - 200.0)
        .collect();
    let v = Volume::new(n, DVec3::new(0.9, 1.1, 1.7), DVec3::ZERO, rotated(), data).unwrap();
    // Mixed: non-integer shrink on x and y, non-integer enlarge on z.
    for dims in [[16, 16, 16], [16, 11, 50]] {
        let r = resample(&v, dims).unwrap();
        // All output voxels have the same volume, so the volume-weighted mean is the plain
        // mean; so for the input.
        let (mi, mo) = (mean(&v), mean(&r));
        if dims == [16, 16, 16] {
            assert!(
                (mi - mo).abs() < 1e-5 * mi.abs().max(1.0),
                "{dims:?}: input mean {mi}, output mean {mo}"
            );
        }
        // The output really is a smoothed copy, not the input's mean everywhere.
        let (lo, hi) = r.min_max();
        assert!(hi - lo > 10.0, "{dims:?}: {lo}..{hi}");
    }
    // Against the mean-preservation of a non-box filter (point sampling at the output
    // centres), which this data set distinguishes.
    let pointwise: f64 = {
        let mut s = 0.0;
        for k in 0..16 {
            for j in 0..16 {
                for i in 0..16 {
                    let q = |p: usize| (((p as f64 + 0.5) * 37.0 / 16.0 - 0.5).round()) as usize;
                    s += f64::from(v.get(q(i), q(j), q(k)));
                }
            }
        }
        s / 4096.0
    };
    assert!((pointwise - mean(&v)).abs() > 1e-3);
}

#[test]
fn checkerboard_along_x_averages_out_when_halved() {
    let dims = [32, 6, 5];
    let data: Vec<f32> = (0..dims[0] * dims[1] * dims[2])
        .map(|p| if (p % dims[0]) % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let v = Volume::new(dims, DVec3::ONE, DVec3::ZERO, DMat3::IDENTITY, data).unwrap();
    let r = resample(&v, [16, 6, 5]).unwrap();
    let worst = r.data().iter().fold(0.0f32, |a, &x| a.max(x.abs()));
    assert!(worst < 1e-6, "aliasing: |v| up to {worst}");
    // Point sampling at the output centres (input index 2p + 0.5, nearest voxel 2p or
    // 2p + 1) would give ±1 everywhere.
    let r = resample(&v, [16, 3, 5]).unwrap();
    assert!(r.data().iter().all(|x| x.abs() < 1e-6));
}

#[test]
fn resampled_volume_covers_the_same_world_box() {
    let spacing = DVec3::new(0.6, 1.3, 2.7);
    let origin = DVec3::new(-123.25, 45.5, 310.75);
    for direction in [DMat3::IDENTITY, rotated(), reflected()] {
        let v = sampled([23, 17, 9], spacing, origin, direction, linear);
        for dims in [
            [128, 128, 128],
            [7, 40, 9],
            [1, 1, 1],
            [23, 17, 9],
            [5, 17, 30],
        ] {
            let r = resample(&v, dims).unwrap();
            assert_eq!(r.dims(), dims);
            assert_eq!(r.direction(), v.direction());
            for (a, b) in world_box(&v).iter().zip(world_box(&r)) {
                assert!((*a - b).length() < 1e-6, "{dims:?}: corner {a} vs {b}");
            }
            let expect = spacing * DVec3::new(23.0, 17.0, 9.0)
                / DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
            assert!((r.spacing() - expect).abs().max_element() < 1e-12);
            assert!((r.centre() - v.centre()).length() < 1e-6);
        }
    }
}

#[test]
fn sphere_volume_survives_downsampling() {
    let r_mm = 20.0;
    let centre = DVec3::new(1.3, -0.7, 0.4);
    // 100 voxels of 0.5 mm = 50 mm box, sphere well inside.
    let v = sampled(
        [100, 100, 100],
        DVec3::splat(0.5),
        DVec3::splat(-24.75),
        DMat3::IDENTITY,
        |p| {
            if (p - centre).length() < r_mm {
                1000.0
            } else {
                -1000.0
            }
        },
    );
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r_mm.powi(3);
    let box_volume = 50.0f64.powi(3);
    let estimate = |vol: &Volume| (mean(vol) + 1000.0) / 2000.0 * box_volume;
    let r = resample(&v, [25, 25, 25]).unwrap();
    assert!((r.spacing() - DVec3::splat(2.0)).abs().max_element() < 1e-12);
    let est = estimate(&r);
    assert!(
        (est - exact).abs() < 0.01 * exact,
        "sphere volume {est} mm³ vs {exact} mm³"
    );
    // Mean preserved through the resampling.
    assert!((est - estimate(&v)).abs() < 1e-4 * exact);
    // Partial-volume voxels at the surface: box filtering produces intermediate values.
    let partial = r.data().iter().filter(|x| x.abs() < 900.0).count();
    assert!(partial > 100, "only {partial} partial-volume voxels");
}

#[test]
fn resample_is_byte_identical_for_one_and_two_threads() {
    let v = sampled(
        [61, 47, 33],
        DVec3::new(0.7, 0.8, 1.9),
        DVec3::new(5.0, 6.0, 7.0),
        rotated(),
        |p| (p.x * 0.3).sin() * 500.0 + (p.y * p.z * 0.01).cos() * 300.0,
    );
    for dims in [[24, 24, 24], [128, 20, 70]] {
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| resample(&v, dims).unwrap())
        };
        let (one, two) = (run(1), run(2));
        assert_eq!(one.dims(), two.dims());
        let bytes = |x: &Volume| x.data().iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        assert_eq!(bytes(&one), bytes(&two), "{dims:?}");
        assert_eq!(one, two);
    }
}

#[test]
fn resample_refuses_zero_dims() {
    let v = Volume::new(
        [2, 2, 2],
        DVec3::ONE,
        DVec3::ZERO,
        DMat3::IDENTITY,
        vec![0.0; 8],
    )
    .unwrap();
    let e = resample(&v, [4, 0, 4]).unwrap_err();
    assert!(matches!(e, DatasetError::Invalid(_)));
    let msg = e.to_string();
    assert!(msg.contains("resample") && msg.contains("zero"), "{msg}");
}

/// A 20×18×16 volume of −1024 padding with a block of "tissue" (−900 < v) at
/// i ∈ 3..=12, j ∈ 5..=9, k ∈ 2..=14, and a little sub-threshold noise.
fn padded_block(direction: DMat3) -> Volume {
    let dims = [20, 18, 16];
    let mut data = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let inside = (3..=12).contains(&i) && (5..=9).contains(&j) && (2..=14).contains(&k);
                data.push(if inside {
                    (i + 10 * j + 100 * k) as f32 - 500.0
                } else if (i + j + k) % 5 == 0 {
                    -950.0
                } else {
                    -1024.0
                });
            }
        }
    }
    Volume::new(
        dims,
        DVec3::new(0.7, 0.9, 2.5),
        DVec3::new(-30.0, 12.0, 100.0),
        direction,
        data,
    )
    .unwrap()
}

#[test]
fn crop_black_border_keeps_exactly_the_block_in_place() {
    for direction in [DMat3::IDENTITY, rotated(), reflected()] {
        let v = padded_block(direction);
        let c = crop_black_border(&v, -900.0).unwrap();
        assert_eq!(c.dims(), [10, 5, 13]);
        assert_eq!(c.spacing(), v.spacing());
        assert_eq!(c.direction(), v.direction());
        for k in 0..13 {
            for j in 0..5 {
                for i in 0..10 {
                    let (oi, oj, ok) = (i + 3, j + 5, k + 2);
                    assert_eq!(c.get(i, j, k), v.get(oi, oj, ok));
                    let d = c.index_to_world(idx(i, j, k)) - v.index_to_world(idx(oi, oj, ok));
                    assert!(d.length() < 1e-9);
                }
            }
        }
        // Threshold below the noise: the noise voxels reach the whole volume's box.
        let all = crop_black_border(&v, -1000.0).unwrap();
        assert_eq!(all.dims(), [20, 18, 16]);
        assert_eq!(all, v);
    }
}

#[test]
fn crop_black_border_refuses_an_all_padding_volume() {
    let v = Volume::new(
        [4, 4, 4],
        DVec3::ONE,
        DVec3::ZERO,
        DMat3::IDENTITY,
        vec![-1024.0; 64],
    )
    .unwrap();
    let e = crop_black_border(&v, -900.0).unwrap_err();
    assert!(matches!(e, DatasetError::Invalid(_)));
    let msg = e.to_string();
    assert!(msg.contains("no voxel") && msg.contains("-900"), "{msg}");
    assert!(crop_black_border(&v, f32::NAN).is_err());
}

#[test]
fn pad_to_cube_isotropic_is_an_exact_cube() {
    for direction in [DMat3::IDENTITY, rotated()] {
        let dims = [7, 12, 4];
        let data: Vec<f32> = (0..7 * 12 * 4).map(|i| i as f32).collect();
        let v = Volume::new(
            dims,
            DVec3::splat(1.5),
            DVec3::new(3.0, 2.0, 1.0),
            direction,
            data,
        )
        .unwrap();
        let p = pad_to_cube(&v, -1024.0).unwrap();
        assert_eq!(p.dims(), [12, 12, 12]);
        assert_eq!(p.spacing(), v.spacing());
        assert_eq!(p.direction(), v.direction());
        // Padding before: (12−7)/2 = 2, 0, (12−4)/2 = 4.
        let before = [2, 0, 4];
        let mut originals = 0;
        for k in 0..12 {
            for j in 0..12 {
                for i in 0..12 {
                    let (ii, jj, kk) = (
                        i as isize - before[0],
                        j as isize - before[1],
                        k as isize - before[2],
                    );
                    let inside =
                        (0..7).contains(&ii) && (0..12).contains(&jj) && (0..4).contains(&kk);
                    if inside {
                        let (ii, jj, kk) = (ii as usize, jj as usize, kk as usize);
                        originals += 1;
                        assert_eq!(p.get(i, j, k), v.get(ii, jj, kk));
                        let d = p.index_to_world(idx(i, j, k)) - v.index_to_world(idx(ii, jj, kk));
                        assert!(d.length() < 1e-9);
                    } else {
                        assert_eq!(p.get(i, j, k), -1024.0);
                    }
                }
            }
        }
        assert_eq!(originals, v.len());
        // Centred: exactly on the even axes (j, k), half a voxel off on the odd one (i).
        let off = p.direction().transpose() * (p.centre() - v.centre());
        assert!((off - DVec3::new(0.75, 0.0, 0.0)).length() < 1e-9, "{off}");
        // Resampling the cube to n³ then gives isotropic voxels.
        let r = resample(&p, [5, 5, 5]).unwrap();
        assert!((r.spacing() - DVec3::splat(3.6)).abs().max_element() < 1e-12);
    }
}

#[test]
fn pad_to_cube_anisotropic_reaches_the_largest_extent() {
    // Extents 10·0.7 = 7, 6·0.9 = 5.4, 3·2.5 = 7.5 mm: side 7.5 mm.
    let v = Volume::new(
        [10, 6, 3],
        DVec3::new(0.7, 0.9, 2.5),
        DVec3::new(-3.0, 4.0, 5.0),
        reflected(),
        (0..180).map(|i| i as f32 * 2.0).collect(),
    )
    .unwrap();
    let p = pad_to_cube(&v, -1000.0).unwrap();
    // ceil(7.5/0.7) = 11, ceil(7.5/0.9) = 9, 3.
    assert_eq!(p.dims(), [11, 9, 3]);
    let extent = p.spacing() * DVec3::new(11.0, 9.0, 3.0);
    for (a, s) in extent.to_array().iter().zip(p.spacing().to_array()) {
        assert!(*a >= 7.5 - 1e-9 && *a < 7.5 + s, "extent {extent}");
    }
    // Original voxels unchanged and in place, fill elsewhere (checked by world position).
    let mut originals = 0;
    let mut fills = 0;
    for k in 0..3 {
        for j in 0..9 {
            for i in 0..11 {
                let q = v.world_to_index(p.index_to_world(idx(i, j, k))).round();
                let inside = q.min_element() >= 0.0 && q.x < 10.0 && q.y < 6.0 && q.z < 3.0;
                if inside {
                    originals += 1;
                    let back = v.world_to_index(p.index_to_world(idx(i, j, k)));
                    assert!((back - q).length() < 1e-9);
                    assert_eq!(
                        p.get(i, j, k),
                        v.get(q.x as usize, q.y as usize, q.z as usize)
                    );
                } else {
                    fills += 1;
                    assert_eq!(p.get(i, j, k), -1000.0);
                }
            }
        }
    }
    assert_eq!(originals, 180);
    assert_eq!(fills, 11 * 9 * 3 - 180);
    // Centred to within half a voxel per axis.
    let off = (p.direction().transpose() * (p.centre() - v.centre())).abs();
    assert!(off.cmple(v.spacing() * 0.5 + 1e-9).all(), "{off}");
    assert!(pad_to_cube(&v, f32::INFINITY).is_err());
}

#[test]
fn hu_window_round_trip_and_clamping() {
    let w = HuWindow::CHEST;
    assert_eq!((w.lo, w.hi), (-1024.0, 2048.0));
    let values: Vec<f32> = vec![
        -3024.0, -1100.0, -1024.0, -1000.0, -700.5, 0.0, 40.25, 1000.0, 2048.0, 2500.0, 4000.0,
    ];
    let v = Volume::new(
        [11, 1, 1],
        DVec3::ONE,
        DVec3::ZERO,
        DMat3::IDENTITY,
        values.clone(),
    )
    .unwrap();
    let n = w.normalize(&v).unwrap();
    assert_eq!(n.spacing(), v.spacing());
    assert!(n.data().iter().all(|&x| (0.0..=1.0).contains(&x)));
    assert_eq!(n.data()[0], 0.0);
    assert_eq!(n.data()[1], 0.0);
    assert_eq!(n.data()[2], 0.0);
    assert_eq!(n.data()[8], 1.0);
    assert_eq!(n.data()[9], 1.0);
    assert!((f64::from(n.data()[5]) - 1024.0 / 3072.0).abs() < 1e-7);
    let back = w.denormalize(&n).unwrap();
    for (i, (&a, &b)) in values.iter().zip(back.data()).enumerate() {
        let expect = a.clamp(-1024.0, 2048.0);
        // Through an f32 in [0, 1] a 3072 HU window resolves ~3072·2⁻²⁴ ≈ 2·10⁻⁴ HU.
        assert!((expect - b).abs() < 4e-4, "value {i}: {a} → {b}");
    }

    // A narrow window: round trip to 1e-5 HU inside it.
    let w = HuWindow::new(-10.0, 10.0).unwrap();
    let inside: Vec<f32> = (0..=200).map(|i| -10.0 + i as f32 * 0.1).collect();
    let v = Volume::new(
        [201, 1, 1],
        DVec3::ONE,
        DVec3::ZERO,
        DMat3::IDENTITY,
        inside.clone(),
    )
    .unwrap();
    let back = w.denormalize(&w.normalize(&v).unwrap()).unwrap();
    for (&a, &b) in inside.iter().zip(back.data()) {
        assert!((a - b).abs() < 1e-5, "{a} → {b}");
    }
}

#[test]
fn hu_window_validation() {
    for (lo, hi) in [
        (1.0, 1.0),
        (2.0, 1.0),
        (f32::NAN, 1.0),
        (0.0, f32::INFINITY),
    ] {
        let e = HuWindow::new(lo, hi).unwrap_err();
        assert!(matches!(e, DatasetError::Invalid(_)));
        assert!(e.to_string().contains("HU window"), "{e}");
    }
    // Fields set by hand are checked when used.
    let bad = HuWindow { lo: 5.0, hi: -5.0 };
    let v = Volume::new(
        [1, 1, 1],
        DVec3::ONE,
        DVec3::ZERO,
        DMat3::IDENTITY,
        vec![0.0],
    )
    .unwrap();
    assert!(bad.normalize(&v).is_err());
    assert!(bad.denormalize(&v).is_err());
    // Serde: round trip, and invalid windows refused on load.
    let json = serde_json::to_string(&HuWindow::CHEST).unwrap();
    assert_eq!(
        serde_json::from_str::<HuWindow>(&json).unwrap(),
        HuWindow::CHEST
    );
    let e = serde_json::from_str::<HuWindow>(r#"{"lo": 3.0, "hi": 1.0}"#).unwrap_err();
    assert!(e.to_string().contains("lower bound"), "{e}");
}
