//! The study report: `results.csv` (mean ± std per train set × test set × views × method),
//! `report.md` and `report.html` (the same content) with metric tables, plots (metric vs
//! views, metric vs realism level or shift, SSIM histograms as the paper's Fig. 4) and the
//! evaluations' example slices, residual maps and line profiles.

mod compute;
mod examples;
mod paired;
mod plots;

use super::coverage::Coverage;
use super::effects::{self, Effect, NEGLIGIBLE_PCT};
use super::render::{Block, render};
use super::{Kind, Study, VIEWS, eval_dir_in};
use crate::evaluation::{NETWORK_ONLY, Row, Scores, merge};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::Path;
use std::path::PathBuf;
use tomograf_datasets::atomic::write_atomic;
use tomograf_model::metrics::mean_std;

/// The baseline that starts from the model's mean training volume.
const MEAN_SART: &str = "SART-TV from the mean";

/// Scores of one method on one test set from one view count, over the test items.
struct Stat {
    /// Training set of the model (`None` for the classical baselines).
    train: Option<String>,
    test: String,
    views: usize,
    method: String,
    scores: Vec<Scores>,
    /// The items of `scores`, in their order.
    items: Vec<String>,
}

#[derive(Clone, Copy)]
enum Metric {
    Ssim,
    Psnr,
    Rmse,
}

impl Metric {
    const ALL: [Metric; 3] = [Metric::Ssim, Metric::Psnr, Metric::Rmse];
    fn of(self, s: &Scores) -> f64 {
        match self {
            Metric::Ssim => s.ssim,
            Metric::Psnr => s.psnr,
            Metric::Rmse => s.rmse_hu,
        }
    }
    fn name(self) -> &'static str {
        match self {
            Metric::Ssim => "SSIM",
            Metric::Psnr => "PSNR (dB)",
            Metric::Rmse => "RMSE (HU)",
        }
    }
    fn file(self) -> &'static str {
        match self {
            Metric::Ssim => "ssim",
            Metric::Psnr => "psnr",
            Metric::Rmse => "rmse",
        }
    }
    fn format(self, (m, s): (f64, f64)) -> String {
        match self {
            Metric::Ssim => format!("{m:.3} ± {s:.3}"),
            Metric::Psnr => format!("{m:.2} ± {s:.2}"),
            Metric::Rmse => format!("{m:.1} ± {s:.1}"),
        }
    }
}

impl Stat {
    fn mean_std(&self, m: Metric) -> (f64, f64) {
        mean_std(&self.scores.iter().map(|s| m.of(s)).collect::<Vec<_>>())
    }

    /// (item, score) pairs of metric `m`.
    fn per_item(&self, m: Metric) -> Vec<(String, f64)> {
        self.items
            .iter()
            .cloned()
            .zip(self.scores.iter().map(|s| m.of(s)))
            .collect()
    }
}

fn stats_of(rows: &[Row], train: Option<&str>, test: &str, out: &mut Vec<Stat>) {
    for r in rows {
        match out.iter_mut().find(|s| {
            s.train.as_deref() == train
                && s.test == test
                && s.views == r.views
                && s.method == r.method
        }) {
            Some(s) => {
                s.scores.push(r.scores);
                s.items.push(r.item.clone());
            }
            None => out.push(Stat {
                train: train.map(str::to_string),
                test: test.into(),
                views: r.views,
                method: r.method.clone(),
                scores: vec![r.scores],
                items: vec![r.item.clone()],
            }),
        }
    }
}

/// Writes the study's results, figures and report from its evaluation folders.
/// With `partial`, from the items scored so far: every cell is averaged over the test
/// phantoms scored in every cell that has any, so that all numbers compare the same
/// phantoms, and the report says which (and which cells have nothing yet). Otherwise every
/// evaluation must be complete.
pub fn write(study: &Study, partial: bool) -> Result<()> {
    let s = &study.settings;
    // The folders whose scores are reported: this one, or the pooled runs (their items
    // named `s<seed>/<item>`).
    let pooled = study.pooled()?;
    let sources: Vec<(PathBuf, Option<u64>)> = if pooled.is_empty() {
        vec![(study.dir.clone(), None)]
    } else {
        pooled
            .iter()
            .map(|(d, seed)| (d.clone(), Some(*seed)))
            .collect()
    };
    // (test set, train set or None for the classical cell, its rows).
    let mut cells = Vec::new();
    for test in &s.test_sets {
        let trains = std::iter::once(None).chain(s.train_sets.iter().map(|t| Some(t.as_str())));
        for train in trains {
            let mut rows = Vec::new();
            for (root, seed) in &sources {
                let dir = eval_dir_in(root, test, train);
                if partial && !dir.join("job.json").exists() {
                    continue;
                }
                let mut got = merge(&dir, partial)
                    .with_context(|| {
                        format!(
                            "{}: run the evaluate stage (on every shard) first, or report on \
                             the items scored so far with --partial",
                            dir.display()
                        )
                    })?
                    .1;
                if let Some(seed) = seed {
                    for r in &mut got {
                        r.item = format!("s{seed}/{}", r.item);
                    }
                }
                rows.extend(got);
            }
            cells.push((test.clone(), train, rows));
        }
    }
    let (coverage, cells) = Coverage::of(cells);
    let mut stats = Vec::new();
    for (test, train, rows) in &cells {
        stats_of(rows, *train, test, &mut stats);
    }
    let first_item = coverage.first_item(&s.test_sets);
    write_csv(&study.dir, &stats)?;
    let figures = study.dir.join("figures");
    std::fs::create_dir_all(&figures)?;
    let mut blocks = intro(study);
    blocks.extend(coverage.paragraph(study));
    blocks.extend(effects_table(&effects::load_or_measure(study)?));
    blocks.extend(tables(study, &stats));
    blocks.extend(paired::paired_tables(study, &stats));
    blocks.extend(baselines_table(study));
    blocks.extend(plots::plots(study, &stats)?);
    if let Some(id) = first_item.filter(|_| pooled.is_empty()) {
        blocks.extend(examples::examples(study, &id));
    }
    let roots: Vec<PathBuf> = sources.iter().map(|(d, _)| d.clone()).collect();
    blocks.extend(compute::compute_table(study, &roots, &cells));
    let (md, html) = render(&blocks, title(s.kind));
    write_atomic(&study.dir.join("report.md"), |w| {
        std::io::Write::write_all(w, md.as_bytes())
    })?;
    write_atomic(&study.dir.join("report.html"), |w| {
        std::io::Write::write_all(w, html.as_bytes())
    })?;
    Ok(())
}

/// The baselines' settings each test set was scored with, as its classical cell's
/// `job.json` records them (chosen on the set's validation phantoms by the evaluate stage;
/// absent in folders evaluated before tuning existed: the defaults).
fn baselines_table(study: &Study) -> Vec<Block> {
    let mut rows = Vec::new();
    let mut untuned = Vec::new();
    for test in &study.settings.test_sets {
        let path = eval_dir_in(&study.dir, test, None).join("job.json");
        let job: Option<crate::evaluation::Job> = std::fs::read(&path)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok());
        let Some(tuned) = job.and_then(|j| j.baselines) else {
            untuned.push(format!("`{test}`"));
            continue;
        };
        for (views, v) in &tuned.views {
            let sart = |s: &tomograf_model::baseline::SartTvSettings| {
                format!("{} sweeps, TV {}", s.sweeps, s.tv_step)
            };
            rows.push(vec![
                format!("`{test}`"),
                views.clone(),
                sart(&v.sart_tv),
                sart(&v.sart_tv_from_mean),
                format!(
                    "noise {}, {} components",
                    v.pca_map.noise,
                    v.pca_map.components.map_or("all".into(), |c| c.to_string())
                ),
                format!("{:?}", v.fdk_window),
            ]);
        }
    }
    let mut out = vec![
        Block::Heading("The baselines' settings, chosen on validation".into()),
        Block::Para(
            "Each test set's baselines were tuned on its own validation phantoms (the same \
             population and acquisition, other seeds; `tune/<set>/search.md` holds the whole \
             search) by the highest mean PSNR per method and view count, with the mean volume \
             and PCA-MAP prior of the training set of the same acquisition (else the first): \
             every baseline at its best for the set it is scored on. TomoGRAF's own settings are its checkpoint's."
                .into(),
        ),
    ];
    if !rows.is_empty() {
        out.push(Block::Table(
            [
                "test set",
                "views",
                "SART-TV",
                "SART-TV from the mean",
                "PCA-MAP",
                "FDK window",
            ]
            .map(String::from)
            .to_vec(),
            rows,
        ));
    }
    if !untuned.is_empty() {
        out.push(Block::Para(format!(
            "Scored with the baselines' defaults (evaluated before tuning existed, or not yet): \
             {}.",
            untuned.join(", ")
        )));
    }
    out
}

fn title(kind: Kind) -> &'static str {
    match kind {
        Kind::RealismGap => "Realism gap: TomoGRAF trained on ideal DRRs vs realistic projections",
        Kind::DomainShift => {
            "Domain shift: TomoGRAF trained on lidc phantoms, tested on shifted sets"
        }
    }
}

fn write_csv(dir: &Path, stats: &[Stat]) -> Result<()> {
    let mut csv = String::from(
        "train_set,test_set,views,method,items,psnr_db_mean,psnr_db_std,ssim_mean,ssim_std,rmse_hu_mean,rmse_hu_std\n",
    );
    for st in stats {
        let (p, ps) = st.mean_std(Metric::Psnr);
        let (q, qs) = st.mean_std(Metric::Ssim);
        let (r, rs) = st.mean_std(Metric::Rmse);
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{p:.4},{ps:.4},{q:.5},{qs:.5},{r:.2},{rs:.2}",
            st.train.as_deref().unwrap_or(""),
            st.test,
            st.views,
            st.method,
            st.scores.len()
        );
    }
    write_atomic(&dir.join("results.csv"), |w| {
        std::io::Write::write_all(w, csv.as_bytes())
    })?;
    Ok(())
}

fn intro(study: &Study) -> Vec<Block> {
    let s = &study.settings;
    let sc = &s.scale;
    let mut b = vec![Block::Para(format!(
        "Scale `{}` (CT {n}³, detector {n}², {} per set, {} \
         training and {} test views per rotation + AP + lateral, model configuration `{}`), \
         seed {}. Views as in \
         the paper: 1 = AP, 2 = AP + lateral, 5 = every 72°, 10 = every 36°. Metrics on the \
         [0, 1]-normalised CT (HU window −1024..2048): PSNR, 3D SSIM (7³ windows), RMSE in \
         HU; mean ± std over the test items. FDK and SART-TV use the same views and do \
         not depend on the training set. Regenerate with `tomograf study {} -o DIR --scale \
         {} --seed {}{}`.",
        sc.name,
        match (s.train_cts.len(), s.test_cts.len()) {
            (0, 0) => format!(
                "{} training and {} test phantoms",
                sc.train_phantoms, sc.test_phantoms
            ),
            (0, t) => format!(
                "{} training phantoms, {t} test CT(s) (phantom test sets: {})",
                sc.train_phantoms, sc.test_phantoms
            ),
            (r, 0) => format!("{r} training CT(s), {} test phantoms", sc.test_phantoms),
            (r, t) => format!(
                "{r} training CT(s), {t} test CT(s) (phantom test sets: {})",
                sc.test_phantoms
            ),
        },
        sc.views,
        sc.test_views,
        sc.config,
        s.seed,
        match s.kind {
            Kind::RealismGap => "realism-gap",
            Kind::DomainShift => "domain-shift",
        },
        sc.name,
        s.seed,
        [("--train-ct", &s.train_cts), ("--test-ct", &s.test_cts)]
            .iter()
            .filter(|(_, c)| !c.is_empty())
            .map(|(flag, c)| {
                let paths: Vec<String> = c.iter().map(|p| p.display().to_string()).collect();
                format!(" {flag} {}", paths.join(","))
            })
            .collect::<String>(),
        n = sc.size,
    ))];
    if !study.pool.is_empty() {
        let dirs: Vec<String> = study.pool.iter().map(|p| p.display().to_string()).collect();
        b.push(Block::Para(format!(
            "**Pooled over {} runs** of this study that differ only in the seed (their \
             training phantoms, noise, model training and test phantoms): {}. Every cell \
             pools their test items (named `s<seed>/<item>`), so the spreads and the paired \
             intervals below cover the training seeds as well as the test items. The example \
             slices are in each run's own report.",
            dirs.len(),
            dirs.join(", ")
        )));
    }
    if sc.name == "tiny" {
        b.push(Block::Para(
            "**Tiny scale**: a smoke test of the pipeline (16³ volumes, a model trained for \
             20 iterations); its numbers say nothing about the methods."
                .into(),
        ));
    }
    b.push(Block::Heading("Data sets".into()));
    let mut rows = Vec::new();
    for (role, specs) in [("train", &study.train), ("test", &study.test)] {
        for d in specs {
            rows.push(vec![
                role.to_string(),
                format!("`{}`", d.name),
                d.population(),
                if d.table { "yes" } else { "no" }.into(),
                if d.pacemaker { "yes" } else { "no" }.into(),
                d.about.to_string(),
            ]);
        }
    }
    b.push(Block::Table(
        [
            "role",
            "set",
            "population",
            "table",
            "pacemaker",
            "physics / content",
        ]
        .map(String::from)
        .to_vec(),
        rows,
    ));
    b
}

/// [`effects_table`] as markdown.
pub(super) fn effects_markdown(effects: &[Effect]) -> String {
    render(
        &effects_table(effects)[1..],
        "What each set does to the projections",
    )
    .0
}

/// The table of what each test set does to the projections ([`effects`]).
fn effects_table(effects: &[Effect]) -> Vec<Block> {
    let pair = |x: [f64; 2], digits: usize| format!("{:.digits$} / {:.digits$}", x[0], x[1]);
    let rows = effects
        .iter()
        .map(|e| {
            vec![
                format!("`{}`", e.set),
                e.reference
                    .as_ref()
                    .map_or("—".into(), |r| format!("`{r}`")),
                format!("{:.2}", e.vs_ideal_pct),
                e.vs_reference_pct.map_or("—".into(), |x| format!("{x:.2}")),
                pair(e.noise_pct, 3),
                e.spr.map_or("—".into(), |s| pair(s, 3)),
                e.quanta_p1_lateral
                    .map_or("—".into(), |q| format!("{q:.0}")),
                format!("{:.2}", e.starved_pct),
                e.mtf50_per_mm.map_or("—".into(), |m| {
                    format!("{m:.3} / {:.3}", e.nyquist_per_mm)
                }),
                if e.reference.is_none() {
                    "—".into()
                } else if e.negligible() {
                    format!("**< {NEGLIGIBLE_PCT} %: too small to show**")
                } else {
                    "changes the data".into()
                },
            ]
        })
        .collect();
    vec![
        Block::Heading("What each set does to the projections".into()),
        Block::Para(format!(
            "Before any network: the AP and lateral views of the first {} test item(s) of \
             each set at the study's detector size, against the ideal DRR of the same CT (line \
             integrals of μ at 60 keV). Changes and noise are RMS over the pixels, in % of the \
             ideal DRR's RMS line integral; noise from two noise realisations, (a − b)/√2 \
             (the scatter estimate's own Monte Carlo noise included); the scatter-to-primary \
             ratio is the panel's mean; quanta are the lateral view's noise-equivalent quanta \
             per pixel (1st percentile); starved pixels had their −log floored for lack of \
             signal; MTF50 is the light spread's and pixel aperture's, against the panel's \
             Nyquist frequency. A set that moves the line integrals by less than \
             {NEGLIGIBLE_PCT} % from its reference cannot show its effect at this scale.",
            effects.first().map_or(0, |e| e.items)
        )),
        Block::Table(
            [
                "set",
                "reference",
                "Δ vs ideal DRR (%)",
                "Δ vs reference (%)",
                "noise SD AP / lateral (%)",
                "scatter/primary AP / lateral",
                "quanta/pixel, lateral (p1)",
                "starved pixels (%)",
                "MTF50 / Nyquist (cycles/mm)",
                "verdict",
            ]
            .map(String::from)
            .to_vec(),
            rows,
        ),
    ]
}

/// Row labels of the metric tables: the models (and, with one training set, its mean
/// volume), then the classical baselines.
fn row_keys(study: &Study) -> Vec<(Option<String>, String, String)> {
    let s = &study.settings;
    let mut keys: Vec<(Option<String>, String, String)> = s
        .train_sets
        .iter()
        .flat_map(|t| {
            [
                (
                    Some(t.clone()),
                    "TomoGRAF".to_string(),
                    format!("TomoGRAF ← {t}"),
                ),
                (
                    Some(t.clone()),
                    NETWORK_ONLY.to_string(),
                    format!("{NETWORK_ONLY} ← {t}"),
                ),
            ]
        })
        .collect();
    if s.train_sets.len() == 1 {
        let t = &s.train_sets[0];
        for (method, label) in [
            ("mean training volume", "mean volume"),
            ("PCA-MAP prior", "PCA-MAP prior"),
            ("SART-TV from the mean", "SART-TV from the mean"),
        ] {
            keys.push((Some(t.clone()), method.into(), format!("{label} ← {t}")));
        }
    }
    keys.push((None, "FDK".into(), "FDK".into()));
    keys.push((None, "SART-TV".into(), "SART-TV".into()));
    keys
}

fn find<'a>(
    stats: &'a [Stat],
    train: Option<&str>,
    test: &str,
    views: usize,
    method: &str,
) -> Option<&'a Stat> {
    stats.iter().find(|s| {
        s.train.as_deref() == train && s.test == test && s.views == views && s.method == method
    })
}

fn tables(study: &Study, stats: &[Stat]) -> Vec<Block> {
    let s = &study.settings;
    let mut b = Vec::new();
    let what = match s.kind {
        Kind::RealismGap => {
            "rows: method (← the level its model was trained on); columns: the level tested on"
        }
        Kind::DomainShift => "rows: method; columns: test set",
    };
    for m in Metric::ALL {
        b.push(Block::Heading(format!("{} ({what})", m.name())));
        let mut header = vec!["views".to_string(), "method".to_string()];
        header.extend(s.test_sets.iter().map(|t| format!("`{t}`")));
        let mut rows = Vec::new();
        for v in VIEWS {
            for (train, method, label) in row_keys(study) {
                let cells: Vec<Option<String>> = s
                    .test_sets
                    .iter()
                    .map(|t| {
                        find(stats, train.as_deref(), t, v, &method)
                            .map(|st| m.format(st.mean_std(m)))
                    })
                    .collect();
                // A method no cell has (the network-only row of a model that runs no
                // data-consistency sweeps) gets no row.
                if cells.iter().all(Option::is_none) {
                    continue;
                }
                let mut row = vec![v.to_string(), label];
                row.extend(cells.into_iter().map(|c| c.unwrap_or_else(|| "—".into())));
                rows.push(row);
            }
        }
        b.push(Block::Table(header, rows));
    }
    b
}
