//! `tomograf tune-baselines` → `tomograf evaluate --baselines`, at 16³ (seconds): the
//! chosen settings are the search's best by mean PSNR (recomputed here from search.csv),
//! `evaluate` with them reproduces the search's scores of those settings to the printed
//! digit, and the errors a user meets with a file tuned for other view counts.

mod common;

use common::{ok, tomograf};
use std::collections::BTreeMap;
use std::path::Path;

fn dataset(dir: &Path, phantoms: &str, seed: &str) {
    ok(&tomograf(&[
        "dataset",
        "-o",
        dir.to_str().unwrap(),
        "--phantoms",
        phantoms,
        "--seed",
        seed,
        "--size",
        "16",
        "--views",
        "10",
    ]));
}

/// `(item, views, method, setting) → (PSNR text, PSNR)` of search.csv.
type Search = BTreeMap<(String, String, String, String), (String, f64)>;

fn read_search(path: &Path) -> Search {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "item,views,method,setting,psnr_db,ssim,body_psnr_db,body_ssim"
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 8, "{l}");
            let psnr: f64 = f[4].parse().unwrap();
            assert!(psnr.is_finite(), "{l}");
            (
                (f[0].into(), f[1].into(), f[2].into(), f[3].into()),
                (f[4].to_string(), psnr),
            )
        })
        .collect()
}

/// The setting label of the chosen `method` in a parsed baselines.toml, as search.csv
/// writes it.
fn chosen(toml: &toml::Table, views: &str, method: &str) -> String {
    let v = toml["views"][views].as_table().unwrap();
    let sart = |key: &str| {
        let s = v[key].as_table().unwrap();
        let step = s["tv_step"].as_float().unwrap();
        format!(
            "{} sweeps; TV step {step}",
            s["sweeps"].as_integer().unwrap()
        )
    };
    match method {
        "SART-TV" => sart("sart_tv"),
        "SART-TV from the mean" => sart("sart_tv_from_mean"),
        "PCA-MAP prior" => {
            let p = v["pca_map"].as_table().unwrap();
            let c = p
                .get("components")
                .map_or("all".to_string(), |c| c.as_integer().unwrap().to_string());
            format!("noise {}; {c} components", p["noise"].as_float().unwrap())
        }
        "FDK" => {
            let w = v["fdk_window"].as_str().unwrap();
            let name = match w {
                "ram-lak" => "RamLak",
                "shepp-logan" => "SheppLogan",
                "cosine" => "Cosine",
                "hann" => "Hann",
                _ => panic!("window {w}"),
            };
            format!("{name} window")
        }
        _ => unreachable!(),
    }
}

#[test]
fn tuned_settings_are_the_search_best_and_evaluate_reproduces_them() {
    let tmp = tempfile::tempdir().unwrap();
    let (train, val) = (tmp.path().join("train"), tmp.path().join("val"));
    dataset(&train, "3", "0");
    dataset(&val, "2", "70000");
    let out = tmp.path().join("tune");
    let tune = |views: &str| {
        tomograf(&[
            "tune-baselines",
            val.to_str().unwrap(),
            "--train-data",
            train.to_str().unwrap(),
            "--views",
            views,
            "-o",
            out.to_str().unwrap(),
        ])
    };
    let run = tune("1,2");
    ok(&run);
    let printed = String::from_utf8_lossy(&run.stdout).to_string();
    assert!(printed.contains("## SART-TV, 1 view(s)"), "{printed}");
    let search = read_search(&out.join("search.csv"));
    // 25 SART-TV settings for each start, 28 PCA-MAP, 4 FDK; 2 items × 2 view counts.
    assert_eq!(search.len(), 82 * 2 * 2);
    let text = std::fs::read_to_string(out.join("baselines.toml")).unwrap();
    let toml: toml::Table = toml::from_str(&text).unwrap();
    for views in ["1", "2"] {
        for method in ["SART-TV", "SART-TV from the mean", "PCA-MAP prior", "FDK"] {
            let mut means: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
            for ((_, v, m, s), (_, p)) in &search {
                if v == views && m == method {
                    means.entry(s.as_str()).or_default().push(*p);
                }
            }
            let mean = |s: &str| means[s].iter().sum::<f64>() / means[s].len() as f64;
            let best = means
                .keys()
                .map(|s| mean(s))
                .fold(f64::NEG_INFINITY, f64::max);
            let pick = chosen(&toml, views, method);
            assert!(means.contains_key(pick.as_str()), "{pick} not searched");
            assert_eq!(mean(&pick), best, "{method}, {views} view(s): {pick}");
            assert!(means.values().all(|v| v.len() == 2));
        }
    }
    // Resuming re-reads the items and writes the same choice; another search is refused.
    ok(&tune("1,2"));
    assert_eq!(
        std::fs::read_to_string(out.join("baselines.toml")).unwrap(),
        text
    );
    let other = tune("1");
    assert!(!other.status.success());
    assert!(String::from_utf8_lossy(&other.stderr).contains("another search"));

    // evaluate with the file scores what the search scored for the chosen settings.
    let eval = tmp.path().join("eval");
    let file = out.join("baselines.toml");
    let evaluate = |views: &str, dir: &Path| {
        tomograf(&[
            "evaluate",
            val.to_str().unwrap(),
            "--train-data",
            train.to_str().unwrap(),
            "--baselines",
            file.to_str().unwrap(),
            "--views",
            views,
            "-o",
            dir.to_str().unwrap(),
        ])
    };
    ok(&evaluate("1,2", &eval));
    let mut compared = 0;
    for item in ["00000", "00001"] {
        let csv = std::fs::read_to_string(eval.join("items").join(format!("{item}.csv"))).unwrap();
        for line in csv.lines().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let (views, method) = (f[1], f[2]);
            if method == "mean training volume" {
                continue; // nothing to tune
            }
            let key = (
                item.to_string(),
                views.to_string(),
                method.to_string(),
                chosen(&toml, views, method),
            );
            let (psnr, _) = &search[&key];
            assert_eq!(f[3], psnr, "{line}");
            compared += 1;
        }
    }
    // SART-TV from the mean (of the training CTs, without a checkpoint), PCA-MAP, FDK and
    // SART-TV.
    assert_eq!(compared, 2 * 2 * 4);
    // A file tuned for 1 and 2 views does not stand in for 5.
    let e = evaluate("5", &tmp.path().join("eval5"));
    assert!(!e.status.success());
    let msg = String::from_utf8_lossy(&e.stderr);
    assert!(msg.contains("tuned for 1, 2 view(s), not 5"), "{msg}");
    // --pca-noise and --baselines together are refused (the file sets the noise).
    let both = tomograf(&[
        "evaluate",
        val.to_str().unwrap(),
        "--train-data",
        train.to_str().unwrap(),
        "--baselines",
        file.to_str().unwrap(),
        "--pca-noise",
        "0.1",
        "-o",
        tmp.path().join("eval-both").to_str().unwrap(),
    ]);
    assert!(!both.status.success());
}

#[test]
fn the_shipped_checkpoints_settings_cover_the_papers_view_counts() {
    // `tomograf demo` reads them; every view count of the paper must be there.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("model/checkpoints/demo/baselines.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let t: toml::Table = toml::from_str(&text).unwrap();
    for views in ["1", "2", "5", "10"] {
        let v = t["views"][views].as_table().unwrap();
        for key in [
            "sart_tv",
            "sart_tv_from_mean",
            "pca_map",
            "fdk_window",
            "tomograf_sweeps",
        ] {
            assert!(v.contains_key(key), "views {views}: no {key}");
        }
    }
    assert!(t["tuned_on"].as_str().unwrap().contains("70000"));
}

/// `tune-baselines --checkpoint`: TomoGRAF's data-consistency sweeps are searched on the
/// SART-TV grid (its network once per item and view count), the choice is the search's best
/// by mean PSNR, `evaluate --checkpoint --baselines` runs the chosen sweeps and scores what
/// the search scored, and a sweeps override beside such a file is refused.
#[test]
fn the_checkpoints_sweeps_are_tuned_alike() {
    let tmp = tempfile::tempdir().unwrap();
    let (train, val) = (tmp.path().join("train"), tmp.path().join("val"));
    dataset(&train, "3", "0");
    dataset(&val, "1", "70000");
    let run = tmp.path().join("run");
    ok(&tomograf(&[
        "train",
        train.to_str().unwrap(),
        "-o",
        run.to_str().unwrap(),
        "--config",
        "tiny",
        "--iterations",
        "4",
    ]));
    let ck = run.join("checkpoint");
    let out = tmp.path().join("tune");
    let printed = tomograf(&[
        "tune-baselines",
        val.to_str().unwrap(),
        "--train-data",
        train.to_str().unwrap(),
        "--checkpoint",
        ck.to_str().unwrap(),
        "--views",
        "1",
        "-o",
        out.to_str().unwrap(),
    ]);
    ok(&printed);
    let md = String::from_utf8_lossy(&printed.stdout).to_string();
    assert!(md.contains("## TomoGRAF, 1 view(s)"), "{md}");
    let search = read_search(&out.join("search.csv"));
    // 25 sweep settings each for TomoGRAF and both SART-TV starts, 28 PCA-MAP, 4 FDK.
    assert_eq!(search.len(), 82 + 25);
    let tomograf_rows: BTreeMap<&str, f64> = search
        .iter()
        .filter(|((_, _, m, _), _)| m == "TomoGRAF")
        .map(|((_, _, _, s), (_, p))| (s.as_str(), *p))
        .collect();
    assert_eq!(tomograf_rows.len(), 25);
    let text = std::fs::read_to_string(out.join("baselines.toml")).unwrap();
    let toml: toml::Table = toml::from_str(&text).unwrap();
    let s = toml["views"]["1"]["tomograf_sweeps"].as_table().unwrap();
    let pick = format!(
        "{} sweeps; TV step {}",
        s["sweeps"].as_integer().unwrap(),
        s["tv_step"].as_float().unwrap()
    );
    let best = tomograf_rows
        .values()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(tomograf_rows[pick.as_str()], best, "{pick}");

    let file = out.join("baselines.toml");
    let evaluate = |dir: &str, extra: &[&str]| {
        let mut args = vec![
            "evaluate",
            val.to_str().unwrap(),
            "--checkpoint",
            ck.to_str().unwrap(),
            "--baselines",
            file.to_str().unwrap(),
            "--views",
            "1",
            "--no-baselines",
        ];
        let dir = tmp.path().join(dir);
        args.extend(["-o", dir.to_str().unwrap()]);
        args.extend(extra);
        (tomograf(&args), dir)
    };
    let (e, dir) = evaluate("eval", &[]);
    ok(&e);
    let csv = std::fs::read_to_string(dir.join("items/00000.csv")).unwrap();
    let row = csv
        .lines()
        .find(|l| l.starts_with("00000,1,TomoGRAF,"))
        .unwrap();
    let key = ("00000".into(), "1".into(), "TomoGRAF".into(), pick.clone());
    assert_eq!(
        row.split(',').nth(3),
        Some(search[&key].0.as_str()),
        "{row}"
    );
    let (e, _) = evaluate("eval-refine", &["--refine", "5"]);
    assert!(!e.status.success());
    let msg = String::from_utf8_lossy(&e.stderr);
    assert!(msg.contains("leave out --refine"), "{msg}");

    // A checkpoint whose sweeps start where left-out views say (refine_start =
    // "held-out"), from 2 views: the search's TomoGRAF row for its choice is what
    // `evaluate` scores with it (the start does not depend on the sweeps searched after it).
    let ck2 = tmp.path().join("checkpoint-held-out");
    std::fs::create_dir_all(&ck2).unwrap();
    for f in std::fs::read_dir(&ck).unwrap() {
        let f = f.unwrap().path();
        std::fs::copy(&f, ck2.join(f.file_name().unwrap())).unwrap();
    }
    let config = std::fs::read_to_string(ck2.join("config.toml")).unwrap();
    assert!(config.contains("refine_start = \"fixed\""), "{config}");
    // No view explained, so that the start is chosen (this tiny model explains one view).
    assert!(config.contains("refine_below_db = 30.0"), "{config}");
    let config = config
        .replace("refine_start = \"fixed\"", "refine_start = \"held-out\"")
        .replace("refine_below_db = 30.0", "refine_below_db = 1000.0");
    std::fs::write(ck2.join("config.toml"), config).unwrap();
    let out2 = tmp.path().join("tune-held-out");
    ok(&tomograf(&[
        "tune-baselines",
        val.to_str().unwrap(),
        "--train-data",
        train.to_str().unwrap(),
        "--checkpoint",
        ck2.to_str().unwrap(),
        "--views",
        "2",
        "-o",
        out2.to_str().unwrap(),
    ]));
    let search2 = read_search(&out2.join("search.csv"));
    let text = std::fs::read_to_string(out2.join("baselines.toml")).unwrap();
    let toml: toml::Table = toml::from_str(&text).unwrap();
    let s = toml["views"]["2"]["tomograf_sweeps"].as_table().unwrap();
    let pick2 = format!(
        "{} sweeps; TV step {}",
        s["sweeps"].as_integer().unwrap(),
        s["tv_step"].as_float().unwrap()
    );
    let dir = tmp.path().join("eval-held-out");
    let e = tomograf(&[
        "evaluate",
        val.to_str().unwrap(),
        "--checkpoint",
        ck2.to_str().unwrap(),
        "--baselines",
        out2.join("baselines.toml").to_str().unwrap(),
        "--views",
        "2",
        "--no-baselines",
        "-o",
        dir.to_str().unwrap(),
    ]);
    ok(&e);
    let notes = String::from_utf8_lossy(&e.stderr);
    assert!(
        notes.contains("left-out views"),
        "the left-out choice ran: {notes}"
    );
    let csv = std::fs::read_to_string(dir.join("items/00000.csv")).unwrap();
    let row = csv
        .lines()
        .find(|l| l.starts_with("00000,2,TomoGRAF,"))
        .unwrap();
    let key = ("00000".into(), "2".into(), "TomoGRAF".into(), pick2);
    assert_eq!(
        row.split(',').nth(3),
        Some(search2[&key].0.as_str()),
        "{row}"
    );
}

/// Evaluation shards run the same search at once (a study's `--stage evaluate --shard i/n`):
/// shard 1 of 2 begins halfway through the items instead of scoring the same ones beside
/// shard 0, and its search, choice and files are byte-identical to one process's.
#[test]
fn a_search_begun_halfway_chooses_and_writes_alike() {
    use tomograf_eval::tuning::{Grid, Tuning, tune};
    use tomograf_model::scatter_correction::ScatterCorrection;
    let tmp = tempfile::tempdir().unwrap();
    let (train, val) = (tmp.path().join("train"), tmp.path().join("val"));
    dataset(&train, "2", "0");
    dataset(&val, "3", "900");
    let run = |out: &Path, shard| {
        tune(&Tuning {
            data: &val,
            split: None,
            items: None,
            train_data: &train,
            views: &[1, 2],
            scatter_correction: ScatterCorrection::None,
            checkpoint: None,
            seed: 0,
            backend: None,
            grid: Grid::Smoke,
            output: out,
            shard,
            progress: &tomograf_scene::Silent,
        })
        .unwrap()
    };
    let (one, half) = (tmp.path().join("one"), tmp.path().join("half"));
    let a = run(&one, (0, 1));
    let b = run(&half, (1, 2));
    // Shard 1 of 2 scored items 1, 2, then 0 (3 items: it begins at 1·3/2 = 1).
    let made = |id: &str| {
        std::fs::metadata(half.join("items").join(format!("{id}.csv")))
            .and_then(|m| m.modified())
            .unwrap()
    };
    assert!(made("00001") <= made("00002") && made("00002") <= made("00000"));
    assert_eq!(a.1, b.1);
    for file in ["search.csv", "search.md", "baselines.toml"] {
        assert_eq!(
            std::fs::read(one.join(file)).unwrap(),
            std::fs::read(half.join(file)).unwrap(),
            "{file}"
        );
    }
}
