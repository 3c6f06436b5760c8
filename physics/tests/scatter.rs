//! Scatter physics checks against independent references: sampled angular distributions vs
//! Klein–Nishina × S and Thomson × F² evaluated here from the published factors (χ²),
//! photon conservation and Beer–Lambert transmission, single scatter in a thin water slab
//! vs a numerical quadrature of the single-scatter integral, thread-count independence,
//! and clear errors for bad settings.

use glam::{DMat3, DVec3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use tomograf_physics::scatter::cross_sections::{
    ScatterFactors, form_factor, incoherent_function, klein_nishina, momentum_transfer,
};
use tomograf_physics::scatter::estimator::Response;
use tomograf_physics::scatter::transport::{Fate, Medium};
use tomograf_physics::scatter::{AntiScatterGrid, Histories, ScatterEngine, ScatterModel};
use tomograf_sim::View;
use tomograf_sim::composition::Composition;
use tomograf_sim::geometry::ViewBeam;
use tomograf_sim::material::{self, Material};
use tomograf_sim::volume::Volume;

const SLAB_MM: f64 = 10.0;

fn water() -> Material {
    material::by_name("water").unwrap()
}

/// A water slab: x, y ∈ [−100, 100] mm, z ∈ [0, 10] mm.
fn slab() -> Composition {
    let dims = [40, 40, 10];
    let n = dims.iter().product();
    let grid = |v: f32| {
        Volume::new(
            dims,
            DVec3::new(5.0, 5.0, 1.0),
            DVec3::new(-97.5, -97.5, 0.5),
            DMat3::IDENTITY,
            vec![v; n],
        )
        .unwrap()
    };
    Composition::from_labels(&grid(0.0), &grid(1.0), vec!["water".into()]).unwrap()
}

/// Mixture factor Σ (wᵢ/Aᵢ) gᵢ(x) over water's elements.
fn mix(x: f64, g: impl Fn(u8, f64) -> f64) -> f64 {
    water()
        .composition()
        .iter()
        .map(|&(z, w)| w / material::element(z).unwrap().atomic_mass_u * g(z, x))
        .sum()
}

/// Expected probability of μ in each of `bins` equal bins for the density ∝ f(μ), by a
/// 400-point midpoint rule per bin.
fn bin_probabilities(bins: usize, f: impl Fn(f64) -> f64) -> Vec<f64> {
    let per = 400;
    let h = 2.0 / (bins * per) as f64;
    let raw: Vec<f64> = (0..bins)
        .map(|b| {
            (0..per)
                .map(|i| f(-1.0 + ((b * per + i) as f64 + 0.5) * h) * h)
                .sum()
        })
        .collect();
    let total: f64 = raw.iter().sum();
    raw.iter().map(|r| r / total).collect()
}

/// χ² of counts against probabilities; asserts it is below the 99.9th percentile for
/// `bins − 1` degrees of freedom (Wilson–Hilferty).
fn assert_chi2(counts: &[u64], probs: &[f64], what: &str) {
    let n: u64 = counts.iter().sum();
    let chi2: f64 = counts
        .iter()
        .zip(probs)
        .map(|(&c, &p)| (c as f64 - n as f64 * p).powi(2) / (n as f64 * p))
        .sum();
    let k = (counts.len() - 1) as f64;
    let z = 3.09; // one-sided 99.9 %
    let limit = k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3);
    assert!(
        chi2 < limit,
        "{what}: χ² = {chi2:.1} > {limit:.1} ({k} dof)"
    );
}

fn histogram(samples: impl Iterator<Item = f64>, bins: usize) -> Vec<u64> {
    let mut h = vec![0u64; bins];
    for mu in samples {
        let b = (((mu + 1.0) / 2.0) * bins as f64).floor() as usize;
        h[b.min(bins - 1)] += 1;
    }
    h
}

#[test]
fn compton_angles_follow_klein_nishina_times_s() {
    let f = ScatterFactors::new(&water()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for e in [20.0, 80.0] {
        let bins = 30;
        let counts = histogram((0..100_000).map(|_| f.sample_compton(e, &mut rng).0), bins);
        let probs = bin_probabilities(bins, |mu| {
            klein_nishina(e, mu)
                * mix(momentum_transfer(e, mu), |z, x| {
                    incoherent_function(z, x).unwrap()
                })
        });
        assert_chi2(&counts, &probs, &format!("Compton at {e} keV"));
    }
}

#[test]
fn rayleigh_angles_follow_thomson_times_form_factor_squared() {
    let f = ScatterFactors::new(&water()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for e in [20.0, 60.0] {
        // Rayleigh is forward-peaked: bin in μ over [−1, 1] with finer bins by using 60.
        let bins = 60;
        let counts = histogram((0..100_000).map(|_| f.sample_rayleigh(e, &mut rng)), bins);
        let probs = bin_probabilities(bins, |mu| {
            (1.0 + mu * mu)
                * mix(momentum_transfer(e, mu), |z, x| {
                    form_factor(z, x).unwrap().powi(2)
                })
        });
        // Merge sparse bins (expected < 5 counts) into their neighbour for a valid χ².
        let (mut c2, mut p2) = (Vec::new(), Vec::new());
        let (mut cc, mut pp) = (0u64, 0.0);
        for (c, p) in counts.iter().zip(&probs) {
            cc += c;
            pp += p;
            if pp * 100_000.0 >= 20.0 {
                c2.push(cc);
                p2.push(pp);
                (cc, pp) = (0, 0.0);
            }
        }
        if pp > 0.0 {
            *c2.last_mut().unwrap() += cc;
            *p2.last_mut().unwrap() += pp;
        }
        assert_chi2(&c2, &p2, &format!("Rayleigh at {e} keV"));
    }
}

#[test]
fn photons_are_conserved_and_transmission_is_beer_lambert() {
    let comp = slab();
    let medium = Medium::new(&comp, &[water()], 60.0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = 40_000u64;
    let (mut tr, mut esc, mut abs) = (0u64, 0u64, 0u64);
    for _ in 0..n {
        let (fate, _, _, _) =
            medium.walk(DVec3::new(0.0, 0.0, -50.0), DVec3::Z, 60.0, 1000, &mut rng);
        match fate {
            Fate::Transmitted => tr += 1,
            Fate::Escaped => esc += 1,
            Fate::Absorbed => abs += 1,
        }
    }
    assert_eq!(
        tr + esc + abs,
        n,
        "absorbed + transmitted + escaped = emitted"
    );
    // Beer–Lambert from the published attenuation (Elam via the material table).
    let p = (-water().mu_per_mm(60.0, 1.0).unwrap() * SLAB_MM).exp();
    let sd = (n as f64 * p * (1.0 - p)).sqrt();
    assert!(
        (tr as f64 - n as f64 * p).abs() < 4.0 * sd,
        "transmitted {tr}, expected {:.0} ± {sd:.0}",
        n as f64 * p
    );
    assert!(esc > 0 && abs > 0);
}

/// The engine for one pencil beam at `e` keV, scored by a photon-counting response.
fn pencil_engine(e: f64) -> ScatterEngine {
    let medium = Medium::new(&slab(), &[water()], e).unwrap();
    let n = e.ceil() as usize + 1;
    let response = Response {
        mean: vec![vec![1.0; n]],
        second_moment: vec![vec![1.0; n]],
    };
    ScatterEngine::new(medium, response, vec![e], &[1.0], 1.0).unwrap()
}

const SOURCE: DVec3 = DVec3::new(0.0, 0.0, -1000.0);

/// A 0.1 mm pixel on the axis at z = 200 mm: photons aimed at it form a pencil beam.
fn aim() -> View {
    View {
        beam: ViewBeam::Cone { source: SOURCE },
        detector_origin: DVec3::new(0.0, 0.0, 200.0),
        u: DVec3::new(0.1, 0.0, 0.0),
        v: DVec3::new(0.0, 0.1, 0.0),
        rows: 1,
        cols: 1,
    }
}

/// A 1 mm pixel off axis, facing the beam.
fn probe() -> View {
    View {
        detector_origin: DVec3::new(60.0, 0.0, 150.0),
        u: DVec3::new(1.0, 0.0, 0.0),
        v: DVec3::new(0.0, 1.0, 0.0),
        ..aim()
    }
}

/// Independent quadrature of the single-scatter integral along the pencil beam of
/// [`aim`] at `e` keV into the [`probe`] pixel: (single Compton, single Rayleigh) photons.
/// `grid(direction, energy)` is the transmission of anything in front of the pixel.
fn single_scatter_quadrature(e: f64, grid: &dyn Fn(DVec3, f64) -> f64) -> (f64, f64) {
    let w = water();
    let mu = |e: f64| w.mu_per_mm(e, 1.0).unwrap();
    let x = w.interactions(e).unwrap();
    let (mu_inc, mu_coh) = (x.incoherent / 10.0, x.coherent / 10.0);
    let s_mix = |e: f64, m: f64| {
        mix(momentum_transfer(e, m), |z, x| {
            incoherent_function(z, x).unwrap()
        })
    };
    let f2_mix = |e: f64, m: f64| {
        mix(momentum_transfer(e, m), |z, x| {
            form_factor(z, x).unwrap().powi(2)
        })
    };
    let sphere = |f: &dyn Fn(f64) -> f64| {
        let n = 20_000;
        let h = 2.0 / n as f64;
        2.0 * std::f64::consts::PI
            * (0..n)
                .map(|i| f(-1.0 + (i as f64 + 0.5) * h) * h)
                .sum::<f64>()
    };
    let norm_c = sphere(&|m| klein_nishina(e, m) * s_mix(e, m));
    let norm_r = sphere(&|m| (1.0 + m * m) * f2_mix(e, m));
    // Photons in the pencil: fluence 1 per mm² at 1 m × area × (1 m / d)².
    let n0 = 0.01 * (1000.0f64 / 1200.0).powi(2);
    let q = probe().detector_origin;
    let steps = 4000;
    let dz = SLAB_MM / steps as f64;
    let (mut qc, mut qr) = (0.0, 0.0);
    for i in 0..steps {
        let z = (i as f64 + 0.5) * dz;
        let to = q - DVec3::new(0.0, 0.0, z);
        let d = to.length();
        let cos = to.z / d;
        let omega = 1.0 * cos / (d * d);
        let path_out = (SLAB_MM - z) / cos;
        let e_c = e / (1.0 + e / 510.998_95 * (1.0 - cos));
        let base = n0 * (-mu(e) * z).exp() * dz * omega;
        qc += base * mu_inc * klein_nishina(e, cos) * s_mix(e, cos) / norm_c
            * (-mu(e_c) * path_out).exp()
            * grid(to / d, e_c);
        qr += base * mu_coh * (1.0 + cos * cos) * f2_mix(e, cos) / norm_r
            * (-mu(e) * path_out).exp()
            * grid(to / d, e);
    }
    (qc, qr)
}

/// Asserts MC single scatter (Compton, Rayleigh, standard error) matches the quadrature.
fn assert_single_scatter(mc: (f64, f64, f64), q: (f64, f64)) {
    let ((mc_c, mc_r, se), (qc, qr)) = (mc, q);
    eprintln!(
        "single Compton MC {mc_c:.4e} vs {qc:.4e}; Rayleigh MC {mc_r:.4e} vs {qr:.4e}; se {se:.2e}"
    );
    // Tolerance: 4 MC standard errors plus 0.5 % for the quadratures' steps (each < 10⁻³;
    // the engine's log–log tables are within 1.1·10⁻⁴ of the element tables).
    let tol = |v: f64| 4.0 * se + 0.005 * v;
    assert!(
        (mc_c + mc_r - qc - qr).abs() < tol(qc + qr),
        "total {} vs {} (se {se})",
        mc_c + mc_r,
        qc + qr
    );
    assert!(
        (mc_c - qc).abs() < tol(qc) + se,
        "Compton {mc_c} vs {qc} (se {se})"
    );
    assert!(
        (mc_r - qr).abs() < tol(qr) + se,
        "Rayleigh {mc_r} vs {qr} (se {se})"
    );
    assert!(
        se < 0.05 * (qc + qr),
        "the check must be sharp: se {se} vs {}",
        qc + qr
    );
}

#[test]
fn single_scatter_in_a_thin_slab_matches_the_quadrature() {
    let e = 60.0;
    let engine = pencil_engine(e);
    let photons = 40_000;
    let s = engine
        .simulate(&aim(), &probe(), photons, 1, 1, 0.0, 11)
        .unwrap();
    assert_eq!(
        s.multiple.mean[0], 0.0,
        "max_order = 1 scores single scatter only"
    );
    assert_single_scatter(
        (
            s.single_compton.mean[0],
            s.single_rayleigh.mean[0],
            s.grid_standard_error[0],
        ),
        single_scatter_quadrature(e, &|_, _| 1.0),
    );
}

#[test]
fn single_scatter_through_an_anti_scatter_grid_matches_the_quadrature() {
    // A ratio-2, 40 lines/cm grid with 36 µm strips and an aluminium interspace in front
    // of the probe (its strips along y, focused on the source). The quadrature applies the
    // geometric model written out here: D/(D+d) · max(0, 1 − r·Δ) · exp(−μ_Al(E)·h/cos γ),
    // Δ the slope across the strips relative to the focus.
    let e = 60.0;
    let g = AntiScatterGrid {
        ratio: 2.0,
        lines_per_cm: 40.0,
        strip_um: 36.0,
        interspace: "aluminium".into(),
    };
    let engine = pencil_engine(e).with_anti_scatter_grid(Some(&g)).unwrap();
    let s = engine
        .simulate(&aim(), &probe(), 40_000, 1, 1, 0.0, 11)
        .unwrap();
    let al = material::by_name("al").unwrap();
    let (period, d_strip) = (10.0 / 40.0, 0.036);
    let (gap, h) = (period - d_strip, 2.0 * (period - d_strip));
    let q = probe().detector_origin;
    let focus = (q.x - SOURCE.x) / (q.z - SOURCE.z);
    let model = |w: DVec3, e: f64| {
        let delta = (w.x / w.z - focus).abs();
        gap / period
            * (1.0 - 2.0 * delta).max(0.0)
            * (-al.mu_per_mm(e, al.density()).unwrap() * h / w.z).exp()
    };
    let quad = single_scatter_quadrature(e, &model);
    assert_single_scatter(
        (
            s.single_compton.mean[0],
            s.single_rayleigh.mean[0],
            s.grid_standard_error[0],
        ),
        quad,
    );
    // The same histories without the grid (same seed): the grid removes more scatter than
    // primary, so the scatter-to-primary ratio falls.
    let open = pencil_engine(e)
        .simulate(&aim(), &probe(), 40_000, 1, 1, 0.0, 11)
        .unwrap();
    let ts = (s.single_compton.mean[0] + s.single_rayleigh.mean[0])
        / (open.single_compton.mean[0] + open.single_rayleigh.mean[0]);
    let tp = g.tabulate(e).unwrap().primary(e);
    eprintln!("Ts {ts:.4}, Tp {tp:.4}");
    assert!(ts > 0.0 && ts < 0.8 * tp, "Ts {ts} vs Tp {tp}");
}

#[test]
fn scatter_bytes_do_not_depend_on_thread_count() {
    let engine = pencil_engine(50.0);
    let mut wide = probe();
    wide.rows = 3;
    wide.cols = 4;
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| engine.simulate(&aim(), &wide, 3000, 4, 20, 0.0, 5).unwrap())
    };
    let (a, b) = (run(1), run(2));
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (x, y) in [
        (&a.single_compton, &b.single_compton),
        (&a.single_rayleigh, &b.single_rayleigh),
        (&a.multiple, &b.multiple),
    ] {
        assert_eq!(bits(&x.mean), bits(&y.mean));
        assert_eq!(bits(&x.second_moment), bits(&y.second_moment));
    }
    assert!(a.multiple.mean.iter().any(|&v| v > 0.0));
}

#[test]
fn bad_settings_are_named() {
    let err = |m: ScatterModel| m.validate().unwrap_err().to_string();
    let mc = |photons, grid, max_order| ScatterModel::MonteCarlo {
        photons,
        grid,
        multiple_grid: 0,
        max_order,
        detection_cell_mm: 0.0,
        angular_window_deg: 0.0,
        split: 1,
        sparse_multiple: false,
        sampler: Default::default(),
        cell_check: 0,
    };
    assert!(err(mc(0, 16, 5)).contains("photons"));
    assert!(err(mc(10, 0, 5)).contains("grid"));
    assert!(err(mc(10, 4, 0)).contains("max_order"));
    for split in [0, 65] {
        let m = ScatterModel::MonteCarlo {
            photons: 10,
            grid: 4,
            multiple_grid: 0,
            max_order: 5,
            detection_cell_mm: 0.0,
            angular_window_deg: 0.0,
            split,
            sparse_multiple: false,
            sampler: Default::default(),
            cell_check: 0,
        };
        assert!(err(m).contains("split"));
    }
    let est = ScatterModel::Estimate {
        photons: 10,
        grid: 4,
        multiple_grid: 0,
        smoothing: f64::NAN,
        detection_cell_mm: 0.0,
    };
    assert!(err(est).contains("smoothing"));
    let bad: Result<ScatterModel, _> = toml::from_str("model = \"monte-karlo\"");
    assert!(bad.is_err());
    let typo = toml::from_str::<ScatterModel>("model = \"monte-carlo\"\nphoton = 5");
    assert!(typo.unwrap_err().to_string().contains("photon"));
    let ok: ScatterModel = toml::from_str("model = \"monte-carlo\"\nphotons = 500").unwrap();
    assert!(matches!(
        ok,
        ScatterModel::MonteCarlo {
            photons: 500,
            grid: 16,
            ..
        }
    ));
    assert_eq!(
        toml::from_str::<ScatterModel>("model = \"none\"").unwrap(),
        ScatterModel::None
    );
    let engine = pencil_engine(50.0);
    let parallel = View {
        beam: ViewBeam::Parallel {
            direction: DVec3::Z,
        },
        ..probe()
    };
    let e = engine
        .simulate(&parallel, &parallel, 10, 1, 1, 0.0, 0)
        .unwrap_err();
    assert!(e.to_string().contains("cone beam"), "{e}");
}

#[test]
fn scattering_factors_have_their_physical_limits() {
    // F(0, Z) = Z (all electrons scatter in phase) and S(x → ∞, Z) → Z (every electron
    // scatters as a free one): limits of the definitions, independent of the tables' source.
    for z in [1u8, 6, 8, 20, 53, 82] {
        let zf = f64::from(z);
        assert!(
            (form_factor(z, 0.0).unwrap() - zf).abs() < 1e-3 * zf,
            "F(0, {z})"
        );
        let s = incoherent_function(z, 40.0).unwrap();
        assert!((s - zf).abs() < 0.01 * zf, "S(40, {z}) = {s}");
        assert!(incoherent_function(z, 0.0).unwrap().abs() < 1e-9);
        assert!(form_factor(z, 40.0).unwrap() < 0.05 * zf);
    }
    assert!(form_factor(0, 1.0).is_err() && incoherent_function(93, 1.0).is_err());
}

/// The multiple-scatter image on fewer points (`ScoringPoints::multiple`): the same
/// histories, so the single-scatter images are bit-identical and the multiple image is
/// identical where the two grids share a point (the panel's corner); elsewhere the coarse
/// grid's interpolation is its only difference. Its total over the panel stays within 2 %
/// of the fine grid's: bilinear interpolation of a smooth image between points 18 mm apart
/// on a 128 mm panel (measured 0.23 % with 8 points per side; 1.6 % with 4).
#[test]
fn multiple_scatter_on_fewer_points_changes_only_the_multiple_image() {
    use tomograf_physics::scatter::ScoringPoints;
    let engine = pencil_engine(60.0);
    let panel = View {
        detector_origin: DVec3::new(-64.0, -64.0, 200.0),
        u: DVec3::new(4.0, 0.0, 0.0),
        v: DVec3::new(0.0, 4.0, 0.0),
        rows: 32,
        cols: 32,
        ..aim()
    };
    let run = |multiple| {
        let points = ScoringPoints {
            single: 16,
            multiple,
        };
        engine
            .simulate_through(
                &panel,
                &panel,
                20_000,
                points,
                Histories::new(20, 1),
                0.0,
                None,
                3,
            )
            .unwrap()
    };
    let (fine, coarse) = (run(16), run(8));
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(
        bits(&fine.single_compton.mean),
        bits(&coarse.single_compton.mean)
    );
    assert_eq!(
        bits(&fine.single_rayleigh.mean),
        bits(&coarse.single_rayleigh.mean)
    );
    assert_eq!(
        fine.multiple.mean[0].to_bits(),
        coarse.multiple.mean[0].to_bits()
    );
    assert!(fine.multiple.mean[0] > 0.0);
    assert_ne!(bits(&fine.multiple.mean), bits(&coarse.multiple.mean));
    let sum = |v: &[f64]| v.iter().sum::<f64>();
    let ratio = sum(&coarse.multiple.mean) / sum(&fine.multiple.mean);
    eprintln!("multiple scatter, 8² against 16² points: total ratio {ratio:.4}");
    assert!((ratio - 1.0).abs() < 0.02, "ratio {ratio}");
    // The grid's totals: the multiple image resampled at the single grid's points.
    assert_eq!(coarse.grid_mean.len(), 256);
    let g = |s: &tomograf_physics::scatter::ScatterImages| sum(&s.grid_mean);
    assert!((g(&coarse) / g(&fine) - 1.0).abs() < 0.02);
    // Equal grids are the one-grid run, bit for bit.
    let same = run(16);
    assert_eq!(bits(&same.multiple.mean), bits(&fine.multiple.mean));
    assert_eq!(
        bits(&same.multiple.mean),
        bits(
            &engine
                .simulate(&panel, &panel, 20_000, 16, 20, 0.0, 3)
                .unwrap()
                .multiple
                .mean
        )
    );
}

/// Splitting every history into branches at its first collision is unbiased — the
/// multiple-scatter image's total over 16 runs agrees with the unsplit runs' within 4
/// standard errors of the difference — and narrows that total's run-to-run spread at the
/// same histories (what it is for; measured here 2–3× in SD with 4 branches).
#[test]
fn splitting_at_the_first_collision_is_unbiased_and_narrows_the_multiple_image() {
    use tomograf_physics::scatter::ScoringPoints;
    let engine = pencil_engine(60.0);
    let panel = View {
        detector_origin: DVec3::new(-64.0, -64.0, 200.0),
        u: DVec3::new(8.0, 0.0, 0.0),
        v: DVec3::new(0.0, 8.0, 0.0),
        rows: 16,
        cols: 16,
        ..aim()
    };
    let points = ScoringPoints {
        single: 8,
        multiple: 8,
    };
    let totals = |split: u32| -> (Vec<f64>, Vec<f64>) {
        (0..16u64)
            .map(|seed| {
                let s = engine
                    .simulate_through(
                        &panel,
                        &panel,
                        2_000,
                        points,
                        Histories::new(20, split),
                        0.0,
                        None,
                        seed,
                    )
                    .unwrap();
                let sum = |v: &[f64]| v.iter().sum::<f64>();
                (
                    sum(&s.multiple.mean),
                    sum(&s.single_compton.mean) + sum(&s.single_rayleigh.mean),
                )
            })
            .unzip()
    };
    let stats = |x: &[f64]| {
        let n = x.len() as f64;
        let m = x.iter().sum::<f64>() / n;
        let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, var.sqrt())
    };
    let (multiple_1, single_1) = totals(1);
    let (multiple_4, single_4) = totals(4);
    for (name, a, b) in [
        ("multiple", &multiple_1, &multiple_4),
        ("single", &single_1, &single_4),
    ] {
        let ((ma, sa), (mb, sb)) = (stats(a), stats(b));
        let se = ((sa * sa + sb * sb) / a.len() as f64).sqrt();
        eprintln!(
            "{name}: unsplit {ma:.4e} ± {sa:.2e} (SD), split 4 {mb:.4e} ± {sb:.2e}; difference {:.2} SE",
            (mb - ma) / se
        );
        assert!(ma > 0.0 && se > 0.0);
        assert!((mb - ma).abs() < 4.0 * se, "{name}: {ma} vs {mb} (SE {se})");
    }
    let (s1, s4) = (stats(&multiple_1).1, stats(&multiple_4).1);
    assert!(
        s4 < 0.75 * s1,
        "multiple image's SD: unsplit {s1}, split {s4}"
    );
}

/// The Sobol start ([`Sampler::Sobol`]) and sparse multiple scoring (each collision after the
/// first scores one point of every 2 × 2 block, ×4) are unbiased: over 24 runs of a wide
/// beam (15² pixels aimed at) each variant's single- and multiple-scatter totals agree with
/// the Latin hypercube's, unsplit and dense, within 4 standard errors of the difference, and
/// so does the multiple image on each of the four parity classes of its points (a class the
/// sparse draw missed or favoured would be off by a factor); sparse scoring with 4 branches
/// narrows the multiple total's run-to-run spread.
#[test]
fn sobol_points_and_sparse_multiple_scoring_are_unbiased() {
    use tomograf_physics::scatter::{Sampler, ScoringPoints};
    let engine = pencil_engine(60.0);
    let panel = View {
        detector_origin: DVec3::new(-64.0, -64.0, 200.0),
        u: DVec3::new(8.0, 0.0, 0.0),
        v: DVec3::new(0.0, 8.0, 0.0),
        // 15 pixels a side: the 8 points per side sit on every other pixel centre.
        rows: 15,
        cols: 15,
        ..aim()
    };
    let points = ScoringPoints {
        single: 8,
        multiple: 8,
    };
    // Per run: [single total, multiple total, multiple on each (row, column) parity class].
    let runs = |h: Histories| -> Vec<[f64; 6]> {
        (0..24u64)
            .map(|seed| {
                let s = engine
                    .simulate_through(&panel, &panel, 2_000, points, h, 0.0, None, seed)
                    .unwrap();
                let sum = |v: &[f64]| v.iter().sum::<f64>();
                let mut r = [0.0; 6];
                r[0] = sum(&s.single_compton.mean) + sum(&s.single_rayleigh.mean);
                r[1] = sum(&s.multiple.mean);
                // The multiple image at the grid's own points (pixels 0, 2, …, 14).
                for (i, &x) in s.multiple.mean.iter().enumerate() {
                    let (row, col) = (i / 15, i % 15);
                    if row % 2 == 0 && col % 2 == 0 {
                        r[2 + (row / 2 % 2) * 2 + col / 2 % 2] += x;
                    }
                }
                r
            })
            .collect()
    };
    let stats = |x: &[[f64; 6]], k: usize| {
        let n = x.len() as f64;
        let m = x.iter().map(|r| r[k]).sum::<f64>() / n;
        let var = x.iter().map(|r| (r[k] - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, var.sqrt())
    };
    let base = runs(Histories::new(20, 1));
    let variants = [
        (
            "sobol",
            Histories {
                sampler: Sampler::Sobol,
                ..Histories::new(20, 1)
            },
        ),
        (
            "sparse ×4",
            Histories {
                sparse_multiple: true,
                ..Histories::new(20, 4)
            },
        ),
        (
            "sobol + sparse ×4",
            Histories {
                sampler: Sampler::Sobol,
                sparse_multiple: true,
                ..Histories::new(20, 4)
            },
        ),
    ];
    let names = [
        "single",
        "multiple",
        "multiple (even, even)",
        "multiple (even, odd)",
        "multiple (odd, even)",
        "multiple (odd, odd)",
    ];
    for (label, h) in variants {
        let other = runs(h);
        for (k, name) in names.iter().enumerate() {
            let ((ma, sa), (mb, sb)) = (stats(&base, k), stats(&other, k));
            let se = ((sa * sa + sb * sb) / base.len() as f64).sqrt();
            eprintln!(
                "{label}, {name}: {mb:.4e} against {ma:.4e}, {:.2} SE",
                (mb - ma) / se
            );
            assert!(ma > 0.0 && se > 0.0);
            assert!(
                (mb - ma).abs() < 4.0 * se,
                "{label}, {name}: {ma} vs {mb} (SE {se})"
            );
        }
        if h.sparse_multiple {
            let (s1, s4) = (stats(&base, 1).1, stats(&other, 1).1);
            assert!(
                s4 < 0.8 * s1,
                "{label}: multiple total's SD {s4} against {s1}"
            );
        }
    }
}
