//! Woodcock tracking with per-brick majorants (`scatter::majorant`) against independent
//! answers: every brick's majorant bounds every voxel it may be asked about (brute force),
//! and the free paths it samples follow Beer–Lambert along the exact Siddon path — the
//! no-collision probability exp(−τ) and the distribution of the first collision's optical
//! depth — for rays along axes, through brick corners, grazing a brick face, starting
//! inside the volume and crossing air, lung, water and bone; the global majorant is held to
//! the same tests. The forced first flight (`Medium::fly_forced`) is held to the same exact
//! path: its collision probability is 1 − exp(−τ) and its collision sits at the optical
//! depth −ln(1 − u·P) it was given (to 1e-9, rounding of two differently ordered sums).
//!
//! Tolerance: |z| ≤ 4.5 for each binomial count (100 000 photons per ray: a bias of 0.7 % in
//! a probability near ½ fails), so a correct tracker fails with probability below 1e-5 per
//! check and the seeds are fixed.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tomograf_physics::scatter::majorant::MajorantGrid;
use tomograf_physics::scatter::transport::Medium;
use tomograf_sim::composition::Composition;
use tomograf_sim::material::{self, Material};
use tomograf_sim::volume::Volume;

const DIMS: [usize; 3] = [24, 20, 16];
const SPACING: f64 = 2.0;
const PHOTONS: usize = 100_000;
const Z_MAX: f64 = 4.5;

/// Materials by label: water, lung, cortical bone.
fn materials() -> Vec<Material> {
    ["water", "lung", "cortical-bone"]
        .iter()
        .map(|n| material::by_name(n).unwrap())
        .collect()
}

/// A box of 48×40×32 mm centred on the origin (2 mm voxels): air for x < −12 mm, a lung
/// block, a bone block and water elsewhere, every voxel's density drawn ±10 % around its
/// tissue's, so bricks differ and no majorant is tight.
fn phantom() -> Composition {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let n: usize = DIMS.iter().product();
    let (mut labels, mut density) = (vec![0.0f32; n], vec![0.0f32; n]);
    for k in 0..DIMS[2] {
        for j in 0..DIMS[1] {
            for i in 0..DIMS[0] {
                let v = i + DIMS[0] * (j + DIMS[1] * k);
                let (label, rho) = if i < 6 {
                    (0, 0.0)
                } else if (8..14).contains(&i) && j < 12 {
                    (1, 0.26)
                } else if (16..20).contains(&i) && (6..14).contains(&k) {
                    (2, 1.92)
                } else {
                    (0, 1.0)
                };
                labels[v] = label as f32;
                density[v] = rho * rng.random_range(0.9f32..1.1);
            }
        }
    }
    let grid =
        |data: Vec<f32>| Volume::centred(DIMS, DVec3::splat(SPACING), DVec3::ZERO, data).unwrap();
    Composition::from_labels(
        &grid(labels),
        &grid(density),
        vec!["water".into(), "lung".into(), "cortical-bone".into()],
    )
    .unwrap()
}

#[test]
fn every_brick_majorant_bounds_the_voxels_within_one_voxel_of_it() {
    let comp = phantom();
    let packed = comp.packed();
    for size in [1, 3, 8] {
        let grid = MajorantGrid::build(packed, 3, size).unwrap();
        let nb = grid.brick_dims();
        for k in 0..DIMS[2] {
            for j in 0..DIMS[1] {
                for i in 0..DIMS[0] {
                    let (rho, m) = tomograf_sim::composition::unpack(packed.get(i, j, k));
                    let mut unit = [0.0; 3];
                    unit[m] = 1.0;
                    let v = [i, j, k];
                    // Every brick whose box grown by one voxel holds this voxel.
                    let range = |a: usize| {
                        let lo = v[a].saturating_sub(1) / size;
                        let hi = ((v[a] + 1) / size).min(nb[a] - 1);
                        lo..=hi
                    };
                    for bz in range(2) {
                        for by in range(1) {
                            for bx in range(0) {
                                let bound = grid.sigma([bx, by, bz], &unit);
                                assert!(
                                    bound >= f64::from(rho),
                                    "brick {bx},{by},{bz} of {size}³: ρ̄ {bound} < voxel {v:?} ρ {rho}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }
}

/// A ray of the tests: start (world mm), direction (unnormalised) and what it exercises.
fn rays() -> Vec<(DVec3, DVec3, &'static str)> {
    vec![
        (
            DVec3::new(-60.0, 1.0, 1.0),
            DVec3::X,
            "along x, through air, lung, bone",
        ),
        (DVec3::new(3.0, -60.0, -3.0), DVec3::Y, "along y"),
        (DVec3::new(-20.0, -14.0, -60.0), DVec3::Z, "along z"),
        (
            DVec3::new(-24.0, -20.0, -16.0),
            DVec3::new(48.0, 40.0, 32.0),
            "corner to corner",
        ),
        // x = 8 mm is voxel plane 16: a face of 8³ and 16³ bricks.
        (DVec3::new(8.0, -60.0, 0.5), DVec3::Y, "in a brick face"),
        (
            DVec3::new(0.3, 0.2, -0.1),
            DVec3::new(1.0, -0.4, 0.7),
            "from inside",
        ),
        (
            DVec3::new(-40.0, -30.0, 12.0),
            DVec3::new(1.0, 0.8, -0.2),
            "oblique",
        ),
    ]
}

/// Both trackers: per-brick (8³, 3³) and global.
fn media() -> Vec<(Medium, &'static str)> {
    let comp = phantom();
    let base = Medium::new(&comp, &materials(), 150.0).unwrap();
    vec![
        (base.clone(), "bricks 8³"),
        (
            base.clone().with_majorant_bricks(Some(3)).unwrap(),
            "bricks 3³",
        ),
        (base.with_majorant_bricks(None).unwrap(), "global"),
    ]
}

fn binomial_z(count: usize, n: usize, p: f64) -> f64 {
    let n = n as f64;
    if p <= 0.0 || p >= 1.0 {
        return if (count as f64 - n * p).abs() < 0.5 {
            0.0
        } else {
            f64::INFINITY
        };
    }
    (count as f64 - n * p) / (n * p * (1.0 - p)).sqrt()
}

#[test]
fn the_no_collision_probability_is_beer_lambert_along_the_exact_path() {
    for (medium, tracker) in media() {
        for (seed, (p, d, what)) in rays().into_iter().enumerate() {
            let d = d.normalize();
            for e in [40.0, 100.0] {
                let sums = medium.paths(p, p + d * 500.0);
                let expected = medium.transmission(&sums, e);
                let mut rng = ChaCha8Rng::seed_from_u64(seed as u64 * 1000 + e as u64);
                let through = (0..PHOTONS)
                    .filter(|_| medium.fly(p, d, e, &mut rng).is_none())
                    .count();
                let z = binomial_z(through, PHOTONS, expected);
                assert!(
                    z.abs() <= Z_MAX,
                    "{tracker}, {what}, {e} keV: {through} of {PHOTONS} uncollided, \
                     expected exp(−τ) = {expected:.4} (z = {z:.2})"
                );
            }
        }
    }
}

#[test]
fn first_collisions_follow_the_optical_depth() {
    // Bins of optical depth τ(t) = ∫₀ᵗ μ: each of the five quantiles of the uncollided
    // decay up to the exit holds the same probability (1 − e^{−τ_exit})/5.
    for (medium, tracker) in media() {
        for (seed, (p, d, what)) in rays().into_iter().enumerate() {
            let d = d.normalize();
            let e = 60.0;
            let tau = |t: f64| -medium.transmission(&medium.paths(p, p + d * t), e).ln();
            let tau_exit = tau(500.0);
            if tau_exit < 0.05 {
                continue;
            }
            let bins = 5;
            let mut counts = vec![0usize; bins];
            let mut rng = ChaCha8Rng::seed_from_u64(7 + seed as u64);
            let p_bin = (1.0 - (-tau_exit).exp()) / bins as f64;
            for _ in 0..PHOTONS {
                if let Some(c) = medium.fly(p, d, e, &mut rng) {
                    let survive = (-tau((c.position - p).length())).exp();
                    let b = (((1.0 - survive) / p_bin) as usize).min(bins - 1);
                    counts[b] += 1;
                }
            }
            for (b, &c) in counts.iter().enumerate() {
                let z = binomial_z(c, PHOTONS, p_bin);
                assert!(
                    z.abs() <= Z_MAX,
                    "{tracker}, {what}: bin {b} of τ holds {c} first collisions, expected \
                     {:.0} (z = {z:.2}; counts {counts:?})",
                    p_bin * PHOTONS as f64
                );
            }
        }
    }
}

#[test]
fn a_zero_brick_size_is_refused() {
    let comp = phantom();
    let err = MajorantGrid::build(comp.packed(), 3, 0).unwrap_err();
    assert!(err.to_string().contains("brick size"), "{err}");
    let medium = Medium::new(&comp, &materials(), 150.0).unwrap();
    assert!(medium.with_majorant_bricks(Some(0)).is_err());
}

#[test]
fn forced_collisions_sit_at_the_optical_depth_they_were_given() {
    let medium = Medium::new(&phantom(), &materials(), 150.0).unwrap();
    let mut scratch = Vec::new();
    for (p, d, what) in rays() {
        let d = d.normalize();
        for e in [40.0, 100.0] {
            let tau = |t: f64| -medium.transmission(&medium.paths(p, p + d * t), e).ln();
            let tau_exit = tau(500.0);
            let expected = -(-tau_exit).exp_m1();
            if tau_exit == 0.0 {
                // Air alone on the chord (the "along z" ray): nothing to force.
                assert!(
                    medium.fly_forced(p, d, e, 0.5, &mut scratch).is_none(),
                    "{what}"
                );
                continue;
            }
            for u in [0.0, 0.001, 0.25, 0.5, 0.75, 0.999, 1.0 - 1e-12] {
                let (c, p_collide) = medium
                    .fly_forced(p, d, e, u, &mut scratch)
                    .unwrap_or_else(|| panic!("{what}: the chord crosses matter"));
                assert!(
                    (p_collide - expected).abs() <= 1e-9 * expected,
                    "{what}, {e} keV: P = {p_collide}, 1 − exp(−τ) = {expected}"
                );
                let t = (c.position - p).dot(d);
                assert!(
                    (c.position - (p + d * t)).length() < 1e-9,
                    "{what}: off the ray"
                );
                let want = -(-u * expected).ln_1p();
                assert!(
                    (tau(t) - want).abs() <= 1e-9 * (1.0 + tau_exit),
                    "{what}, {e} keV, u = {u}: τ at the collision {} against {want}",
                    tau(t)
                );
                assert_eq!(c.energy_kev, e);
                let sum = c.p_photo + c.p_compton + c.p_rayleigh;
                assert!((sum - 1.0).abs() < 1e-12 && c.p_compton > 0.0);
            }
        }
    }
    // No matter on the chord, or no chord: no collision to force.
    let air = DVec3::new(-20.0, -60.0, 0.5);
    assert!(
        medium
            .fly_forced(air, DVec3::Y, 60.0, 0.5, &mut scratch)
            .is_none()
    );
    let miss = DVec3::new(0.0, 0.0, 100.0);
    assert!(
        medium
            .fly_forced(miss, DVec3::X, 60.0, 0.5, &mut scratch)
            .is_none()
    );
}
