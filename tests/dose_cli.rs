//! End-to-end tests of `[dose]` on the command line: the dose NIfTI and JSON beside the
//! images, dose where the body is and not in air, bytes independent of the thread count,
//! and clear errors for scenes that cannot have a dose; `validate tg195` writes its files.

mod common;

use common::*;
use std::path::{Path, PathBuf};

/// Renders the small phantom (2 views, 8 × 8 panel) with `dose` as the body of `[dose]`
/// into `dir/name` with `global` flags; returns the output folder.
fn run(dir: &Path, name: &str, global: &[&str], dose: &str) -> PathBuf {
    let out = dir.join(name);
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(
        &scene,
        format!(
            "[volume]\nphantom_dims = [24, 24, 16]\nphantom_spacing_mm = [15.0, 15.0, 20.0]\n\
             [detector]\nrows = 8\ncols = 8\n[views]\nposes = [\"ap\", \"lateral\"]\n\
             [acquisition]\npreset = \"kv-flat-panel-120kvp\"\nseed = 3\n\
             [output]\ndir = \"{}\"\nformats = [\"npy\"]\n[dose]\n{dose}\n",
            out.display()
        ),
    )
    .unwrap();
    let mut args = global.to_vec();
    args.extend(["project", "--scene", scene.to_str().unwrap()]);
    ok(&tomograf(&args));
    out
}

#[test]
fn dose_files_are_written_and_follow_the_body() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = run(d, "a", &["--threads", "1"], "photons = 20000");
    let nii = out.join("drr_dose.nii.gz");
    let vol = tomograf_datasets::nifti::read_nifti(&nii).unwrap();
    assert_eq!(vol.dims(), [24, 24, 16]);
    let gy = vol.data();
    assert!(gy.iter().all(|v| v.is_finite() && *v >= 0.0));
    let max = gy.iter().copied().fold(0.0f32, f32::max);
    assert!(max > 0.0);
    // The phantom's corners are air (no mass, no dose); its centre is tissue in the beam.
    assert_eq!(gy[0], 0.0);
    let centre = gy[12 + 24 * (12 + 24 * 8)];
    assert!(centre > 0.0, "centre dose {centre}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("drr_dose.json")).unwrap()).unwrap();
    assert_eq!(json["views"].as_array().unwrap().len(), 2);
    assert_eq!(json["photons_per_view"], 20000);
    assert!(json["energy_imparted_joule"].as_f64().unwrap() > 0.0);
    // Same bytes on two threads.
    let two = run(d, "b", &["--threads", "2"], "photons = 20000");
    assert_eq!(
        std::fs::read(&nii).unwrap(),
        std::fs::read(two.join("drr_dose.nii.gz")).unwrap()
    );
}

#[test]
fn scenes_without_a_dose_are_refused_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fails = |body: &str| {
        let scene = d.join("bad.toml");
        std::fs::write(
            &scene,
            format!("[output]\ndir = \"{}\"\n{body}", d.join("o").display()),
        )
        .unwrap();
        let out = tomograf(&["project", "--scene", scene.to_str().unwrap()]);
        assert!(!out.status.success(), "should fail: {body}");
        assert!(
            !d.join("o").join("drr.npy").exists(),
            "rendered before refusing"
        );
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let e = fails("[dose]\nphotons = 1000\n");
    assert!(e.contains("[dose]") && e.contains("acquisition"), "{e}");
    let e = fails("[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[dose]\nphotons = 0\n");
    assert!(e.contains("photons = 0"), "{e}");
    let e = fails("[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[dose]\nphotns = 10\n");
    assert!(e.contains("photns"), "{e}");
}

#[test]
fn validate_tg195_writes_its_table_csv_and_figures() {
    // Case 1 only, 20 000 photons per run: the files exist, the CSV has the 20 Case 1
    // rows (4 beams × 3 kermas and 2 ratios), `--replot` redraws from it, and a case TG-195 does
    // not have, or one we do not build, is refused by name.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v");
    let o = out.to_str().unwrap();
    let run = tomograf(&[
        "validate",
        "tg195",
        "--cases",
        "1",
        "--photons-case1",
        "20000",
        "-o",
        o,
    ]);
    ok(&run);
    for f in ["tg195.md", "tg195.csv", "tg195-deviations.png"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let csv = std::fs::read_to_string(out.join("tg195.csv")).unwrap();
    assert!(csv.starts_with("case,quantity,ours,ours_se"), "{csv}");
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 20, "{csv}");
    assert!(rows.iter().all(|r| r.starts_with("1 ")), "{csv}");
    // `--update` re-runs case 2 and keeps case 1's rows and seconds, byte for byte.
    ok(&tomograf(&[
        "validate",
        "tg195",
        "--update",
        "--cases",
        "2",
        "--photons-case2",
        "20000",
        "-o",
        o,
    ]));
    let merged = std::fs::read_to_string(out.join("tg195.csv")).unwrap();
    assert!(merged.starts_with(&csv), "case 1 rows changed:\n{merged}");
    assert_eq!(merged.lines().filter(|l| l.starts_with("2 ")).count(), 40);
    let md = std::fs::read_to_string(out.join("tg195.md")).unwrap();
    assert!(
        md.contains("Kept from the previous run: case 1 (photons per run: case 1 20000"),
        "{md}"
    );
    assert!(
        md.contains("* case 1, 30 keV:") && md.contains("* case 2, radiography 56.4 keV:"),
        "{md}"
    );
    std::fs::remove_file(out.join("tg195-deviations.png")).unwrap();
    ok(&tomograf(&["validate", "tg195", "--replot", "-o", o]));
    assert!(out.join("tg195-deviations.png").is_file());
    let bad = tomograf(&["validate", "tg195", "--cases", "5", "-o", o]);
    assert!(!bad.status.success());
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("unknown case '5'"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}
