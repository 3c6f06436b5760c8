//! The detector names a physicist picks, against closed forms written out here.
//!
//! * `perfect-absorber` (alias `ideal`) and `noiseless-csi` give the exact polychromatic
//!   −log of a water slab: Σ Φ·E·η·exp(−μ_w(E)·t) / Σ Φ·E·η, with η = 1 or
//!   η = 1 − exp(−μ_CsI(E)·0.6 mm) from the material tables. Tolerance 1e-4 relative: the
//!   f32 kernel and f32 images (≈ 1e-6) and the composition's density rounding (2e-6).
//! * Their difference is the scintillator's beam hardening alone; docs/detector.md quotes it.
//! * A monoenergetic beam at the default fluence and 1 mAs reads its exact line integral
//!   behind a thick, dense slab (a 1-photon default and a half-ADU floor on a noiseless
//!   detector clipped it at ln(2·flat)), and a
//!   photon-starved run is reported in [`Acquired::clipped`].

use glam::{DMat3, DVec3};
use tomograf_physics::acquisition::{Acquired, Acquisition, FilterSpec, SpectrumSpec};
use tomograf_physics::detector::{DetectorModel, Output, Readout};
use tomograf_physics::scatter::ScatterModel;
use tomograf_sim::material::by_name;
use tomograf_sim::tissue::TissueModel;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, View, Volume};

/// A `thickness_mm` slab of `hu` along y (the AP beam's direction), 40 × 40 mm across.
fn slab(hu: f32, thickness_mm: f64) -> Volume {
    let ny = 20;
    let dy = thickness_mm / ny as f64;
    Volume::new(
        [20, ny, 20],
        DVec3::new(2.0, dy, 2.0),
        DVec3::new(-19.0, -thickness_mm / 2.0 + dy / 2.0, -19.0),
        DMat3::IDENTITY,
        vec![hu; 20 * ny * 20],
    )
    .unwrap()
}

/// A parallel AP view of 4 × 4 pixels of 2 mm through the slab's middle.
fn view() -> View {
    Geometry {
        beam: Beam::Parallel,
        detector: Detector::new(4, 4, 2.0),
        isocentre: DVec3::ZERO,
    }
    .view(Pose::AP)
    .unwrap()
}

fn acquisition(spectrum: SpectrumSpec, detector: DetectorModel, e_cal: f64) -> Acquisition {
    Acquisition {
        spectrum,
        materials: TissueModel::water(e_cal),
        detector,
        output: Output::LogLineIntegral,
        scatter: ScatterModel::None,
        anti_scatter_grid: None,
    }
}

fn acquire(a: &Acquisition, hu: &Volume) -> Acquired {
    a.prepare(hu, 1)
        .unwrap()
        .acquire_with_parts(Projector::Siddon, &view(), 0)
        .unwrap()
}

/// −ln of the closed-form polychromatic transmission through `t_mm` of water (1 g/cm³),
/// energy-integrating with absorption η(E).
fn closed_form(spec: &SpectrumSpec, t_mm: f64, eta: impl Fn(f64) -> f64) -> f64 {
    let s = spec.spectrum().unwrap();
    let water = by_name("water").unwrap();
    let (mut num, mut den) = (0.0, 0.0);
    for (&e, &phi) in s.energies_kev().iter().zip(s.fluence()) {
        let w = phi * e * eta(e);
        num += w * (-water.mu_per_mm(e, 1.0).unwrap() * t_mm).exp();
        den += w;
    }
    -(num / den).ln()
}

#[test]
fn perfect_absorber_and_noiseless_csi_match_their_closed_forms() {
    let spec = SpectrumSpec {
        filtration: vec![FilterSpec {
            material: "al".into(),
            thickness_mm: 3.0,
        }],
        ..SpectrumSpec::tungsten(120.0, &[], 1.0)
    };
    let t = 200.0;
    let hu = slab(0.0, t);
    let csi = by_name("CsI").unwrap();
    let eta_csi = |e: f64| -(-csi.mu_per_mm(e, csi.density()).unwrap() * 0.6).exp_m1();
    let want_perfect = closed_form(&spec, t, |_| 1.0);
    let want_csi = closed_form(&spec, t, eta_csi);
    for (name, want) in [
        ("perfect-absorber", want_perfect),
        ("ideal", want_perfect),
        ("noiseless-csi", want_csi),
    ] {
        let d = DetectorModel::by_name(name, None).unwrap();
        assert!(!d.has_signal_unit(), "{name}");
        let got = acquire(&acquisition(spec.clone(), d, 70.0), &hu);
        assert_eq!(got.clipped, 0, "{name}");
        for &l in &got.images[0].data {
            let l = f64::from(l);
            assert!((l - want).abs() <= 1e-4 * want, "{name}: {l} vs {want}");
        }
    }
    // The scintillator hardens the recorded beam: η(E) falls with energy, so the CsI
    // panel weights the low, strongly attenuated energies more and reads more attenuation.
    let diff = want_csi / want_perfect - 1.0;
    println!(
        "200 mm water, 120 kVp + 3 mm Al: perfect absorber {want_perfect:.4}, noiseless CsI \
         {want_csi:.4} ({:+.2} %)",
        100.0 * diff
    );
    assert!((0.01..0.10).contains(&diff.abs()), "{diff}");
}

#[test]
fn a_monoenergetic_beam_at_default_settings_is_not_clipped() {
    // 100 mm of water at density 2 (HU 1000) at 30 keV: L ≈ 7.5, T ≈ 5e-4 (the old default
    // of 1 photon per mAs per mm² read ln(2·120) = 5.5 here).
    let spec = SpectrumSpec {
        kvp: None,
        energy_kev: Some(30.0),
        ..SpectrumSpec::tungsten(120.0, &[], 1.0)
    };
    let hu = slab(1000.0, 100.0);
    let want = by_name("water").unwrap().mu_per_mm(30.0, 2.0).unwrap() * 100.0;
    assert!(want > 7.0, "{want}");
    let got = acquire(
        &acquisition(spec.clone(), DetectorModel::ideal(), 30.0),
        &hu,
    );
    assert_eq!(got.clipped, 0);
    for &l in &got.images[0].data {
        assert!((f64::from(l) - want).abs() <= 1e-4 * want, "{l} vs {want}");
    }
    // A quarter photon per mAs per mm² on a detector with a signal unit (a 16-bit ADC,
    // 1 ADU per keV): one photon per 4 mm² pixel, T·open ≈ 0.02 ADU < 0.5 — clipped, and the
    // acquisition says so.
    let starved = SpectrumSpec {
        photons_per_mas_mm2: Some(0.25),
        ..spec
    };
    let adc = DetectorModel {
        readout: Readout {
            bits: Some(16),
            ..Readout::ideal()
        },
        ..DetectorModel::ideal()
    };
    let got = acquire(&acquisition(starved, adc, 30.0), &hu);
    assert_eq!(got.clipped, 16);
    assert!(f64::from(got.images[0].data[0]) < want - 0.3);
}

#[test]
fn detector_names_are_one_table_with_clear_errors() {
    for name in DetectorModel::NAMES {
        let d = DetectorModel::by_name(name, None).unwrap();
        d.validate().unwrap();
    }
    assert_eq!(
        DetectorModel::by_name("ideal", None).unwrap(),
        DetectorModel::by_name("perfect-absorber", None).unwrap()
    );
    let pc = DetectorModel::by_name("photon-counting", Some(vec![25.0, 50.0])).unwrap();
    assert_eq!(pc.channels(), 2);
    let e = DetectorModel::by_name("csi", None).unwrap_err().to_string();
    assert!(
        e.contains("unknown detector model 'csi'") && e.contains("noiseless-csi"),
        "{e}"
    );
    let e = DetectorModel::by_name("cbct", Some(vec![20.0]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("photon-counting detector model only"), "{e}");
    // The noisy presets keep the half-unit floor; the noiseless ones have none.
    assert!(DetectorModel::kv_flat_panel().has_signal_unit());
    assert!(!DetectorModel::noiseless_csi().has_signal_unit());
}

#[test]
fn the_default_monoenergetic_fluence_is_a_clinical_beams_order() {
    let preset = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    let photons = preset.spectrum.spectrum().unwrap().total_fluence();
    let ratio = tomograf_physics::acquisition::MONOENERGETIC_FLUENCE / photons;
    println!("kv-flat-panel-120kvp beam: {photons:.3e} photons/mAs/mm² at 1 m; ratio {ratio:.2}");
    assert!((1.0 / 3.0..3.0).contains(&ratio), "{ratio}");
}
