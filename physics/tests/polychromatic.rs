//! Polychromatic integration against closed forms.
//!
//! * A single-material slab: the traced, integrated signal equals the polychromatic
//!   Beer–Lambert sum Σ_b N_b·w_b·exp(−(μ/ρ)(E_b)·ρT) written out here from the material
//!   table. Tolerance 2e-5 relative: the composition stores densities to 2e-6 relative,
//!   which moves an exponent of ~5 by 1e-5.
//! * Beam hardening: the effective attenuation falls and the mean transmitted energy
//!   rises with thickness, both equal to their closed forms written out here in f64, to
//!   the f32 kernel's stated precision ([`f32_bound`]).
//! * Monochromatic at the calibration energy: equals the monochromatic projector (the
//!   tissue model's densities are calibrated for exactly that), for the water model and the
//!   Schneider model. Tolerance 2e-5 relative + 1e-6 absolute (f32 images, f32 densities).
//! * Units: photons per pixel for a stated fluence, mAs, SID and pitch, with inverse-square
//!   and obliquity fall-off, against hand-computed numbers.

use glam::{DMat3, DVec3};
use tomograf_physics::detector::{ChannelWeights, DetectorModel, Mode};
use tomograf_physics::polychromatic::SpectralIntegrator;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::composition::Composition;
use tomograf_sim::material::{self, Material};
use tomograf_sim::phantom::Phantom;
use tomograf_sim::render::MassThickness;
use tomograf_sim::tissue::TissueModel;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Renderer, View, Volume};

/// A Kramers-like spectrum 20–`kvp` keV in 1 keV bins (photons per mAs per mm² at 1 m).
fn spectrum(kvp: f64) -> (Vec<f64>, Vec<f64>) {
    let e: Vec<f64> = (20..kvp as usize).map(|e| e as f64 + 0.5).collect();
    let n = e.iter().map(|e| 1e4 * (kvp - e) / e).collect();
    (e, n)
}

/// The relative precision the integrator states for its f32 kernel
/// (`tomograf_physics::polychromatic`): each bin's transmission is exact to (τ_b + 2)·2⁻²³
/// relative, and rounding the weights, attenuations and partial sums to f32 adds ≈ 2·2⁻²⁴;
/// over a sum, the bins' bounds weighted by their contributions `c_b`.
fn f32_bound(tau: &[f64], c: &[f64]) -> f64 {
    let total: f64 = c.iter().sum();
    let weighted: f64 = tau.iter().zip(c).map(|(t, c)| (t + 3.0) * c).sum();
    weighted / total * 2f64.powi(-23)
}

fn weights(mode: Mode, energies: &[f64]) -> ChannelWeights {
    let d = DetectorModel {
        mode,
        ..DetectorModel::ideal()
    };
    d.channel_weights(energies, &vec![1.0; energies.len()])
        .unwrap()
}

fn integrator(m: &Material, kvp: f64, mode: Mode) -> SpectralIntegrator {
    let (e, n) = spectrum(kvp);
    let att = e.iter().map(|&e| m.mass_attenuation(e).unwrap()).collect();
    let w = weights(mode, &e);
    SpectralIntegrator::new(e, &n, vec![(m.name().to_string(), att)], &w).unwrap()
}

#[test]
fn slab_matches_closed_form_beer_lambert_sum() {
    let al = material::by_name("aluminium").unwrap();
    let rho = al.density();
    // A 20 mm slab along y: 10 voxels of 2 mm; parallel beam along +y.
    let dims = [8, 10, 8];
    let grid = |v: f32| {
        Volume::new(
            dims,
            DVec3::splat(2.0),
            DVec3::ZERO,
            DMat3::IDENTITY,
            vec![v; 640],
        )
        .unwrap()
    };
    let comp =
        Composition::from_labels(&grid(0.0), &grid(rho as f32), vec!["aluminium".into()]).unwrap();
    let g = Geometry {
        beam: Beam::Parallel,
        detector: Detector::new(4, 4, 2.0),
        isocentre: comp.packed().centre(),
    };
    let view = g.view(Pose::new(0.0, 0.0)).unwrap();
    let t = Renderer::for_composition(&comp, Projector::Siddon)
        .unwrap()
        .mass_thickness(&view, comp.materials())
        .unwrap();
    let integ = integrator(&al, 120.0, Mode::energy_integrating(1.0));
    let img = integ.expected(&t, &view, 2.0).unwrap();
    let (e, n) = spectrum(120.0);
    let area = 4.0; // 2 mm × 2 mm pixels, beam normal to the panel
    let thickness_g_cm2 = rho * 20.0 / 10.0;
    let closed: f64 = e
        .iter()
        .zip(&n)
        .map(|(&e, &n)| n * e * (-al.mass_attenuation(e).unwrap() * thickness_g_cm2).exp())
        .sum::<f64>()
        * 2.0
        * area;
    for &v in &img.mean {
        assert!(((v - closed) / closed).abs() < 2e-5, "{v} vs {closed}");
    }
}

#[test]
fn beam_hardening_follows_closed_form() {
    let water = material::by_name("water").unwrap();
    let ei = integrator(&water, 100.0, Mode::energy_integrating(1.0));
    let pc = integrator(
        &water,
        100.0,
        Mode::PhotonCounting {
            thresholds_kev: vec![0.0],
        },
    );
    let (e, n) = spectrum(100.0);
    let att: Vec<f64> = e
        .iter()
        .map(|&e| water.mass_attenuation(e).unwrap())
        .collect();
    let sum = |f: &dyn Fn(usize) -> f64| (0..e.len()).map(f).sum::<f64>();
    let open_ei = ei.unattenuated()[0];
    let (mut last_mu, mut last_mean) = (f64::INFINITY, 0.0);
    for t_cm in [0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 30.0] {
        let (mut m_ei, mut m_pc, mut s) = ([0.0], [0.0], [0.0]);
        ei.pixel(&[t_cm], &mut m_ei, &mut s);
        pc.pixel(&[t_cm], &mut m_pc, &mut s);
        let mu_eff = -(m_ei[0] / open_ei).ln() / t_cm;
        let mean_e = m_ei[0] / m_pc[0];
        let closed_ei = sum(&|b| n[b] * e[b] * (-att[b] * t_cm).exp());
        let closed_pc = sum(&|b| n[b] * (-att[b] * t_cm).exp());
        let closed_mu = -(closed_ei / sum(&|b| n[b] * e[b])).ln() / t_cm;
        let tau: Vec<f64> = att.iter().map(|a| a * t_cm).collect();
        let contrib = |w: &dyn Fn(usize) -> f64| -> Vec<f64> {
            (0..e.len()).map(|b| w(b) * (-tau[b]).exp()).collect()
        };
        let tol_ei = f32_bound(&tau, &contrib(&|b| n[b] * e[b]));
        let tol_pc = f32_bound(&tau, &contrib(&|b| n[b]));
        assert!(
            (m_ei[0] / closed_ei - 1.0).abs() < tol_ei,
            "{t_cm}: {}",
            m_ei[0]
        );
        assert!(
            (m_pc[0] / closed_pc - 1.0).abs() < tol_pc,
            "{t_cm}: {}",
            m_pc[0]
        );
        // −ln(I/I0)/t moves by the signal's relative error over μ_eff·t.
        assert!(
            (mu_eff / closed_mu - 1.0).abs() < tol_ei / (closed_mu * t_cm),
            "{t_cm}: {mu_eff} vs {closed_mu}"
        );
        assert!((mean_e / (closed_ei / closed_pc) - 1.0).abs() < tol_ei + tol_pc);
        assert!(mu_eff < last_mu, "effective mu must fall with thickness");
        assert!(mean_e > last_mean, "mean energy must rise with thickness");
        (last_mu, last_mean) = (mu_eff, mean_e);
    }
    // Hardening is large through 30 cm of water: the mean energy rises by > 10 keV.
    let (mut a, mut b, mut s) = ([0.0], [0.0], [0.0]);
    ei.pixel(&[0.0], &mut a, &mut s);
    pc.pixel(&[0.0], &mut b, &mut s);
    assert!(last_mean - a[0] / b[0] > 10.0);
}

/// The kernel takes bins in blocks of 16, padded with bins that must add exactly nothing:
/// every bin count from 1 to 33 (whole, partial and single blocks) and two materials, one
/// of them absent from the pixel, against the closed-form sum in f64, to the kernel's
/// stated precision ([`f32_bound`]; a padding bin of weight 1 would add ≥ 1e-3).
#[test]
fn every_bin_count_matches_closed_form() {
    let water = material::by_name("water").unwrap();
    let bone = material::by_name("cortical bone").unwrap();
    for bins in 1..=33 {
        let e: Vec<f64> = (0..bins).map(|b| 30.0 + 5.0 * b as f64).collect();
        let n: Vec<f64> = (0..bins).map(|b| 1e3 + 10.0 * b as f64).collect();
        let att = |m: &Material| e.iter().map(|&e| m.mass_attenuation(e).unwrap()).collect();
        let integ = SpectralIntegrator::new(
            e.clone(),
            &n,
            vec![("water".into(), att(&water)), ("bone".into(), att(&bone))],
            &weights(Mode::energy_integrating(1.0), &e),
        )
        .unwrap();
        for t in [[3.0, 0.0], [0.0, 1.5], [2.0, 0.7]] {
            let (mut mean, mut second) = ([0.0], [0.0]);
            integ.pixel(&t, &mut mean, &mut second);
            let tau: Vec<f64> = e
                .iter()
                .map(|&e| {
                    t[0] * water.mass_attenuation(e).unwrap()
                        + t[1] * bone.mass_attenuation(e).unwrap()
                })
                .collect();
            let contrib: Vec<f64> = (0..bins).map(|b| n[b] * e[b] * (-tau[b]).exp()).collect();
            let closed: f64 = contrib.iter().sum();
            assert!(
                (mean[0] / closed - 1.0).abs() < f32_bound(&tau, &contrib),
                "{bins} bins, t = {t:?}: {} vs {closed}",
                mean[0]
            );
        }
    }
}

fn mono_matches_projector(model: TissueModel) {
    let e_cal = model.calibration_kev;
    let hu = Phantom::thorax()
        .voxelize([48, 40, 24], DVec3::new(8.0, 8.0, 12.0), DVec3::ZERO)
        .unwrap();
    let (comp, materials) = model.composition(&hu).unwrap();
    let att = materials
        .iter()
        .map(|m| {
            (
                m.name().to_string(),
                vec![m.mass_attenuation(e_cal).unwrap()],
            )
        })
        .collect();
    let w = weights(Mode::energy_integrating(1.0), &[e_cal]);
    let integ = SpectralIntegrator::new(vec![e_cal], &[1e6], att, &w).unwrap();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(32, 40, 12.0),
        isocentre: DVec3::ZERO,
    };
    let mu = Attenuation::hounsfield_at_kev(e_cal)
        .unwrap()
        .to_mu(hu)
        .unwrap();
    for theta in [0.0, 90.0, 33.0] {
        let view = g.view(Pose::new(theta, 0.0)).unwrap();
        let t = Renderer::for_composition(&comp, Projector::Siddon)
            .unwrap()
            .mass_thickness(&view, comp.materials())
            .unwrap();
        let obj = integ.expected(&t, &view, 1.0).unwrap();
        let open = integ.open(&view, 1.0).unwrap();
        let reference = Renderer::new(&mu, Projector::Siddon)
            .unwrap()
            .render(&view)
            .unwrap();
        let mut max_l = 0.0f64;
        for (p, &r) in reference.data.iter().enumerate() {
            let l = -(obj.mean[p] / open.mean[p]).ln();
            let r = f64::from(r);
            max_l = max_l.max(r);
            assert!(
                (l - r).abs() <= 2e-5 * r + 1e-6,
                "{} θ={theta} pixel {p}: polychromatic-mono {l} vs projector {r}",
                materials.len()
            );
        }
        assert!(max_l > 2.0, "the view must cross the body");
    }
}

#[test]
fn monochromatic_water_model_equals_the_projector() {
    mono_matches_projector(TissueModel::water(60.0));
}

#[test]
fn monochromatic_schneider_at_calibration_energy_equals_the_projector() {
    mono_matches_projector(TissueModel::schneider());
}

#[test]
fn photons_per_pixel_follow_fluence_mas_distance_and_obliquity() {
    let water = material::by_name("water").unwrap();
    let w = weights(
        Mode::PhotonCounting {
            thresholds_kev: vec![0.0],
        },
        &[60.0],
    );
    // 1000 photons per mAs per mm² at 1 m, monoenergetic.
    let integ = SpectralIntegrator::new(
        vec![60.0],
        &[1000.0],
        vec![("water".into(), vec![water.mass_attenuation(60.0).unwrap()])],
        &w,
    )
    .unwrap();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(3, 3, 500.0),
        isocentre: DVec3::ZERO,
    };
    let view = g.view(Pose::new(0.0, 0.0)).unwrap();
    let open = integ.open(&view, 2.0).unwrap();
    // Centre pixel: 1000 · 2 mAs · 0.25 m² … in mm²: 500² mm² · (1000/1500)².
    let centre = 1000.0 * 2.0 * 500.0 * 500.0 * (1000.0f64 / 1500.0).powi(2);
    assert!(
        (open.mean[4] / centre - 1.0).abs() < 1e-12,
        "{}",
        open.mean[4]
    );
    // Corner pixel at 500√2 mm off axis: d² = 1500² + 2·500², cos γ = 1500/d.
    let d2 = 1500.0f64.powi(2) + 2.0 * 500.0f64.powi(2);
    let corner = 1000.0 * 2.0 * 500.0 * 500.0 * 1e6 / d2 * 1500.0 / d2.sqrt();
    assert!(
        (open.mean[0] / corner - 1.0).abs() < 1e-12,
        "{}",
        open.mean[0]
    );
    // Counting: the second moment equals the mean (Poisson).
    assert!((open.second_moment[0] / open.mean[0] - 1.0).abs() < 1e-12);
    // Nothing in the way: the expected image is the open field, pixel for pixel, and each
    // pixel through 1 g/cm² of water is it times exp(−μ/ρ).
    let t = |v: f64| MassThickness {
        rows: 3,
        cols: 3,
        materials: vec!["water".into()],
        data: vec![v; 9],
    };
    let zero = integ.expected(&t(0.0), &view, 2.0).unwrap();
    assert_eq!(zero.mean, open.mean);
    let through = integ.expected(&t(1.0), &view, 2.0).unwrap();
    let expected = (-water.mass_attenuation(60.0).unwrap()).exp();
    for (a, b) in through.mean.iter().zip(&open.mean) {
        assert!((a / b / expected - 1.0).abs() < 1e-6, "{a} / {b}");
    }
    // An image whose data does not match its size is refused, naming the counts.
    let mut short = t(1.0);
    short.data.pop();
    let e = integ.expected(&short, &view, 2.0).unwrap_err().to_string();
    assert!(
        e.contains("8 mass thicknesses") && e.contains("need 9"),
        "{e}"
    );
}

#[test]
fn bad_spectral_inputs_are_named() {
    let w = weights(Mode::energy_integrating(1.0), &[60.0]);
    let e = SpectralIntegrator::new(vec![60.0], &[f64::NAN], vec![], &w).unwrap_err();
    assert!(e.to_string().contains("NaN"), "{e}");
    let e =
        SpectralIntegrator::new(vec![60.0], &[1.0], vec![("x".into(), vec![])], &w).unwrap_err();
    assert!(e.to_string().contains("'x'"), "{e}");
    let e = TissueModel {
        calibration_kev: 70.0,
        bins: vec![],
        blend_hu: 0.0,
    }
    .validate()
    .unwrap_err();
    assert!(e.to_string().contains("0 HU intervals"), "{e}");
}

/// Spectra in any units: photon counts far outside f32's range (1e-40 or 1e35 per bin) give
/// the same signal as counts near 1, scaled — never 0, infinity or NaN (the kernel works
/// in f32 on moments divided by their largest bin). 1e-6: f32 rounding.
#[test]
fn spectra_far_outside_f32_range_scale_exactly() {
    let water = material::by_name("water").unwrap();
    let e: Vec<f64> = (0..10).map(|b| 30.0 + 8.0 * b as f64).collect();
    let att: Vec<f64> = e
        .iter()
        .map(|&e| water.mass_attenuation(e).unwrap())
        .collect();
    let at = |k: f64| {
        let n: Vec<f64> = (0..10).map(|b| k * (1.0 + b as f64)).collect();
        let integ = SpectralIntegrator::new(
            e.clone(),
            &n,
            vec![("water".into(), att.clone())],
            &weights(Mode::energy_integrating(1.0), &e),
        )
        .unwrap();
        let (mut mean, mut second) = ([0.0], [0.0]);
        integ.pixel(&[2.0], &mut mean, &mut second);
        (mean[0], second[0])
    };
    let one = at(1.0);
    for k in [1e-40, 1e35] {
        let (m, s) = at(k);
        assert!(
            m.is_finite() && m > 0.0 && s.is_finite() && s > 0.0,
            "{k}: {m}, {s}"
        );
        assert!(
            (m / (k * one.0) - 1.0).abs() < 1e-6,
            "{k}: {m} vs {}",
            k * one.0
        );
        assert!(
            (s / (k * one.1) - 1.0).abs() < 1e-6,
            "{k}: {s} vs {}",
            k * one.1
        );
    }
}

#[test]
fn orbit_jobs_share_one_column_copy_and_render_the_same() {
    // A physics job of 8 orbit views makes one k-fastest copy of the composition for all of
    // them (`Prepared::for_views`), whose column sheets give the per-ray tracers' images;
    // AP/PA jobs and tilted orbits make none.
    use tomograf_physics::acquisition::Acquisition;
    let hu = Phantom::thorax()
        .voxelize([48, 40, 24], DVec3::new(8.0, 8.0, 12.0), DVec3::ZERO)
        .unwrap();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(24, 30, 16.0),
        isocentre: DVec3::new(0.0123, 0.0456, 0.0078),
    };
    let views = |first: f64, step: f64, tilt: f64| -> Vec<View> {
        (0..8)
            .map(|n| g.view(Pose::new(first + step * n as f64, tilt)).unwrap())
            .collect()
    };
    let mut acq = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    acq.detector = DetectorModel::by_name("noiseless-csi", None).unwrap();
    let prepared = || acq.prepare(&hu, 1).unwrap();
    let orbit = views(20.0, 30.0, 0.0);
    let shared = prepared().for_views(Projector::Siddon, &orbit).unwrap();
    assert!(shared.shares_column_copy());
    let alone = prepared();
    assert!(!alone.shares_column_copy());
    for (i, v) in orbit.iter().enumerate() {
        let (a, b) = (
            shared.mass_thickness(Projector::Siddon, v).unwrap(),
            alone.mass_thickness(Projector::Siddon, v).unwrap(),
        );
        let total: f64 = b.data.iter().sum();
        assert!(total > 0.0);
        for (x, y) in a.data.iter().zip(&b.data) {
            assert!(
                (x - y).abs() <= 1e-9 * y.abs() + 1e-12,
                "view {i}: {x} vs {y}"
            );
        }
        let (a, b) = (
            shared.acquire(Projector::Siddon, v, i).unwrap(),
            alone.acquire(Projector::Siddon, v, i).unwrap(),
        );
        for (x, y) in a[0].data.iter().zip(&b[0].data) {
            assert!(
                (x - y).abs() <= 1e-5 * y.abs() + 1e-6,
                "view {i}: {x} vs {y}"
            );
        }
    }
    let none = |v: &[View]| {
        prepared()
            .for_views(Projector::Siddon, v)
            .unwrap()
            .shares_column_copy()
    };
    assert!(!none(&views(20.0, 30.0, 15.0)), "a tilted orbit");
    assert!(!none(&views(0.0, 180.0, 0.0)), "AP and PA views");
}
