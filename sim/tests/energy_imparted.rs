//! The energy-imparted (dose) tally against independent answers: energy conservation,
//! first-collision deposition of a pencil beam in a water slab against the attenuation
//! tables and a quadrature of Klein–Nishina written here, regions against the voxel map,
//! dose units, thread-count independence, and clear errors for bad input.

use glam::{DMat3, DVec3};
use tomograf_sim::composition::Composition;
use tomograf_sim::material::{self, Material};
use tomograf_sim::scatter::cross_sections::{incoherent_function, momentum_transfer};
use tomograf_sim::scatter::energy_imparted::{
    BeamSpectrum, JOULE_PER_EV, TallySettings, dose_gy, simulate,
};
use tomograf_sim::scatter::field::FieldSource;
use tomograf_sim::scatter::region::Region;
use tomograf_sim::scatter::transport::Medium;
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
    let s_water = |mu: f64| {
        let q = momentum_transfer(e, mu);
        water()
            .composition()
            .iter()
            .map(|&(z, w)| {
                w / material::element(z).unwrap().atomic_mass_u * incoherent_function(z, q).unwrap()
            })
            .sum::<f64>()
    };
    let want =
        e * 1000.0 * interacting * (x.photoelectric + x.incoherent * transfer_fraction(e, s_water))
            / x.total();
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
    let beam = BeamSpectrum::new(vec![30.0, 60.0, 90.0], &[1.0, 2.0, 1.0]).unwrap();
    let source = FieldSource::new(
        DVec3::new(0.0, 0.0, -500.0),
        DVec3::ZERO,
        DVec3::X * 10.0,
        DVec3::Y * 10.0,
    )
    .unwrap();
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
