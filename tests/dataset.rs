//! End-to-end tests of `tomograf dataset`: outputs, resume after a kill, shards.

use std::path::Path;
use std::process::Command;

fn tomograf(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tomograf"))
        .args(args)
        .output()
        .expect("runs")
}

fn ok(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Every file under `dir` (relative path → bytes), sorted.
fn tree(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((
                    p.strip_prefix(dir).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

const JOB: [&str; 6] = ["--phantoms", "3", "--size", "24", "--views", "6"];

#[test]
fn makes_items_with_manifest_and_normalised_ct() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let mut args = vec!["dataset", "-o", d];
    args.extend(JOB);
    ok(&tomograf(&args));
    let manifest = std::fs::read_to_string(dir.path().join("manifest.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = manifest
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[2]["source"]["spec"]["seed"], 2);
    assert_eq!(lines[2]["source"]["spec"]["profile"], "lidc-cropped");
    assert_eq!(
        lines[0]["angles_deg"].as_array().unwrap().len(),
        8,
        "6 views + AP + lateral"
    );
    // Projections: 8 × 24 × 24 finite line integrals, tissue in the middle.
    let bytes = std::fs::read(dir.path().join("00001/projections.npy")).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    assert_eq!(npy.shape(), &[8, 24, 24]);
    let p = npy.into_vec::<f32>().unwrap();
    assert!(p.iter().all(|v| v.is_finite() && *v >= 0.0) && p[12 * 24 + 12] > 1.0);
    // CT: 24³ in [0, 1], with air (0) and tissue present.
    let ct = tomograf_datasets::nifti::read_nifti(&dir.path().join("00001/ct.nii.gz")).unwrap();
    assert_eq!(ct.dims(), [24, 24, 24]);
    let (lo, hi) = ct.min_max();
    assert!(lo >= 0.0 && hi <= 1.0 && hi > 0.3, "{lo} {hi}");
    // Different seeds, different items.
    assert_ne!(
        std::fs::read(dir.path().join("00000/projections.npy")).unwrap(),
        std::fs::read(dir.path().join("00001/projections.npy")).unwrap()
    );
}

#[test]
fn resumes_after_a_kill_and_shards_give_the_same_bytes() {
    let one = tempfile::tempdir().unwrap();
    let mut args = vec!["dataset", "-o", one.path().to_str().unwrap()];
    args.extend(JOB);
    ok(&tomograf(&args));
    let reference = tree(one.path());

    // A run killed while writing item 1: its item.json is missing and a file is cut short.
    std::fs::remove_file(one.path().join("00001/item.json")).unwrap();
    let npy = one.path().join("00001/projections.npy");
    let cut = std::fs::read(&npy).unwrap();
    std::fs::write(&npy, &cut[..cut.len() / 2]).unwrap();
    let out = tomograf(&args);
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stderr).contains("1 item(s) made, 2 already finished"));
    assert_eq!(tree(one.path()), reference, "resumed run differs");

    // Two shards, one of them on one thread, into another folder: the same bytes.
    let sharded = tempfile::tempdir().unwrap();
    for (shard, threads) in [("1/2", "1"), ("0/2", "2")] {
        let mut a = vec![
            "--threads",
            threads,
            "dataset",
            "-o",
            sharded.path().to_str().unwrap(),
            "--shard",
            shard,
        ];
        a.extend(JOB);
        ok(&tomograf(&a));
    }
    assert_eq!(tree(sharded.path()), reference, "sharded run differs");
    assert!(
        !tree(sharded.path()).iter().any(|(p, _)| p.contains("tmp")),
        "temporary files left"
    );
}

#[test]
fn bad_arguments_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    for (extra, msg) in [
        (vec!["--phantoms", "1", "--shard", "2/2"], "must be I/N"),
        (vec!["--phantoms", "1", "--hu-window", "100,-100"], "window"),
        (vec![], "nothing to do"),
        (vec!["/nonexistent/ct.nii.gz"], "ct.nii.gz"),
        (
            vec!["--phantoms", "1", "--heterogeneity", "-3"],
            "--heterogeneity -3 HU",
        ),
        (
            vec!["--phantoms", "1", "--organ-spread", "4"],
            "--organ-spread 4 is outside 0–3",
        ),
        (
            vec!["--phantoms", "1", "--deform", "-2"],
            "--deform -2 mm is outside 0–30 mm",
        ),
    ] {
        let mut args = vec!["dataset", "-o", d];
        args.extend(extra.iter().copied());
        let out = tomograf(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(msg) && !err.contains("panicked"),
            "{extra:?}: {err}"
        );
    }
}

#[test]
fn a_scan_range_keeps_its_stretch_of_the_body_and_is_recorded() {
    // The same two phantoms whole and cut to drawn scan ranges: each cut item records its
    // range, and its CT spans that fraction of the whole item's length (to a section of the
    // full-resolution phantom at either end).
    let dir = tempfile::tempdir().unwrap();
    let (whole, cut) = (dir.path().join("whole"), dir.path().join("cut"));
    let job = ["--phantoms", "2", "--size", "24", "--views", "4"];
    let mut args = vec!["dataset", "-o", whole.to_str().unwrap()];
    args.extend(job);
    ok(&tomograf(&args));
    let mut args = vec!["dataset", "-o", cut.to_str().unwrap(), "--scan-range", "5"];
    args.extend(job);
    ok(&tomograf(&args));
    for id in ["00000", "00001"] {
        let record: serde_json::Value =
            serde_json::from_slice(&std::fs::read(cut.join(id).join("item.json")).unwrap())
                .unwrap();
        let (from, to) = (
            record["scan_range"]["from"].as_f64().unwrap(),
            record["scan_range"]["to"].as_f64().unwrap(),
        );
        assert!(0.0 <= from && from + 0.5 <= to && to <= 1.0, "{from} {to}");
        let plain: serde_json::Value =
            serde_json::from_slice(&std::fs::read(whole.join(id).join("item.json")).unwrap())
                .unwrap();
        assert!(plain.get("scan_range").is_none(), "no range, no record");
        let length = |d: &Path| {
            let ct = tomograf_datasets::nifti::read_nifti(&d.join(id).join("ct.nii.gz")).unwrap();
            ct.spacing().z * ct.dims()[2] as f64
        };
        let (l_whole, l_cut) = (length(&whole), length(&cut));
        let tolerance = 2.0 * 2.5 / l_whole; // two sections of the generator's ≤ 2.5 mm grid
        assert!(
            ((l_cut / l_whole) - (to - from)).abs() <= tolerance,
            "{id}: {l_cut} of {l_whole} mm against the range {from}–{to}"
        );
    }
}
