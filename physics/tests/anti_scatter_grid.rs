//! The anti-scatter grid's transmission against analytic values of its geometric model:
//! primary transmission with a published interspace attenuation, the transmission of an
//! isotropic (Lambertian) scatter field against a closed form derived here, and clear
//! errors for bad grids.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tomograf_physics::scatter::AntiScatterGrid;

fn grid(ratio: f64, interspace: &str) -> AntiScatterGrid {
    AntiScatterGrid {
        ratio,
        lines_per_cm: 40.0,
        strip_um: 36.0,
        interspace: interspace.into(),
    }
}

#[test]
fn primary_transmission_is_open_fraction_times_interspace_attenuation() {
    // 40 lines/cm: period 250 µm, interspace D = 214 µm, open fraction 0.856.
    let air = grid(10.0, "air").tabulate(120.0).unwrap();
    for e in [20.0, 60.0, 119.0] {
        assert!((air.primary(e) - 0.856).abs() < 1e-12);
    }
    // Aluminium interspace, r = 10: h = 2.14 mm. NIST XCOM / Hubbell & Seltzer (NISTIR
    // 5632) aluminium μ/ρ at 60 keV = 0.2778 cm²/g, ρ = 2.699 g/cm³. The tool's tables are
    // Elam et al. (xraydb): agreement to 1 % in μ is expected, 0.2 % in Tp here.
    let al = grid(10.0, "aluminium").tabulate(120.0).unwrap();
    let published = 0.856 * (-0.2778f64 * 2.699 * 0.214).exp();
    let tp = al.primary(60.0);
    assert!(
        (tp / published - 1.0).abs() < 2e-3,
        "Tp(60 keV) {tp} vs {published}"
    );
    // Along the focus but oblique to the normal: only the interspace path lengthens.
    let cos = 0.9;
    assert!(
        (al.at_slope(0.0, cos, 60.0) - 0.856 * (-0.2778f64 * 2.699 * 0.214 / cos).exp()).abs()
            < 2e-3
    );
}

/// Ts of a Lambertian (cosine-weighted, isotropic radiance) field over the hemisphere for
/// a grid without interspace attenuation: with a = r |cos φ|, the polar integral has the
/// closed form ∫₀^{atan(1/a)} (1 − a tan θ) cos θ sin θ dθ = ½ − (a/2) atan(1/a), so
/// Ts = (f/π) ∫₀^{2π} [½ − (a/2) atan(1/a)] dφ (f the open fraction); the φ integral by a
/// 200 000-point midpoint rule.
fn lambertian_closed_form(ratio: f64, open: f64) -> f64 {
    let n = 200_000;
    let h = 2.0 * std::f64::consts::PI / n as f64;
    let sum: f64 = (0..n)
        .map(|i| {
            let a = ratio * ((i as f64 + 0.5) * h).cos().abs();
            if a == 0.0 {
                0.5
            } else {
                0.5 - 0.5 * a * (1.0 / a).atan()
            }
        })
        .sum();
    open / std::f64::consts::PI * sum * h
}

#[test]
fn lambertian_scatter_transmission_matches_the_closed_form() {
    let (u, n) = (DVec3::X, DVec3::Z);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for ratio in [4.0, 8.0, 12.0] {
        let t = grid(ratio, "air").tabulate(100.0).unwrap();
        // Cosine-weighted directions: (x, y) uniform on the unit disc, z = √(1 − x² − y²).
        let samples = 400_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..samples {
            let (x, y) = loop {
                let (x, y) = (
                    rng.random::<f64>() * 2.0 - 1.0,
                    rng.random::<f64>() * 2.0 - 1.0,
                );
                if x * x + y * y < 1.0 {
                    break (x, y);
                }
            };
            let w = DVec3::new(x, y, (1.0 - x * x - y * y).sqrt());
            let v = t.towards(w, u, n, 0.0, 60.0);
            s += v;
            s2 += v * v;
        }
        let mean = s / samples as f64;
        let se = ((s2 / samples as f64 - mean * mean) / samples as f64).sqrt();
        let exact = lambertian_closed_form(ratio, 0.856);
        eprintln!("r = {ratio}: Ts MC {mean:.5} ± {se:.5}, closed form {exact:.5}");
        assert!(
            (mean - exact).abs() < 4.0 * se,
            "r = {ratio}: {mean} vs {exact} (se {se})"
        );
        // A grid passes far less scatter than primary (the point of it).
        assert!(exact < 0.5 * t.primary(60.0));
    }
    // A focused strip elsewhere on the panel: the same field seen relative to the focus.
    let t = grid(8.0, "air").tabulate(100.0).unwrap();
    let w = DVec3::new(0.1, 0.0, 1.0).normalize();
    assert!((t.towards(w, u, n, 0.1, 60.0) - 0.856).abs() < 1e-12);
    assert!((t.towards(w, u, n, 0.0, 60.0) - 0.856 * (1.0 - 8.0 * 0.1)).abs() < 1e-12);
    assert_eq!(t.towards(w, u, n, -0.1, 60.0), 0.0);
}

#[test]
fn bad_grids_are_named() {
    let err = |g: AntiScatterGrid| g.validate().unwrap_err().to_string();
    assert!(err(grid(-1.0, "air")).contains("ratio"));
    assert!(err(grid(f64::NAN, "air")).contains("ratio"));
    assert!(
        err(AntiScatterGrid {
            lines_per_cm: 0.0,
            ..grid(8.0, "air")
        })
        .contains("lines_per_cm")
    );
    assert!(
        err(AntiScatterGrid {
            strip_um: 300.0,
            ..grid(8.0, "air")
        })
        .contains("strip_um")
    );
    assert!(err(grid(8.0, "unobtainium")).contains("interspace"));
    let typo = toml::from_str::<AntiScatterGrid>("ratio = 8\nlines_per_cm = 40\nstrips_um = 3");
    assert!(typo.unwrap_err().to_string().contains("strips_um"));
    let ok: AntiScatterGrid = toml::from_str("ratio = 8\nlines_per_cm = 40").unwrap();
    assert_eq!(ok, AntiScatterGrid::new(8.0, 40.0));
}
