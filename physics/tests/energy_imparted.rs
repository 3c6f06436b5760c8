//! The energy-imparted (dose) tally against independent answers: energy conservation,
//! first-collision deposition of a pencil beam in a water slab against the attenuation
//! tables and a quadrature of Klein–Nishina written here, regions against the voxel map,
//! dose units, thread-count independence, and clear errors for bad input.

use glam::{DMat3, DVec3};
use tomograf_physics::scatter::cross_sections::{incoherent_function, momentum_transfer};
use tomograf_physics::scatter::energy_imparted::{
    BeamSpectrum, JOULE_PER_EV, RegionEstimator, TallySettings, dose_gy, simulate,
};
use tomograf_physics::scatter::field::FieldSource;
use tomograf_physics::scatter::region::Region;
use tomograf_physics::scatter::transport::Medium;
use tomograf_sim::composition::Composition;
use tomograf_sim::material::{self, Material};
use tomograf_sim::volume::Volume;

fn water() -> Material {
    material::by_name("water").unwrap()
}

/// A water block: x, y ∈ [−20, 20] mm, z ∈ [0, 50] mm, 4 × 4 × 25 voxels.
fn block() -> Medium {
    let dims = [4, 4, 25];
    let n = dims.iter().product();
    let grid = |v: f32| {
        Volume::new(
            dims,
            DVec3::new(10.0, 10.0, 2.0),
            DVec3::new(-15.0, -15.0, 1.0),
            DMat3::IDENTITY,
            vec![v; n],
        )
        .unwrap()
    };
    let c = Composition::from_labels(&grid(0.0), &grid(1.0), vec!["water".into()]).unwrap();
    Medium::new(&c, &[water()], 150.0).unwrap()
}

/// A pencil beam along +z from z = −1000 mm onto the block's entrance face.
fn pencil() -> FieldSource {
    FieldSource::new(
        DVec3::new(0.0, 0.0, -1000.0),
        DVec3::ZERO,
        DVec3::X * 0.01,
        DVec3::Y * 0.01,
    )
    .unwrap()
}

/// A 20 × 20 mm field on the block's entrance face from 500 mm.
fn field_20mm() -> FieldSource {
    FieldSource::new(
        DVec3::new(0.0, 0.0, -500.0),
        DVec3::ZERO,
        DVec3::X * 10.0,
        DVec3::Y * 10.0,
    )
    .unwrap()
}

/// 30, 60 and 90 keV photons in the ratio 1 : 2 : 1.
fn three_lines() -> BeamSpectrum {
    BeamSpectrum::new(vec![30.0, 60.0, 90.0], &[1.0, 2.0, 1.0]).unwrap()
}

/// Mean fraction of the photon energy given to the electron in a Compton scatter,
/// ⟨T/E⟩ = ∫ (1 − E′/E) S(x) dσ_KN / ∫ S(x) dσ_KN, by Simpson's rule over cos θ, written
/// here from the Klein–Nishina formula; `s(mu)` is the incoherent scattering function
/// (1: a free electron at rest).
fn transfer_fraction(e_kev: f64, s: impl Fn(f64) -> f64) -> f64 {
    let k = e_kev / 510.998_95;
    let n = 20_000;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..=n {
        let mu = -1.0 + 2.0 * i as f64 / n as f64;
        let r = 1.0 / (1.0 + k * (1.0 - mu));
        let ds = r * r * (r + 1.0 / r - (1.0 - mu * mu)) * s(mu);
        let w = if i == 0 || i == n {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        };
        num += w * ds * (1.0 - r);
        den += w * ds;
    }
    num / den
}

#[test]
fn first_collision_deposition_in_a_water_slab_matches_the_tables() {
    // Only the first interaction deposits (max_collisions = 1): per photon
    // E·(1 − e^{−μt})·[μ_pe + μ_inc·⟨T/E⟩]/μ, with ⟨T/E⟩ from Klein–Nishina × S, S of
    // water mixed from the published per-element functions (Σ wᵢ/Aᵢ Sᵢ). Tolerance: 4
    // standard errors plus 0.2 % for the sampler's 1 keV table interpolation.
    let medium = block();
    let e = 100.0;
    let settings = TallySettings {
        photons: 1_000_000,
        max_collisions: 1,
        voxel_map: false,
        ..TallySettings::default()
    };
    let r = simulate(
        &medium,
        &pencil(),
        &BeamSpectrum::monoenergetic(e).unwrap(),
        &[],
        settings,
        7,
    )
    .unwrap();
    let x = water().interactions(e).unwrap();
    let mu = x.total() * 1.0 / 10.0; // mm⁻¹ at 1 g/cm³
    let interacting = 1.0 - (-mu * 50.0).exp();
    let want = e * 1000.0 * interacting * water_deposition(e) / x.total();
    let got = r.deposited.ev_per_photon;
    eprintln!(
        "first collision: {got:.2} ± {:.2} eV, analytic {want:.2}",
        r.deposited.standard_error
    );
    let tol = 4.0 * r.deposited.standard_error + 0.002 * want;
    assert!(
        (got - want).abs() < tol,
        "deposited {got:.3} eV/photon, analytic {want:.3} (±{tol:.3})"
    );
    // A sanity bound on the quadrature itself: at 100 keV the Compton electron takes
    // about 14 % of the photon energy on average (Attix, Table 7.2 gives σ_tr/σ ≈ 0.138).
    let f = transfer_fraction(100.0, |_| 1.0);
    assert!((f - 0.138).abs() < 0.003, "⟨T/E⟩ = {f}");
}

#[test]
fn energy_is_conserved_and_regions_agree_with_the_voxel_map() {
    let medium = block();
    let beam = three_lines();
    let source = field_20mm();
    let whole = Region::cube(
        "whole",
        DVec3::new(0.0, 0.0, 25.0),
        DVec3::new(40.0, 40.0, 50.0),
    );
    let front = Region::cube(
        "front",
        DVec3::new(0.0, 0.0, 5.0),
        DVec3::new(40.0, 40.0, 10.0),
    );
    let r = simulate(
        &medium,
        &source,
        &beam,
        &[whole, front],
        TallySettings {
            photons: 100_000,
            ..TallySettings::default()
        },
        3,
    )
    .unwrap();
    assert_eq!(r.source_ev, 60_000.0);
    let (diff, se) = r.balance();
    assert!(diff.abs() < 4.0 * se.max(1e-9), "balance {diff} ± {se} eV");
    assert!(
        r.stopped.ev_per_photon == 0.0,
        "no history reaches 1000 collisions"
    );
    assert!(r.escaped.ev_per_photon > 0.0 && r.deposited.ev_per_photon > 0.0);
    // The whole-block region scores every deposit; the voxel map sums to the same.
    let whole_ev = r.regions[0].1.ev_per_photon;
    let map: f64 = r.voxel_ev.iter().sum();
    assert!((whole_ev - r.deposited.ev_per_photon).abs() < 1e-9 * whole_ev);
    assert!((map - whole_ev).abs() < 1e-9 * whole_ev);
    // The first 10 mm are the first 5 voxel layers (4 × 4 each).
    let front_map: f64 = r.voxel_ev[..4 * 4 * 5].iter().sum();
    assert!((front_map - r.regions[1].1.ev_per_photon).abs() < 1e-9 * front_map);
}

#[test]
fn dose_is_energy_over_mass() {
    let medium = block();
    let mut ev = vec![0.0; 4 * 4 * 25];
    ev[0] = 1.0e6; // 1 MeV per source photon in voxel 0 (10 × 10 × 2 mm of water: 0.2 g)
    let d = dose_gy(&medium, &ev, 1.0e9).unwrap();
    let want = 1.0e6 * 1.0e9 * JOULE_PER_EV / 0.2e-3;
    assert!(
        (f64::from(d[0]) - want).abs() < 1e-6 * want,
        "{} vs {want}",
        d[0]
    );
    assert!(d[1..].iter().all(|&v| v == 0.0));
    assert!(dose_gy(&medium, &ev[1..], 1.0).is_err());
    assert!(dose_gy(&medium, &ev, f64::NAN).is_err());
}

#[test]
fn bytes_do_not_depend_on_the_thread_count() {
    let medium = block();
    let beam = BeamSpectrum::monoenergetic(56.4).unwrap();
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                simulate(
                    &medium,
                    &pencil(),
                    &beam,
                    &[],
                    TallySettings {
                        photons: 20_000,
                        ..TallySettings::default()
                    },
                    11,
                )
                .unwrap()
            })
    };
    let (a, b) = (run(1), run(2));
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.voxel_ev), bits(&b.voxel_ev));
    assert_eq!(
        a.deposited.ev_per_photon.to_bits(),
        b.deposited.ev_per_photon.to_bits()
    );
}

#[test]
fn bad_inputs_give_clear_errors() {
    let medium = block();
    let beam = BeamSpectrum::monoenergetic(60.0).unwrap();
    let zero = TallySettings {
        photons: 0,
        ..TallySettings::default()
    };
    let err = simulate(&medium, &pencil(), &beam, &[], zero, 0).unwrap_err();
    assert!(err.to_string().contains("photons = 0"), "{err}");
    let hot = BeamSpectrum::monoenergetic(200.0).unwrap();
    let err = simulate(&medium, &pencil(), &hot, &[], TallySettings::default(), 0).unwrap_err();
    assert!(err.to_string().contains("200 keV"), "{err}");
    let flat = Region::cube("flat", DVec3::ZERO, DVec3::new(1.0, 1.0, 0.0));
    let err = simulate(
        &medium,
        &pencil(),
        &beam,
        &[flat],
        TallySettings::default(),
        0,
    )
    .unwrap_err();
    assert!(err.to_string().contains("'flat'"), "{err}");
    assert!(BeamSpectrum::monoenergetic(0.5).is_err());
    assert!(BeamSpectrum::new(vec![50.0], &[0.0]).is_err());
    assert!(BeamSpectrum::new(vec![50.0, 60.0], &[1.0]).is_err());
}

#[test]
fn acquisition_dose_in_a_thin_slab_is_its_kerma() {
    // A 2 × 2 × 0.5 mm slab of the preset's 0 HU tissue at 1 m from the source, exactly
    // the field there (the detector, 2.2 × 2.2 mm at 1.1 m): the dose is the collision kerma of the primary fluence,
    // Σ_b Φ_b E_b (μ_en/ρ)_b, with Φ_b the spectrum's photons per mm² at 1 m for the
    // preset's mAs (times the slab's mean primary transmission), and μ_en/ρ = μ_pe/ρ +
    // μ_inc/ρ·⟨T/E⟩ from the tables and the KN × S quadrature above (no fluorescence, as
    // the tally). What this checks end to end: photons per mAs, the field's solid angle,
    // eV → J and the voxel mass. The slab also absorbs some of its own scatter, which the
    // collision kerma leaves out: measured with the tally's first-collision mode, 1.4–1.6 %
    // more at 20–25 keV and 0.3–0.6 % above 40 keV in this slab. So the dose must lie in
    // [kerma, kerma × 1.02], widened by 4 standard errors (the spread of the views' doses):
    // a wrong unit or factor anywhere in the chain moves it far outside.
    use tomograf_physics::acquisition::Acquisition;
    use tomograf_sim::geometry::View;
    use tomograf_sim::geometry::ViewBeam;
    let acq = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    let hu = Volume::new(
        [2, 2, 1],
        DVec3::new(1.0, 1.0, 0.5),
        DVec3::new(-0.5, -0.5, 1000.25),
        DMat3::IDENTITY,
        vec![0.0; 4],
    )
    .unwrap();
    let view = View {
        beam: ViewBeam::Cone {
            source: DVec3::ZERO,
        },
        detector_origin: DVec3::new(-1.0, -1.0, 1100.0),
        u: DVec3::X * 0.2,
        v: DVec3::Y * 0.2,
        rows: 11,
        cols: 11,
    };
    // Each view alone, to see the spread, then all eight in one call.
    let single: Vec<f64> = (0..8)
        .map(|k| {
            let d = acq.dose(&hu, &[view], 1_000_000, 100 + k).unwrap();
            d.gray.data().iter().map(|&v| f64::from(v)).sum::<f64>() / 4.0
        })
        .collect();
    let views = vec![view; 8];
    let dose = acq.dose(&hu, &views, 1_000_000, 5).unwrap();
    let (composition, materials) = acq.materials.composition(&hu).unwrap();
    let (rho, m) = tomograf_sim::composition::unpack(composition.packed().data()[0]);
    let material = &materials[m];
    let spectrum = acq.spectrum.spectrum().unwrap();
    let phi = spectrum.photons_per_mm2(acq.spectrum.mas, 1000.0).unwrap();
    let mut want = 0.0;
    for (&e, &n) in spectrum.energies_kev().iter().zip(&phi) {
        if n == 0.0 {
            continue;
        }
        let x = material.interactions(e).unwrap();
        let s = |mu: f64| {
            let q = momentum_transfer(e, mu);
            material
                .composition()
                .iter()
                .map(|&(z, w)| {
                    w / material::element(z).unwrap().atomic_mass_u
                        * incoherent_function(z, q).unwrap()
                })
                .sum::<f64>()
        };
        let muen = x.photoelectric + x.incoherent * transfer_fraction(e, s); // cm²/g
        let mu_mm = x.total() * f64::from(rho) / 10.0;
        let mean_transmission = (1.0 - (-mu_mm * 0.5).exp()) / (mu_mm * 0.5);
        // Φ per cm² · keV · cm²/g → keV/g → J/kg.
        want += n * 100.0 * mean_transmission * e * muen * 1.602_176_634e-16 * 1000.0;
    }
    want *= views.len() as f64;
    // Off the axis the fluence on the plane falls as cos³θ ≥ 0.99993 here: negligible.
    let got = dose.gray.data().iter().map(|&v| f64::from(v)).sum::<f64>() / 4.0;
    let m = single.iter().sum::<f64>() / 8.0;
    // Eight views summed: the standard error of the sum is √8 × the views' spread.
    let spread = (single.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 7.0).sqrt() * 8f64.sqrt();
    eprintln!("slab dose {got:.4e} Gy (±{spread:.2e}), kerma {want:.4e} Gy");
    assert!(
        got > want - 4.0 * spread && got < 1.02 * want + 4.0 * spread,
        "dose {got} Gy, collision kerma {want} Gy (± {spread})"
    );
    assert_eq!(dose.per_view.len(), 8);
    assert!(dose.energy_joule > 0.0);
    // Parallel views and zero photons are refused.
    let mut parallel = view;
    parallel.beam = ViewBeam::Parallel {
        direction: DVec3::Z,
    };
    assert!(acq.dose(&hu, &[parallel], 1000, 0).is_err());
    assert!(acq.dose(&hu, &views, 0, 0).is_err());
    assert!(acq.dose(&hu, &[], 10, 0).is_err());
}

/// The published per-element incoherent functions mixed for water (Σ wᵢ/Aᵢ Sᵢ), at
/// energy `e` keV and cos θ = `mu`.
fn s_water(e: f64, mu: f64) -> f64 {
    let q = momentum_transfer(e, mu);
    water()
        .composition()
        .iter()
        .map(|&(z, w)| {
            w / material::element(z).unwrap().atomic_mass_u * incoherent_function(z, q).unwrap()
        })
        .sum()
}

/// μ_pe/ρ + μ_inc/ρ·⟨T/E⟩ of water (cm²/g), from the tables and this file's quadrature.
fn water_deposition(e: f64) -> f64 {
    let x = water().interactions(e).unwrap();
    x.photoelectric + x.incoherent * transfer_fraction(e, |mu| s_water(e, mu))
}

#[test]
fn the_deposition_coefficient_is_photoelectric_plus_the_mean_compton_transfer() {
    // At the medium's 1 keV grid points its table holds the cross sections exactly; the
    // two quadratures (Simpson, 4096 and 20 000 intervals) agree far below 0.1 %.
    let medium = block();
    for e in [20.0, 56.0, 100.0, 140.0] {
        let got = medium.deposition_coefficient(0, e);
        let want = water_deposition(e);
        assert!(
            (got - want).abs() < 1e-3 * want,
            "{e} keV: {got} cm²/g, want {want}"
        );
    }
}

#[test]
fn track_length_first_flights_give_the_analytic_deposition() {
    // First flights only (max_collisions = 1): the track-length estimate of the whole
    // block is E·(μ_dep/ρ)·ρ·⟨ℓ⟩ with ⟨ℓ⟩ = (1 − e^{−μt})/μ, the same expectation as the
    // analog first-collision deposit, but each photon scores its own flight length, so its
    // standard error must be smaller than the analog one from the same histories.
    // Tolerance: 4 standard errors plus 0.2 % (1 keV table interpolation).
    let medium = block();
    let e = 100.0;
    let whole = Region::cube(
        "whole",
        DVec3::new(0.0, 0.0, 25.0),
        DVec3::new(40.0, 40.0, 50.0),
    );
    let r = simulate(
        &medium,
        &pencil(),
        &BeamSpectrum::monoenergetic(e).unwrap(),
        &[whole],
        TallySettings {
            photons: 200_000,
            max_collisions: 1,
            voxel_map: false,
            regions: RegionEstimator::TrackLength,
        },
        7,
    )
    .unwrap();
    let mu = water().interactions(e).unwrap().total() / 10.0; // mm⁻¹ at 1 g/cm³
    let mean_path_mm = (1.0 - (-mu * 50.0).exp()) / mu;
    let want = e * 1000.0 * water_deposition(e) * mean_path_mm / 10.0;
    let tl = r.regions[0].1;
    eprintln!(
        "track length {:.2} ± {:.3} eV, analog {:.2} ± {:.3}, analytic {want:.2}",
        tl.ev_per_photon, tl.standard_error, r.deposited.ev_per_photon, r.deposited.standard_error
    );
    let tol = 4.0 * tl.standard_error + 0.002 * want;
    assert!((tl.ev_per_photon - want).abs() < tol);
    assert!(tl.standard_error < 0.7 * r.deposited.standard_error);
}

#[test]
fn track_length_and_collision_estimators_agree_in_small_regions() {
    // Both estimators are unbiased for the same transport: in a thin slab across the beam,
    // a cylinder along x and a tilted one, with multiple scatter and a three-line
    // spectrum, they must agree within 4 combined standard errors, and the track-length
    // one must have the smaller error in each (few photons interact in a 2 mm slab).
    let medium = block();
    let beam = three_lines();
    let source = field_20mm();
    let regions = [
        Region::cube(
            "slab",
            DVec3::new(0.0, 0.0, 21.0),
            DVec3::new(40.0, 40.0, 2.0),
        ),
        Region::cylinder("along x", DVec3::new(0.0, 0.0, 30.0), DVec3::X, 3.0, 30.0),
        Region::cylinder(
            "tilted",
            DVec3::new(5.0, -5.0, 12.0),
            DVec3::new(1.0, 1.0, 1.0),
            4.0,
            12.0,
        ),
    ];
    let run = |estimator| {
        simulate(
            &medium,
            &source,
            &beam,
            &regions,
            TallySettings {
                photons: 200_000,
                voxel_map: false,
                regions: estimator,
                ..TallySettings::default()
            },
            21,
        )
        .unwrap()
    };
    let (analog, tl) = (
        run(RegionEstimator::Collision),
        run(RegionEstimator::TrackLength),
    );
    for ((name, a), (_, t)) in analog.regions.iter().zip(&tl.regions) {
        eprintln!(
            "{name}: collision {:.3} ± {:.3}, track length {:.3} ± {:.3} eV",
            a.ev_per_photon, a.standard_error, t.ev_per_photon, t.standard_error
        );
        let se = a.standard_error.hypot(t.standard_error);
        assert!(
            (a.ev_per_photon - t.ev_per_photon).abs() < 4.0 * se,
            "{name}: {} vs {} (± {se})",
            a.ev_per_photon,
            t.ev_per_photon
        );
        assert!(t.standard_error < a.standard_error, "{name}");
    }
    // The totals are scored at the interaction points either way: same histories, same bits.
    assert_eq!(
        analog.deposited.ev_per_photon.to_bits(),
        tl.deposited.ev_per_photon.to_bits()
    );
}

#[test]
fn region_chords_match_a_brute_force_walk() {
    // Exact cases: axis-parallel through a box, across and along a cylinder, and misses.
    let cube = Region::cube("c", DVec3::splat(0.5), DVec3::ONE);
    assert_eq!(
        cube.chord(DVec3::new(-100.0, 0.5, 0.5), DVec3::X, 0.0, f64::INFINITY),
        Some((100.0, 101.0))
    );
    assert_eq!(
        cube.chord(DVec3::new(-100.0, 0.5, 0.5), DVec3::X, 0.0, 100.5),
        Some((100.0, 100.5))
    );
    assert_eq!(
        cube.chord(DVec3::new(-100.0, 1.5, 0.5), DVec3::X, 0.0, f64::INFINITY),
        None
    );
    let cyl = Region::cylinder("z", DVec3::ZERO, DVec3::Z, 5.0, 100.0);
    let (t0, t1) = cyl
        .chord(DVec3::new(-100.0, 3.0, 0.0), DVec3::X, 0.0, f64::INFINITY)
        .unwrap();
    assert!((t0 - 96.0).abs() < 1e-12 && (t1 - 104.0).abs() < 1e-12);
    assert_eq!(
        cyl.chord(DVec3::new(1.0, 1.0, -100.0), DVec3::Z, 0.0, f64::INFINITY),
        Some((50.0, 150.0))
    );
    assert_eq!(
        cyl.chord(DVec3::new(6.0, 0.0, -100.0), DVec3::Z, 0.0, f64::INFINITY),
        None
    );
    assert_eq!(
        cyl.chord(DVec3::new(-100.0, 0.0, 51.0), DVec3::X, 0.0, f64::INFINITY),
        None
    );
    // Random lines against stepping `contains` in 1 µm steps.
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let regions = [
        Region::cylinder(
            "tilted",
            DVec3::new(1.0, -2.0, 0.5),
            DVec3::new(1.0, 2.0, -1.0),
            3.0,
            8.0,
        ),
        Region::cube("box", DVec3::new(0.5, 0.0, -1.0), DVec3::new(6.0, 3.0, 4.0)),
        Region::half_cylinder(
            "half",
            DVec3::new(0.5, 0.0, 0.5),
            DVec3::new(1.0, 2.0, -1.0),
            3.5,
            7.0,
            DVec3::new(2.0, -1.0, 0.0),
        ),
    ];
    for r in &regions {
        r.validate().unwrap();
    }
    let mut hits = 0;
    for _ in 0..400 {
        // From a point 8 mm out towards a point near the regions.
        let rand3 = |rng: &mut rand_chacha::ChaCha8Rng, a: f64| {
            DVec3::new(
                rng.random_range(-a..a),
                rng.random_range(-a..a),
                rng.random_range(-a..a),
            )
        };
        let p = rand3(&mut rng, 1.0).normalize() * 8.0;
        let d = (rand3(&mut rng, 3.0) - p).normalize();
        for r in &regions {
            let step = 1e-3;
            let inside = (0..16_000)
                .filter(|&i| r.contains(p + d * ((i as f64 + 0.5) * step)))
                .count() as f64
                * step;
            let chord = r.chord(p, d, 0.0, 16.0).map_or(0.0, |(t0, t1)| t1 - t0);
            hits += usize::from(chord > 0.0);
            assert!(
                (chord - inside).abs() < 3e-3,
                "{}: chord {chord}, walk {inside}",
                r.name
            );
        }
    }
    assert!(hits > 600, "only {hits} of 1200 lines hit a region");
}

#[test]
fn combined_regions_carry_their_covariance() {
    // Two halves of the block and the whole: with the collision estimator the whole's
    // batch tallies are exactly the halves' sums, so combine(half₁ + half₂) must give the
    // whole's mean and standard error (the latter only if the covariance is right: the
    // halves are correlated through shared histories), and half₁ twice with weight ½ is
    // half₁ itself.
    let medium = block();
    let beam = BeamSpectrum::monoenergetic(60.0).unwrap();
    let regions = [
        Region::cube(
            "front",
            DVec3::new(0.0, 0.0, 12.5),
            DVec3::new(40.0, 40.0, 25.0),
        ),
        Region::cube(
            "back",
            DVec3::new(0.0, 0.0, 37.5),
            DVec3::new(40.0, 40.0, 25.0),
        ),
        Region::cube(
            "whole",
            DVec3::new(0.0, 0.0, 25.0),
            DVec3::new(40.0, 40.0, 50.0),
        ),
    ];
    let r = simulate(
        &medium,
        &pencil(),
        &beam,
        &regions,
        TallySettings {
            photons: 50_000,
            voxel_map: false,
            ..TallySettings::default()
        },
        5,
    )
    .unwrap();
    let whole = r.regions[2].1;
    let sum = r.combine(&[(0, 1.0), (1, 1.0)]).unwrap();
    assert!((sum.ev_per_photon - whole.ev_per_photon).abs() < 1e-9 * whole.ev_per_photon);
    assert!(
        (sum.standard_error - whole.standard_error).abs() < 1e-6 * whole.standard_error,
        "{} vs {}",
        sum.standard_error,
        whole.standard_error
    );
    let independent = r.regions[0]
        .1
        .standard_error
        .hypot(r.regions[1].1.standard_error);
    eprintln!(
        "whole ± {:.4}, halves combined ± {:.4}, as if independent ± {independent:.4}",
        whole.standard_error, sum.standard_error
    );
    let same = r.combine(&[(0, 0.5), (0, 0.5)]).unwrap();
    assert!((same.standard_error - r.regions[0].1.standard_error).abs() < 1e-9);
    assert!(r.combine(&[(3, 1.0)]).is_err());
}
