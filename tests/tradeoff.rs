//! `tomograf tradeoff`: its error column against a direct comparison of two `tomograf
//! project` renders (a different code path: the command line's own pipeline and files).

mod common;
use common::{SMALL, ok, read_npy, tomograf};
use std::path::Path;

/// `(rms, max)` relative errors as the tradeoff page defines them, computed here.
fn errors(a: &[f32], r: &[f32]) -> (f64, f64) {
    assert_eq!(a.len(), r.len());
    let (mut d2, mut r2, mut dm, mut rm) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (&x, &y) in a.iter().zip(r) {
        let (x, y) = (f64::from(x), f64::from(y));
        d2 += (x - y).powi(2);
        r2 += y * y;
        dm = dm.max((x - y).abs());
        rm = rm.max(y.abs());
    }
    ((d2 / r2).sqrt(), dm / rm)
}

fn project(dir: &Path, name: &str, extra: &[&str]) -> Vec<f32> {
    let out = dir.join(name);
    let mut args = vec!["project", "-o", out.to_str().unwrap(), "--format", "npy"];
    args.extend(SMALL);
    args.extend(extra);
    ok(&tomograf(&args));
    read_npy(&out.join("drr.npy")).1
}

/// The CSV row whose setting column is `setting`: (rms, max).
fn row(csv: &str, setting: &str) -> (f64, f64) {
    let line = csv
        .lines()
        .find(|l| l.contains(&format!("\"{setting}\"")))
        .unwrap_or_else(|| panic!("no row '{setting}' in\n{csv}"));
    let f: Vec<&str> = line.rsplitn(3, ',').collect();
    (f[1].parse().unwrap(), f[0].parse().unwrap())
}

fn tradeoff(dir: &Path, extra: &[&str]) -> String {
    let report = dir.join("report");
    let mut args = vec![
        "tradeoff",
        "--report",
        report.to_str().unwrap(),
        "--repeats",
        "1",
    ];
    args.extend(SMALL);
    args.extend(extra);
    let out = tomograf(&args);
    ok(&out);
    let md = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(md.contains("For an error budget of"), "{md}");
    assert!(report.join("tradeoff.png").exists());
    std::fs::read_to_string(report.join("tradeoff.csv")).unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-5 * b.abs().max(1e-9)
}

#[test]
fn ideal_drr_trilinear_error_matches_a_direct_comparison() {
    let dir = tempfile::tempdir().unwrap();
    let csv = tradeoff(dir.path(), &["--steps", "1,2"]);
    let reference = project(dir.path(), "siddon", &[]);
    for step in ["1", "2"] {
        let img = project(
            dir.path(),
            step,
            &["--projector", "trilinear", "--step", step],
        );
        let (rms, max) = errors(&img, &reference);
        let (r, m) = row(&csv, &format!("trilinear, step {step} voxel"));
        assert!(
            close(r, rms) && close(m, max),
            "step {step}: tradeoff says rms {r}, max {m}; direct {rms}, {max}"
        );
        // A coarser step is no free lunch: the error is real and not vanishing.
        assert!(rms > 1e-5, "step {step}: rms {rms}");
    }
}

#[test]
fn energy_bin_error_matches_a_direct_comparison() {
    let dir = tempfile::tempdir().unwrap();
    // A noiseless, unblurred detector, so `project` renders what tradeoff renders.
    let physics = [
        "--preset",
        "kv-flat-panel-120kvp",
        "--detector-model",
        "noiseless-csi",
    ];
    let mut args = physics.to_vec();
    args.extend(["--bins", "8", "--steps", "1"]);
    let csv = tradeoff(dir.path(), &args);
    let reference = project(dir.path(), "full", &physics);
    let mut binned = physics.to_vec();
    binned.extend(["--energy-bins", "8"]);
    let img = project(dir.path(), "bins8", &binned);
    let (rms, max) = errors(&img, &reference);
    let line = csv.lines().find(|l| l.starts_with("energy bins")).unwrap();
    let setting = line.split('"').nth(1).unwrap();
    let (r, m) = row(&csv, setting);
    assert!(
        close(r, rms) && close(m, max),
        "tradeoff says rms {r}, max {m}; direct {rms}, {max}"
    );
    assert!(rms > 0.0);
}

#[test]
fn bad_budget_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r");
    let mut args = vec![
        "tradeoff",
        "--report",
        report.to_str().unwrap(),
        "--budget",
        "0",
    ];
    args.extend(SMALL);
    let out = tomograf(&args);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--budget"));
}

#[test]
fn scatter_rungs_are_measured_against_the_full_reference() {
    let dir = tempfile::tempdir().unwrap();
    let csv = tradeoff(
        dir.path(),
        &[
            "--preset",
            "kv-flat-panel-120kvp",
            "--scatter",
            "monte-carlo",
            "--scatter-photons",
            "4000",
            "--scatter-fractions",
            "0.5,0.125",
            "--steps",
            "1",
            "--bins",
            "8",
        ],
    );
    assert!(csv.contains("\"reference without scatter\""), "{csv}");
    // The fractions asked for (not the defaults, ¼ and 1/16).
    let (r2000, _) = row(&csv, "scatter Monte Carlo, 2000 photons");
    let (r500, _) = row(&csv, "scatter Monte Carlo, 500 photons");
    assert!(!csv.contains("1000 photons"), "{csv}");
    let (est, _) = row(&csv, "scatter estimate, 2000 photons, 8 mm cells");
    // Fewer histories, more Monte Carlo noise against the same 4000-history reference.
    assert!(r500 > r2000 && r2000 > 0.0, "500: {r500}, 2000: {r2000}");
    assert!(est > 0.0);
}

#[test]
fn the_scatter_reference_is_bounded_and_detection_cells_are_a_knob() {
    let dir = tempfile::tempdir().unwrap();
    let csv = tradeoff(
        dir.path(),
        &[
            "--preset",
            "kv-flat-panel-120kvp",
            "--scatter",
            "estimate",
            "--scatter-reference-photons",
            "3000",
            "--scatter-fractions",
            "0.25",
            "--scatter-cells",
            "2,16",
            "--steps",
            "1",
            "--bins",
            "8",
        ],
    );
    // An estimate scene's reference: the Monte Carlo with the photons asked for, through
    // 8 mm cells; cells no coarser than the reference's are not tried.
    assert!(
        csv.contains("scatter Monte Carlo, 3000 photons, 8 mm cells"),
        "{csv}"
    );
    assert!(!csv.contains("through 2 mm cells"), "{csv}");
    let (cells, _) = row(&csv, "scatter forced detection through 16 mm cells");
    assert!(cells > 0.0 && cells < 0.05, "{cells}");
    assert!(
        csv.lines().any(|l| l.starts_with("scatter cells,")),
        "{csv}"
    );

    let r0 = dir.path().join("r0");
    let mut args = vec![
        "tradeoff",
        "--report",
        r0.to_str().unwrap(),
        "--preset",
        "kv-flat-panel-120kvp",
        "--scatter",
        "estimate",
        "--scatter-reference-photons",
        "0",
    ];
    args.extend(SMALL);
    let out = tomograf(&args);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("reference photons"), "{err}");
}
