//! End to end through the command line: `dataset` → `train` (and `--resume`) →
//! `reconstruct` → `evaluate`, at the `tiny` configuration (seconds), plus the errors a
//! user meets with wrong inputs.

mod common;

use common::{ok, tomograf};
use std::path::Path;

/// The losses of `metrics.csv` (every column but the wall-clock `seconds`).
fn losses(run: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|&i| header[i] != "seconds")
        .collect();
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            keep.iter().map(|&i| f[i]).collect::<Vec<_>>().join(",")
        })
        .collect()
}

fn tiny_dataset(dir: &Path) {
    ok(&tomograf(&[
        "dataset",
        "-o",
        dir.to_str().unwrap(),
        "--phantoms",
        "2",
        "--size",
        "16",
        "--views",
        "10",
    ]));
}

#[test]
fn train_resume_reconstruct_evaluate() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    tiny_dataset(&data);
    let run = tmp.path().join("run");
    let train = |extra: &[&str]| {
        let mut args = vec![
            "train",
            data.to_str().unwrap(),
            "-o",
            run.to_str().unwrap(),
            "--config",
            "tiny",
        ];
        args.extend_from_slice(extra);
        tomograf(&args)
    };
    ok(&train(&["--iterations", "3"]));
    for f in ["metrics.csv", "loss.png", "checkpoint/generator.bpk"] {
        assert!(run.join(f).is_file(), "train wrote no {f}");
    }
    assert_eq!(losses(&run).len(), 3, "one metrics row per iteration");
    ok(&train(&["--resume", "--iterations", "5"]));
    let resumed = losses(&run);
    assert_eq!(resumed.len(), 5, "resume continues to 5 iterations");

    // Reconstruct one item from its AP view (cap 3 iterations), with `extra` flags.
    let vol = tmp.path().join("rec.nii.gz");
    let reconstruct = |extra: &[&str]| {
        let (item, ck) = (data.join("00000"), run.join("checkpoint"));
        let mut args = vec![
            "reconstruct",
            item.to_str().unwrap(),
            "--checkpoint",
            ck.to_str().unwrap(),
            "--views",
            "1",
            "-o",
            vol.to_str().unwrap(),
        ];
        if !extra.contains(&"--iterations") {
            args.extend(["--iterations", "3"]);
        }
        args.extend_from_slice(extra);
        tomograf(&args)
    };
    // A NIfTI volume of finite HU.
    ok(&reconstruct(&[]));
    assert!(vol.is_file());

    // `--spread`: with one fit there is none, and the error says so (the volume is written);
    // with a checkpoint that averages two fits, each voxel's standard deviation across them
    // in HU: finite, ≥ 0, on the volume's grid, and not zero everywhere.
    let spread = tmp.path().join("spread.nii.gz");
    let out = reconstruct(&["--spread", spread.to_str().unwrap()]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("--spread") && e.contains("no spread across fits"),
        "{e}"
    );
    assert!(!spread.exists());
    let ck2 = tmp.path().join("ensemble");
    std::fs::create_dir(&ck2).unwrap();
    for f in std::fs::read_dir(run.join("checkpoint")).unwrap() {
        let f = f.unwrap().path();
        std::fs::copy(&f, ck2.join(f.file_name().unwrap())).unwrap();
    }
    let config = std::fs::read_to_string(ck2.join("config.toml")).unwrap();
    assert!(config.contains("[infer]\n"), "{config}");
    std::fs::write(
        ck2.join("config.toml"),
        config.replace("[infer]\n", "[infer]\nensemble = 2\n"),
    )
    .unwrap();
    let item = data.join("00000");
    ok(&tomograf(&[
        "reconstruct",
        item.to_str().unwrap(),
        "--checkpoint",
        ck2.to_str().unwrap(),
        "--iterations",
        "3",
        "-o",
        vol.to_str().unwrap(),
        "--spread",
        spread.to_str().unwrap(),
    ]));
    let sd = tomograf_datasets::nifti::read_nifti(&spread).unwrap();
    let v = tomograf_datasets::nifti::read_nifti(&vol).unwrap();
    assert_eq!(sd.dims(), v.dims());
    assert!(sd.data().iter().all(|x| x.is_finite() && *x >= 0.0));
    assert!(
        sd.data().iter().any(|&x| x > 0.0),
        "two fits agree everywhere"
    );

    // A stopping threshold every view reaches at once ends inference at the first check
    // (`tiny` checks every 5 iterations; the cap is raised to 12); a threshold that is not
    // a number is refused, naming it.
    let out = reconstruct(&["--psnr-threshold", "-1000", "--iterations", "12"]);
    ok(&out);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("5 iterations,"), "{e}");
    let out = reconstruct(&["--psnr-threshold", "NaN"]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("PSNR threshold NaN"), "{e}");

    // Evaluates the trained checkpoint at `views` (2 inference iterations) into `out`.
    let checkpoint = run.join("checkpoint");
    let evaluate = |views: &str, extra: &[&str], out: &Path| {
        let mut args = vec![
            "evaluate",
            data.to_str().unwrap(),
            "--checkpoint",
            checkpoint.to_str().unwrap(),
            "--views",
            views,
            "--iterations",
            "2",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        ok(&tomograf(&args));
    };

    // Evaluate at 1 and 2 views, with the PCA prior of the training set: every method
    // scored for every item and view count, inside the body too.
    let eval = tmp.path().join("eval");
    evaluate("1,2", &["--train-data", data.to_str().unwrap()], &eval);
    let csv = std::fs::read_to_string(eval.join("results.csv")).unwrap();
    for views in ["1", "2"] {
        for method in [
            "TomoGRAF",
            "TomoGRAF (network only)",
            "mean training volume",
            "SART-TV from the mean",
            "PCA-MAP prior",
            "FDK",
            "SART-TV",
        ] {
            let rows: Vec<&str> = csv
                .lines()
                .filter(|l| {
                    let f: Vec<&str> = l.split(',').collect();
                    f.len() > 5 && f[1] == views && f[2] == method
                })
                .collect();
            assert_eq!(rows.len(), 2, "{method} at {views} view(s): {csv}");
            for r in rows {
                let f: Vec<&str> = r.split(',').collect();
                for i in [3, 8, 9] {
                    let v: f64 = f[i].parse().unwrap();
                    assert!(v.is_finite(), "{r}");
                }
            }
        }
    }
    // Two items: TomoGRAF minus each method, paired, per view count.
    let md = std::fs::read_to_string(eval.join("results.md")).unwrap();
    assert!(
        md.contains("| views | TomoGRAF − | PSNR (dB) | SSIM |"),
        "{md}"
    );
    assert!(md.contains("| 2 | SART-TV from the mean | "), "{md}");
    // Figures for the first item only, unless --all-figures.
    assert!(eval.join("00000_1view_slices.png").is_file());
    assert!(!eval.join("00001_1view_slices.png").exists());
    let all = tmp.path().join("eval-all");
    evaluate("1", &["--no-baselines", "--all-figures"], &all);
    for item in ["00000", "00001"] {
        assert!(all.join(format!("{item}_1view_slices.png")).is_file());
        assert!(all.join(format!("{item}_1view.nii.gz")).is_file());
    }

    // --no-baselines scores the model alone (as the studies' model cells do).
    let model_only = tmp.path().join("eval-model");
    evaluate("1", &["--no-baselines"], &model_only);
    let csv = std::fs::read_to_string(model_only.join("results.csv")).unwrap();
    let methods: std::collections::BTreeSet<&str> = csv
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(2))
        .collect();
    assert_eq!(
        methods,
        [
            "TomoGRAF",
            "TomoGRAF (network only)",
            "mean training volume",
            "SART-TV from the mean"
        ]
        .into(),
        "{csv}"
    );
    // Without a checkpoint there is nothing left to score: clap names the missing flag.
    let out = tomograf(&[
        "evaluate",
        data.to_str().unwrap(),
        "--no-baselines",
        "-o",
        tmp.path().join("eval-none").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("--checkpoint"), "{e}");
}

#[test]
fn training_does_not_depend_on_the_thread_count() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    tiny_dataset(&data);
    let mut runs = Vec::new();
    for threads in ["1", "2"] {
        let run = tmp.path().join(format!("run{threads}"));
        ok(&tomograf(&[
            "--threads",
            threads,
            "train",
            data.to_str().unwrap(),
            "-o",
            run.to_str().unwrap(),
            "--config",
            "tiny",
            "--iterations",
            "3",
        ]));
        runs.push(losses(&run));
    }
    assert_eq!(runs[0], runs[1], "losses with 1 and 2 threads");
}

/// `train --init CHECKPOINT`: a run trained on one set carried on to another, its
/// iteration count going on; the flags it cannot take together are refused by name.
#[test]
fn a_checkpoint_is_fine_tuned_on_another_set() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    tiny_dataset(&a);
    ok(&tomograf(&[
        "dataset",
        "-o",
        b.to_str().unwrap(),
        "--phantoms",
        "3",
        "--seed",
        "7",
        "--size",
        "16",
        "--views",
        "10",
    ]));
    let (run_a, run_b) = (tmp.path().join("run-a"), tmp.path().join("run-b"));
    ok(&tomograf(&[
        "train",
        a.to_str().unwrap(),
        "-o",
        run_a.to_str().unwrap(),
        "--config",
        "tiny",
        "--iterations",
        "3",
    ]));
    let init = run_a.join("checkpoint");
    let fine_tune = |extra: &[&str]| {
        let mut args = vec![
            "train",
            b.to_str().unwrap(),
            "-o",
            run_b.to_str().unwrap(),
            "--init",
            init.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        tomograf(&args)
    };
    let out = fine_tune(&["--iterations", "3"]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("give --iterations beyond 3"), "{e}");
    let out = fine_tune(&["--iterations", "5", "--config", "tiny"]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("--config") && e.contains("--init"), "{e}");

    let out = fine_tune(&["--iterations", "5"]);
    ok(&out);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("from its iteration 3 on 3 new item(s)"), "{e}");
    let iterations: Vec<String> = losses(&run_b)
        .iter()
        .map(|r| r.split(',').next().unwrap().to_string())
        .collect();
    assert_eq!(
        iterations,
        ["4", "5"],
        "metrics go on from the checkpoint's count"
    );
    let codes: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run_b.join("checkpoint/codes.json")).unwrap())
            .unwrap();
    assert_eq!(
        codes["items"],
        serde_json::json!(["00000", "00001", "00002"])
    );
    let config = std::fs::read_to_string(run_b.join("config.toml")).unwrap();
    assert!(
        config.contains("name = \"tiny\""),
        "the checkpoint's configuration: {config}"
    );
    // The run folder now holds its own checkpoint: --resume continues it.
    ok(&fine_tune(&["--resume", "--iterations", "6"]));
    assert_eq!(losses(&run_b).len(), 3);

    // An evaluation folder holds one checkpoint's scores: the fine-tuned checkpoint is
    // refused there, by name, and so is the resumed one in the same folder.
    let eval = tmp.path().join("eval");
    let evaluate = |ck: &Path, eval: &Path| {
        tomograf(&[
            "evaluate",
            b.to_str().unwrap(),
            "--checkpoint",
            ck.to_str().unwrap(),
            "--views",
            "1",
            "--iterations",
            "1",
            "--items",
            "1",
            "--no-baselines",
            "-o",
            eval.to_str().unwrap(),
        ])
    };
    ok(&evaluate(&init, &eval));
    ok(&evaluate(&init, &eval));
    let tuned = run_b.join("checkpoint");
    let refused = |out: std::process::Output| {
        assert!(!out.status.success());
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(e.contains("(another checkpoint)"), "{e}");
    };
    refused(evaluate(&tuned, &eval));
    let eval_b = tmp.path().join("eval-b");
    ok(&evaluate(&tuned, &eval_b));
    ok(&fine_tune(&["--resume", "--iterations", "7"]));
    refused(evaluate(&tuned, &eval_b));

    // Set b re-made with other phantoms under the same ids: resuming run b on it is
    // refused, naming the item whose content changed under its code.
    let b2 = tmp.path().join("b2");
    ok(&tomograf(&[
        "dataset",
        "-o",
        b2.to_str().unwrap(),
        "--phantoms",
        "3",
        "--seed",
        "8",
        "--size",
        "16",
        "--views",
        "10",
    ]));
    let out = tomograf(&[
        "train",
        b2.to_str().unwrap(),
        "-o",
        run_b.to_str().unwrap(),
        "--resume",
        "--iterations",
        "8",
    ]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("item 00000") && e.contains("learned its code on"),
        "{e}"
    );

    // --init on the very items the checkpoint learned its codes on keeps them (and their
    // optimiser state): the run is the checkpoint resumed, loss for loss.
    let (run_c, run_d) = (tmp.path().join("run-c"), tmp.path().join("run-d"));
    let out = tomograf(&[
        "train",
        a.to_str().unwrap(),
        "-o",
        run_c.to_str().unwrap(),
        "--init",
        init.to_str().unwrap(),
        "--iterations",
        "5",
    ]);
    ok(&out);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("their codes are kept"), "{e}");
    std::fs::create_dir_all(run_d.join("checkpoint")).unwrap();
    for f in std::fs::read_dir(&init).unwrap() {
        let f = f.unwrap().path();
        std::fs::copy(&f, run_d.join("checkpoint").join(f.file_name().unwrap())).unwrap();
    }
    std::fs::copy(run_a.join("metrics.csv"), run_d.join("metrics.csv")).unwrap();
    ok(&tomograf(&[
        "train",
        a.to_str().unwrap(),
        "-o",
        run_d.to_str().unwrap(),
        "--resume",
        "--iterations",
        "5",
    ]));
    let resumed = losses(&run_d);
    assert_eq!(losses(&run_c), resumed[resumed.len() - 2..]);
    assert_eq!(
        std::fs::read(run_c.join("checkpoint/codes.bpk")).unwrap(),
        std::fs::read(run_d.join("checkpoint/codes.bpk")).unwrap()
    );
}

#[test]
fn wrong_inputs_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("no-such-set");
    let out = tomograf(&[
        "train",
        missing.to_str().unwrap(),
        "-o",
        tmp.path().join("run").to_str().unwrap(),
        "--config",
        "tiny",
    ]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("no-such-set"), "{e}");

    let data = tmp.path().join("data");
    tiny_dataset(&data);
    let out = tomograf(&[
        "train",
        data.to_str().unwrap(),
        "-o",
        tmp.path().join("run").to_str().unwrap(),
        "--config",
        "no-such-preset",
    ]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("no-such-preset"), "{e}");
    let out = tomograf(&[
        "reconstruct",
        data.join("00000").to_str().unwrap(),
        "--checkpoint",
        crate_checkpoint().to_str().unwrap(),
        "--views",
        "0",
        "-o",
        tmp.path().join("r.nii.gz").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("view"), "{e}");
    assert!(!tmp.path().join("r.nii.gz").exists(), "no output on error");

    // The shipped checkpoint's mean volume is 64³: the mean-volume baseline cannot score a
    // 16³ item, and says so with both sizes.
    let out = tomograf(&[
        "evaluate",
        data.to_str().unwrap(),
        "--checkpoint",
        crate_checkpoint().to_str().unwrap(),
        "--views",
        "1",
        "--items",
        "1",
        "--iterations",
        "2",
        "-o",
        tmp.path().join("ev16").to_str().unwrap(),
    ]);
    assert!(
        !out.status.success(),
        "a 16³ item against a 64³ mean volume must fail"
    );
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("[64, 64, 64]") && e.contains("[16, 16, 16]"),
        "the error names the sizes that do not fit: {e}"
    );
}

fn crate_checkpoint() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("model/checkpoints/demo")
}

#[test]
fn model_bench_prints_ratios_against_its_baselines() {
    let out = tomograf(&["bench", "--model", "--quick", "--repeats", "1"]);
    ok(&out);
    let md = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "training step, `tiny`",
        "1-view inference",
        "SART-TV",
        "| ratio |",
    ] {
        assert!(md.contains(needle), "no '{needle}' in: {md}");
    }
}

/// The second shipped checkpoint (`model/checkpoints/lidc-full-chest`, docs/model.md, "A
/// prior that transfers: a mixed population"): the shipped recipe on 32 `lidc` and 32
/// `full-chest` phantoms and those shape-augmented with heterogeneous soft tissue (then
/// warped, then cut to scan ranges: decisions 9 and 17), trained for the iterations its
/// `state.json` records, with the demo checkpoint's
/// inference settings. It loads and reconstructs a 64³ full-chest phantom from one view to
/// a finite volume, and its settings differ from the demo checkpoint's in nothing but what
/// it learnt, for how long, the open gate from 5 views, the four fits averaged from one view
/// and the blend where they disagree its own validation chose (decisions 14, 18 and 21).
#[test]
fn the_mixed_population_checkpoint_reconstructs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("model/checkpoints");
    let mixed = root.join("lidc-full-chest");
    // The same settings but for how long each trained: the first `iterations = ` line (the
    // training's; the one in [infer] is the inference cap) is left out, and the open gate
    // from 5 views and the ensemble from one view the mixed checkpoint's validation chose
    // (their comments and lines).
    let config = |d: &Path| {
        let text = std::fs::read_to_string(d.join("config.toml")).unwrap();
        let trained = text.lines().position(|l| l.starts_with("iterations = "));
        assert!(
            trained.is_some(),
            "no training iteration count in {}",
            d.display()
        );
        text.lines()
            .enumerate()
            .filter(|&(i, _)| Some(i) != trained)
            .map(|(_, l)| l)
            .take_while(|l| !l.starts_with("# Chosen on validation phantoms matched to real CTs"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(config(&mixed), config(&root.join("demo")), "config.toml");
    let text = std::fs::read_to_string(mixed.join("config.toml")).unwrap();
    assert!(text.contains("\nrefine_always_from_views = 5\n"), "{text}");
    assert!(
        text.contains("\nensemble = 4\nensemble_code_sd = 1.0\nensemble_max_views = 1\n"),
        "{text}"
    );
    // Decisions 18 and 21: SART-TV from the mean blended in where the one-view fits
    // disagree, only when their average explains the view below 40 dB, then at weight 0.75 ×
    // ½ where their spread is 50 HU (50 / 3072 of the window).
    assert!(
        text.trim_end().ends_with(
            "\nmean_sweeps_weight = 0.0\nmean_sweeps_spread = 0.016276041666666668\n\
             mean_sweeps_below_db = 40.0\nmean_sweeps_weight_below = 0.75"
        ),
        "{text}"
    );
    assert!((0.016276041666666668f64 * 3072.0 - 50.0).abs() < 1e-9);
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    ok(&tomograf(&[
        "dataset",
        "-o",
        data.to_str().unwrap(),
        "--phantoms",
        "1",
        "--seed",
        "90000",
        "--profile",
        "full-chest",
        "--size",
        "64",
        "--views",
        "10",
    ]));
    let out_file = tmp.path().join("r.nii.gz");
    ok(&tomograf(&[
        "reconstruct",
        data.join("00000").to_str().unwrap(),
        "--checkpoint",
        mixed.to_str().unwrap(),
        "--views",
        "1",
        "--iterations",
        "5",
        "-o",
        out_file.to_str().unwrap(),
    ]));
    assert!(out_file.exists());
}
