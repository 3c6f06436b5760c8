//! End-to-end tests of the `tomograf` command line.

mod common;

use common::*;
use std::path::Path;

#[test]
fn default_job_renders_the_phantom_with_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let mut args = vec![
        "project",
        "-o",
        d,
        "--format",
        "exr,tiff,npy,png",
        "--view",
        "ap",
        "--view",
        "lateral",
    ];
    args.extend(SMALL);
    ok(&tomograf(&args));
    for f in [
        "drr_000.exr",
        "drr_001.exr",
        "drr_000.tiff",
        "drr_000.png",
        "drr_001.png",
        "drr.npy",
        "drr.json",
    ] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    let (shape, data) = read_npy(&dir.path().join("drr.npy"));
    assert_eq!(shape, vec![2, 64, 64]);
    assert!(data.iter().all(|v| v.is_finite() && *v >= 0.0));
    // Through ~23 cm of tissue at 60 keV the centre line integral is several units.
    let centre = data[32 * 64 + 32];
    assert!(
        centre > 2.0 && centre < 10.0,
        "centre line integral {centre}"
    );
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("drr.json")).unwrap()).unwrap();
    assert_eq!(side["views"].as_array().unwrap().len(), 2);
    assert_eq!(side["views"][1]["pose"]["theta_deg"], 90.0);
    assert!(side["views"][0]["beam"]["source"].is_array());
    assert_eq!(side["projector"]["kind"], "siddon");
    assert_eq!(side["volume"]["phantom"], "thorax");
}

/// Renders view (30°, 10°) of the small in-memory phantom and of `input` (the same phantom
/// written to a file or folder) and checks the images agree. The files store spacing and
/// origin in single precision or decimal text (~1e-5 mm here), which moves grazing rays'
/// tiny chords: allow 1e-4 relative (absolute below L = 1). A flip, shift or transpose
/// changes pixels by O(1).
fn assert_renders_like_the_phantom(input: &Path, work: &Path) {
    let (a, b) = (work.join("a"), work.join("b"));
    let view = ["--format", "npy", "--view", "30,10"];
    let mut args = vec!["project", "-o", a.to_str().unwrap()];
    args.extend(view);
    args.extend(SMALL);
    ok(&tomograf(&args));
    let mut args = vec![
        "project",
        input.to_str().unwrap(),
        "-o",
        b.to_str().unwrap(),
    ];
    args.extend(view);
    args.extend(["--rows", "64", "--cols", "64"]);
    ok(&tomograf(&args));
    let (x, y) = (
        read_npy(&a.join("drr.npy")).1,
        read_npy(&b.join("drr.npy")).1,
    );
    assert_eq!(x.len(), y.len());
    let worst = x
        .iter()
        .zip(&y)
        .map(|(p, q)| (p - q).abs() / p.abs().max(1.0))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "largest relative difference {worst}");
    assert!(x.iter().any(|&v| v > 1.0), "image is not empty");
}

/// Writes the small phantom with `tomograf phantom` plus `extra` arguments to `output`.
fn write_small_phantom(output: &Path, extra: &[&str]) {
    let mut args = vec![
        "phantom",
        "-o",
        output.to_str().unwrap(),
        "--dims",
        "64,64,40",
        "--spacing",
        "5.6,5.6,8.3",
    ];
    args.extend(extra);
    ok(&tomograf(&args));
}

#[test]
fn nifti_round_trip_renders_the_same_image() {
    // The phantom written to NIfTI (RAS on disk) and read back must give the same pixels
    // as the in-memory phantom: no flip, shift or transpose on the way.
    let dir = tempfile::tempdir().unwrap();
    let nii = dir.path().join("p.nii.gz");
    write_small_phantom(&nii, &[]);
    assert_renders_like_the_phantom(&nii, dir.path());
}

#[test]
fn dicom_series_renders_like_the_phantom_and_is_listed() {
    // Phantom → DICOM series (LPS, int16; its HU are whole numbers, so nothing is lost).
    let dir = tempfile::tempdir().unwrap();
    let series = dir.path().join("patient").join("study").join("series");
    write_small_phantom(&series, &["--dicom"]);
    assert_renders_like_the_phantom(&series, dir.path());
    let out = tomograf(&["scan", dir.path().to_str().unwrap()]);
    ok(&out);
    let listing = String::from_utf8_lossy(&out.stdout);
    assert!(listing.contains("CT\t40\t64×64"), "{listing}");
}

#[test]
fn same_bytes_whatever_the_thread_count_and_scene_equals_flags() {
    let dir = tempfile::tempdir().unwrap();
    // `global`: options before the subcommand (e.g. --threads 1).
    let run = |name: &str, global: &[&str]| {
        let out = dir.path().join(name);
        let mut args = global.to_vec();
        args.extend([
            "project",
            "-o",
            out.to_str().unwrap(),
            "--format",
            "npy",
            "--arc",
            "0:40:3",
        ]);
        args.extend(SMALL);
        ok(&tomograf(&args));
        std::fs::read(out.join("drr.npy")).unwrap()
    };
    let one = run("t1", &["--threads", "1"]);
    assert_eq!(one, run("t2", &[]));
    // The same job from a scene file.
    let scene = dir.path().join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            "[volume]\nphantom_dims = [64, 64, 40]\nphantom_spacing_mm = [5.6, 5.6, 8.3]\n[detector]\nrows = 64\ncols = 64\n[views]\narc = \"0:40:3\"\n[output]\ndir = \"{}\"\nformats = [\"npy\"]\n",
            dir.path().join("s").display()
        ),
    )
    .unwrap();
    ok(&tomograf(&["project", "--scene", scene.to_str().unwrap()]));
    assert_eq!(
        one,
        std::fs::read(dir.path().join("s").join("drr.npy")).unwrap()
    );
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["--sad", "1000", "--sid", "900"],
            "SID (900 mm) is smaller than SAD (1000 mm)",
        ),
        (&["--pitch", "0"], "pitch is 0 mm"),
        (&["--rows", "0"], "empty detector"),
        (
            &["--phantom-spacing", "1,-1,1"],
            "spacing along axis 1 is -1 mm",
        ),
        (&["--format", "jpeg"], "unknown output format 'jpeg'"),
        (
            &["--energy-kev", "900"],
            "outside the water attenuation table",
        ),
        (&["--view", "sideways"], "neither a named view"),
        (
            &["--projector", "trilinear", "--step", "0"],
            "trilinear step is 0 voxels",
        ),
        (
            &["--beam", "parallel", "--sad", "1000"],
            "do not apply to a parallel beam",
        ),
    ];
    for (extra, msg) in cases {
        let mut args = vec!["project", "-o", d, "--phantom-dims", "8,8,8"];
        if !extra.contains(&"--phantom-spacing") {
            args.extend(["--phantom-spacing", "40,40,40"]);
        }
        args.extend(*extra);
        let out = tomograf(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{extra:?} should fail");
        assert!(err.contains(msg), "{extra:?}: expected '{msg}' in: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // Missing and corrupt volumes.
    let bad = dir.path().join("bad.nii");
    std::fs::write(&bad, b"not a nifti file at all").unwrap();
    let empty_dir = dir.path().join("empty-series");
    std::fs::create_dir(&empty_dir).unwrap();
    for (path, msg) in [
        (bad.to_str().unwrap(), "bad.nii"),
        ("/nonexistent/ct.nii.gz", "ct.nii.gz"),
        ("ct.mha", "a folder holding one DICOM series"),
        (empty_dir.to_str().unwrap(), "empty-series"),
    ] {
        let out = tomograf(&["project", path, "-o", d]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(msg) && !err.contains("panicked"),
            "{path}: {err}"
        );
    }
}

#[test]
fn bench_quick_runs() {
    let dir = tempfile::tempdir().unwrap();
    let md = dir.path().join("bench.md");
    ok(&tomograf(&[
        "bench",
        "--quick",
        "--repeats",
        "1",
        "--out",
        md.to_str().unwrap(),
    ]));
    let text = std::fs::read_to_string(md).unwrap();
    assert!(text.contains("G voxel steps/s") && text.contains("Observed order"));
}

/// `--empty-below`: on the phantom (air exactly 0) skipping at threshold 0 changes no
/// pixel beyond one f32 ulp; the sidecar records it; a negative threshold and its use with
/// detector physics are clear errors.
#[test]
fn empty_space_skipping_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        project_npy(
            &dir.path().join(name),
            &[&["--view", "30,10"], extra].concat(),
        )
    };
    let plain = run("plain", &[]);
    let skipped = run("skip", &["--empty-below", "0"]);
    let (a, b) = (
        read_npy(&plain.join("drr.npy")).1,
        read_npy(&skipped.join("drr.npy")).1,
    );
    assert!(a.iter().any(|&v| v > 1.0), "the view sees the phantom");
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() <= f32::EPSILON * x.abs(), "{x} vs {y}");
    }
    let sidecar = std::fs::read_to_string(skipped.join("drr.json")).unwrap();
    assert!(sidecar.contains("\"threshold\""), "{sidecar}");
    refused(
        dir.path(),
        &[
            (&["--empty-below=-1"], "threshold"),
            (
                &["--empty-below", "1e-4", "--preset", "kv-flat-panel-120kvp"],
                "empty_below_per_mm (--empty-below) is for the ideal DRR",
            ),
        ],
    );
}

/// `project` of the small phantom into `out` as NPY, with `extra` flags; must succeed.
fn project_npy(out: &Path, extra: &[&str]) -> std::path::PathBuf {
    let mut args = vec!["project", "-o", out.to_str().unwrap(), "--format", "npy"];
    args.extend(SMALL);
    args.extend(extra);
    ok(&tomograf(&args));
    out.to_path_buf()
}

/// `project` of the small phantom with each case's flags fails, its error holding the
/// case's text.
fn refused(dir: &Path, cases: &[(&[&str], &str)]) {
    for (extra, expected) in cases {
        let mut args = vec!["project", "-o", dir.to_str().unwrap()];
        args.extend(SMALL);
        args.extend(*extra);
        let out = tomograf(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(expected),
            "{extra:?}: {err}"
        );
    }
}

/// `--tracer` (`[projector] tracer`): each named tracer renders the default's image to
/// rounding, with detector physics too; the sidecar records a tracer other than `auto`
/// (absent: auto, so default runs keep their bytes); an unknown name and a tracer for the
/// trilinear projector are clear errors.
#[test]
fn the_tracer_is_chosen_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        project_npy(
            &dir.path().join(name),
            &[&["--arc", "0:40:9"], extra].concat(),
        )
    };
    for physics in [
        &[][..],
        &[
            "--preset",
            "kv-flat-panel-120kvp",
            "--detector-model",
            "noiseless-csi",
        ][..],
    ] {
        let plain = run("plain", physics);
        let a = read_npy(&plain.join("drr.npy")).1;
        assert!(a.iter().any(|&v| v > 0.5), "the views see the phantom");
        let sidecar = std::fs::read_to_string(plain.join("drr.json")).unwrap();
        assert!(!sidecar.contains("\"tracer\""), "{sidecar}");
        for t in ["scalar", "packets", "sheets", "columns"] {
            let out = run(t, &[physics, &["--tracer", t]].concat());
            let b = read_npy(&out.join("drr.npy")).1;
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() <= 1e-5 * x.abs().max(1e-3), "{t}: {x} vs {y}");
            }
            let sidecar = std::fs::read_to_string(out.join("drr.json")).unwrap();
            assert!(
                sidecar.contains(&format!("\"tracer\": \"{t}\"")),
                "{sidecar}"
            );
        }
    }
    refused(
        dir.path(),
        &[
            (&["--tracer", "fast"], "unknown tracer 'fast'"),
            (
                &["--tracer", "scalar", "--projector", "trilinear"],
                "the trilinear projector has one marcher",
            ),
        ],
    );
}

/// `reconstruct-classical` reads what `project` wrote through the one sidecar definition:
/// an ideal arc reconstructs; a real-detector folder is refused by name.
#[test]
fn reconstruct_classical_reads_the_projection_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    let arc = dir.path().join("arc");
    let mut args = vec![
        "project",
        "-o",
        arc.to_str().unwrap(),
        "--arc",
        "0:10:36",
        "--format",
        "npy",
    ];
    args.extend(SMALL);
    ok(&tomograf(&args));
    let rec = dir.path().join("rec");
    let out = tomograf(&[
        "reconstruct-classical",
        arc.to_str().unwrap(),
        "-o",
        rec.to_str().unwrap(),
    ]);
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stderr).contains("SART-TV from 36 views"));

    let real = dir.path().join("real");
    let mut args = vec![
        "project",
        "-o",
        real.to_str().unwrap(),
        "--view",
        "ap",
        "--format",
        "npy",
        "--preset",
        "kv-flat-panel-120kvp",
    ];
    args.extend(SMALL);
    ok(&tomograf(&args));
    let out = tomograf(&[
        "reconstruct-classical",
        real.to_str().unwrap(),
        "-o",
        rec.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("drr.json") && e.contains("detector signal") && e.contains("does not read"),
        "{e}"
    );
}

/// `train --replot`: the shipped model's losses drawn without training; a file that is not
/// a run's metrics is named.
#[test]
fn train_replots_the_shipped_models_losses() {
    let dir = tempfile::tempdir().unwrap();
    let csv = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/model/checkpoints/demo-metrics.csv"
    );
    ok(&tomograf(&[
        "train",
        "--replot",
        csv,
        "-o",
        dir.path().to_str().unwrap(),
    ]));
    let png = std::fs::read(dir.path().join("loss.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let readme = concat!(env!("CARGO_MANIFEST_DIR"), "/README.md");
    let out = tomograf(&[
        "train",
        "--replot",
        readme,
        "-o",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("is not a training run's metrics.csv"));
}
