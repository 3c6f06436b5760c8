//! Per-material tracing in one pass against one independent line integral per material.
//!
//! For each material m, the field "density where the voxel is m, 0 elsewhere" is rendered
//! with the (separately verified) line-integral renderer; the one-pass mass thickness of m
//! must equal it. Tolerance 1e-5 relative (+1e-9 absolute): the composition stores
//! densities truncated to 19 mantissa bits (≤ 1.9e-6 relative, see `composition.rs`), and
//! the masked reference fields hold the same truncated densities, so the remaining
//! difference is summation order (~1e-12).

mod common;

use common::*;
use glam::{DMat3, DVec3};
use rand::Rng;
use tomograf_sim::composition::{Composition, unpack};
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Renderer, Volume};

/// A random composition with `k` materials, ~30 % empty voxels.
fn random_composition(seed: u64, dims: [usize; 3], k: usize) -> Composition {
    let mut r = rng(seed);
    let n = dims[0] * dims[1] * dims[2];
    let labels: Vec<f32> = (0..n).map(|_| r.random_range(0..k) as f32).collect();
    let density: Vec<f32> = (0..n)
        .map(|_| {
            if r.random_bool(0.3) {
                0.0
            } else {
                r.random_range(0.001..3.0)
            }
        })
        .collect();
    let vol = |d| {
        Volume::new(
            dims,
            DVec3::new(0.9, 1.1, 1.7),
            DVec3::new(-10.0, 5.0, 2.0),
            DMat3::IDENTITY,
            d,
        )
        .unwrap()
    };
    let names = (0..k).map(|m| format!("m{m}")).collect();
    Composition::from_labels(&vol(labels), &vol(density), names).unwrap()
}

/// The density field of material `m` alone (g/cm³), from the packed grid.
fn masked(c: &Composition, m: usize) -> Volume {
    c.packed()
        .map(|v| {
            let (rho, l) = unpack(v);
            if l == m { rho } else { 0.0 }
        })
        .unwrap()
}

fn check(c: &Composition, projector: Projector, threshold: f64, theta: f64) {
    let p = c.packed();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 300.0,
            sid_mm: 500.0,
        },
        detector: Detector::new(24, 26, 1.0),
        isocentre: p.centre(),
    };
    let view = g.view(Pose::new(theta, 10.0)).unwrap();
    let names = c.materials().to_vec();
    let paths = Renderer::for_composition(c, projector)
        .unwrap()
        .with_packet_threshold(threshold)
        .mass_thickness(&view, &names)
        .unwrap();
    let mut nonzero = 0;
    for m in 0..names.len() {
        let field = masked(c, m);
        let reference = Renderer::new(&field, projector)
            .unwrap()
            .render(&view)
            .unwrap();
        for r in 0..view.rows {
            for col in 0..view.cols {
                let got = paths.at(r, col)[m] * 10.0; // g/cm² → g/cm³·mm
                let want = f64::from(reference.at(r, col));
                nonzero += usize::from(want > 0.0);
                assert!(
                    (got - want).abs() <= 1e-5 * want.abs() + 1e-9,
                    "{projector:?} θ={theta} material {m} pixel ({r},{col}): {got} vs {want}"
                );
            }
        }
    }
    assert!(nonzero > 100, "the view must see the materials");
}

#[test]
fn one_pass_siddon_equals_a_line_integral_per_material() {
    for (seed, k) in [(1, 1), (2, 3), (3, 5), (4, 16)] {
        let c = random_composition(seed, [13, 11, 9], k);
        for theta in [0.0, 33.0, 90.0, 151.0] {
            check(&c, Projector::Siddon, f64::INFINITY, theta); // scalar tracer
            check(&c, Projector::Siddon, 0.0, theta); // SIMD packets where available
        }
    }
}

#[test]
fn one_pass_trilinear_equals_a_line_integral_per_material() {
    let c = random_composition(9, [10, 12, 8], 4);
    for theta in [0.0, 47.0] {
        check(&c, Projector::Trilinear { step_voxels: 0.5 }, 0.0, theta);
    }
}

#[test]
fn bad_labels_and_densities_are_named() {
    let grid =
        |d: Vec<f32>| Volume::new([2, 1, 1], DVec3::ONE, DVec3::ZERO, DMat3::IDENTITY, d).unwrap();
    let names = vec!["water".to_string(), "bone".to_string()];
    let e = Composition::from_labels(&grid(vec![0.0, 2.0]), &grid(vec![1.0, 1.0]), names.clone())
        .unwrap_err()
        .to_string();
    assert!(e.contains("voxel 1") && e.contains("material 2"), "{e}");
    let e = Composition::from_labels(&grid(vec![0.0, 1.5]), &grid(vec![1.0, 1.0]), names.clone())
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a whole number"), "{e}");
    let e = Composition::from_labels(&grid(vec![0.0, 1.0]), &grid(vec![1.0, -1.0]), names)
        .unwrap_err()
        .to_string();
    assert!(e.contains("density -1"), "{e}");
    let e = Composition::from_labels(&grid(vec![0.0, 0.0]), &grid(vec![1.0, 1.0]), vec![])
        .unwrap_err()
        .to_string();
    assert!(e.contains("0 materials"), "{e}");
}

#[test]
fn every_simd_kernel_matches_the_scalar_tracer() {
    use tomograf_sim::GridRay;
    use tomograf_sim::trace::{MaterialPaths, packet, siddon};
    let c = random_composition(11, [17, 9, 12], 6);
    let p = c.packed();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 200.0,
            sid_mm: 400.0,
        },
        detector: Detector::new(16, 32, 1.2),
        isocentre: p.centre(),
    };
    let k = c.materials().len();
    let mut packets = 0;
    for theta in [0.0, 20.0, 65.0, 130.0] {
        let view = g.view(Pose::new(theta, -15.0)).unwrap();
        for row in 0..view.rows {
            let rays: Vec<Option<GridRay>> = (0..view.cols)
                .map(|col| GridRay::clip(p, &view.ray(row as f64, col as f64)))
                .collect();
            for kernel in packet::supported() {
                let mut out = vec![0.0; rays.len() * k];
                let mut handled = vec![false; rays.len()];
                packet::trace_row_materials_with(
                    kernel,
                    p.data(),
                    p.dims(),
                    &rays,
                    0.0,
                    k,
                    &mut out,
                    &mut handled,
                );
                for (n, ray) in rays.iter().enumerate().filter(|(n, _)| handled[*n]) {
                    packets += 1;
                    let mut acc = MaterialPaths::new(p.data());
                    if let Some(ray) = ray {
                        siddon::trace(p.dims(), ray, &mut acc);
                    }
                    for m in 0..k {
                        let (a, b) = (out[n * k + m], acc.sums()[m]);
                        assert!(
                            (a - b).abs() <= 1e-9 * b.abs() + 1e-12,
                            "{kernel:?} θ={theta} row {row} ray {n} material {m}: {a} vs {b}"
                        );
                    }
                }
            }
        }
    }
    if packet::available() {
        assert!(packets > 1000, "the SIMD kernels must have handled rays");
    }
}

#[test]
fn tiles_of_rows_match_the_scalar_tracer() {
    use tomograf_sim::GridRay;
    use tomograf_sim::trace::{MaterialPaths, packet, siddon};
    let c = random_composition(12, [15, 11, 13], 5);
    let p = c.packed();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 200.0,
            sid_mm: 400.0,
        },
        detector: Detector::new(7, 19, 1.3),
        isocentre: p.centre(),
    };
    let k = c.materials().len();
    let mut handled_rays = 0;
    for theta in [0.0, 50.0, 115.0] {
        let view = g.view(Pose::new(theta, 10.0)).unwrap();
        // Seven rows at once: a tile of four, then three.
        let rays: Vec<Option<GridRay>> = (0..view.rows)
            .flat_map(|row| (0..view.cols).map(move |col| (row, col)))
            .map(|(row, col)| GridRay::clip(p, &view.ray(row as f64, col as f64)))
            .collect();
        for kernel in packet::supported() {
            let mut out = vec![0.0; rays.len() * k];
            let mut handled = vec![false; rays.len()];
            packet::trace_rows_with(
                kernel,
                p.data(),
                p.dims(),
                &rays,
                view.cols,
                0.0,
                k,
                &mut out,
                &mut handled,
            );
            for (n, ray) in rays.iter().enumerate().filter(|(n, _)| handled[*n]) {
                handled_rays += 1;
                let mut acc = MaterialPaths::new(p.data());
                if let Some(ray) = ray {
                    siddon::trace(p.dims(), ray, &mut acc);
                }
                for m in 0..k {
                    let (a, b) = (out[n * k + m], acc.sums()[m]);
                    assert!(
                        (a - b).abs() <= 1e-9 * b.abs() + 1e-12,
                        "{kernel:?} θ={theta} ray {n} material {m}: {a} vs {b}"
                    );
                }
            }
        }
    }
    if packet::available() {
        assert!(
            handled_rays > 300,
            "the SIMD kernels must have handled rays"
        );
    }
}

/// `blend_hu` (partial volume at tissue boundaries): CT numbers within ±W/2 of an inner
/// bound are the 50/50 mass mixture of the neighbours — its mass attenuation the mean of
/// theirs at any energy (the mixture rule, computed here from the two materials) — while
/// every voxel keeps the linear attenuation its HU says at the calibration energy (2e-6
/// relative: the 19-bit packed density). Bad widths are refused by name.
#[test]
fn blended_boundaries_mix_the_neighbours() {
    use tomograf_sim::attenuation::mu_water_per_mm;
    use tomograf_sim::material::by_name;
    use tomograf_sim::tissue::TissueModel;
    // lung band about −120, plain lung, plain soft tissue, soft/bone-30 band about 100,
    // plain bone-60.
    let hu = [-130.0f32, -150.0, 60.0, 95.0, 500.0];
    let vol = Volume::centred([5, 1, 1], DVec3::ONE, DVec3::ZERO, hu.to_vec()).unwrap();
    let plain = TissueModel::schneider();
    let mut model = plain.clone();
    model.blend_hu = 40.0;
    let (comp, mats) = model.composition(&vol).unwrap();
    let names: Vec<&str> = mats.iter().map(|m| m.name()).collect();
    let label = |i: usize| names[unpack(comp.packed().data()[i]).1];
    assert_eq!(
        (0..5).map(label).collect::<Vec<_>>(),
        [
            "lung+adipose",
            "lung",
            "soft-tissue",
            "soft-tissue+bone-30",
            "bone-60"
        ]
    );
    let (plain_comp, plain_mats) = plain.composition(&vol).unwrap();
    assert_eq!(
        plain_mats[unpack(plain_comp.packed().data()[0]).1].name(),
        "lung",
        "without blending the band is plain lung"
    );
    let bone30 = plain
        .materials()
        .unwrap()
        .into_iter()
        .find(|m| m.name() == "bone-30")
        .unwrap();
    let soft = by_name("soft-tissue").unwrap();
    let mixed = mats
        .iter()
        .find(|m| m.name() == "soft-tissue+bone-30")
        .unwrap();
    for e in [20.0, 40.0, 70.0, 120.0] {
        let want =
            0.5 * soft.mass_attenuation(e).unwrap() + 0.5 * bone30.mass_attenuation(e).unwrap();
        let got = mixed.mass_attenuation(e).unwrap();
        assert!(rel_err(got, want) < 1e-9, "{e} keV: {got} vs {want}");
    }
    let e_cal = model.calibration_kev;
    for (i, &h) in hu.iter().enumerate() {
        let (rho, m) = unpack(comp.packed().data()[i]);
        let mu = f64::from(rho) * mats[m].mass_attenuation(e_cal).unwrap() / 10.0;
        let want = mu_water_per_mm(e_cal).unwrap() * (1.0 + f64::from(h) / 1000.0);
        assert!(
            rel_err(mu, want) < 2e-6,
            "voxel {i} ({h} HU): {mu} vs {want}"
        );
    }
    for (w, words) in [
        (-1.0, "blend_hu = -1"),
        (f64::NAN, "blend_hu = NaN"),
        (150.0, "not narrower than 'adipose'"),
    ] {
        let mut bad = TissueModel::schneider();
        bad.blend_hu = w;
        let e = bad.composition(&vol).unwrap_err().to_string();
        assert!(e.contains(words), "{e}");
    }
}
