//! The study report: `results.csv` (mean ± std per train set × test set × views × method),
//! `report.md` and `report.html` (the same content) with metric tables, plots (metric vs
//! views, metric vs realism level or shift, SSIM histograms as the paper's Fig. 4) and the
//! evaluations' example slices, residual maps and line profiles.

use super::coverage::Coverage;
use super::effects::{self, Effect, NEGLIGIBLE_PCT};
use super::render::{Block, render};
use super::{Kind, Study, VIEWS, eval_dir_in, relative};
use crate::evaluation::{NETWORK_ONLY, Row, Scores, merge};
use crate::figures::{
    Axes, BarSeries, COLOUR_NAMES, plot_categories, plot_histograms, plot_with_bars,
};
use crate::paired::Paired;
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::Path;
use std::path::PathBuf;
use tomograf_datasets::atomic::write_atomic;
use tomograf_model::metrics::mean_std;

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
    blocks.extend(paired_tables(study, &stats));
    blocks.extend(baselines_table(study));
    blocks.extend(plots(study, &stats)?);
    if let Some(id) = first_item.filter(|_| pooled.is_empty()) {
        blocks.extend(examples(study, &id));
    }
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

/// The baselines TomoGRAF is compared with: those of its model's cell (made from its
/// training set), then the classical ones.
/// The baseline that starts from the model's mean training volume.
const MEAN_SART: &str = "SART-TV from the mean";

const BASELINES: [(&str, bool); 5] = [
    ("mean training volume", true),
    ("PCA-MAP prior", true),
    ("SART-TV from the mean", true),
    ("FDK", false),
    ("SART-TV", false),
];

/// `a` − `b` in PSNR and SSIM, paired over their common items.
fn paired_psnr_ssim(a: &Stat, b: &Stat) -> (Option<Paired>, Option<Paired>) {
    let d = |m| Paired::of(&a.per_item(m), &b.per_item(m));
    (d(Metric::Psnr), d(Metric::Ssim))
}

/// Paired differences over the test items, with 95 % t-intervals: TomoGRAF against the best
/// baseline of each cell and, in the realism gap, each model against the first.
fn paired_tables(study: &Study, stats: &[Stat]) -> Vec<Block> {
    let s = &study.settings;
    let cell = |p: Option<Paired>, digits: usize| p.map_or("—".into(), |p| p.format(digits));
    let (mut shown, mut resolved) = (0, 0);
    let mut count = |p: &Option<Paired>| {
        if let Some(p) = p {
            shown += 1;
            resolved += usize::from(p.resolved());
        }
    };
    let mut best_rows = Vec::new();
    for test in &s.test_sets {
        for v in VIEWS {
            for t in &s.train_sets {
                let Some(ours) = find(stats, Some(t), test, v, "TomoGRAF") else {
                    continue;
                };
                let best = BASELINES
                    .iter()
                    .filter_map(|(b, own)| find(stats, own.then_some(t.as_str()), test, v, b))
                    .max_by(|a, b| {
                        a.mean_std(Metric::Psnr)
                            .0
                            .total_cmp(&b.mean_std(Metric::Psnr).0)
                    });
                let Some(best) = best else { continue };
                let (psnr, ssim) = paired_psnr_ssim(ours, best);
                count(&psnr);
                count(&ssim);
                best_rows.push(vec![
                    format!("`{test}`"),
                    v.to_string(),
                    format!("`{t}`"),
                    best.method.clone(),
                    cell(psnr, 2),
                    cell(ssim, 3),
                    psnr.map_or(0, |p| p.n).to_string(),
                ]);
            }
        }
    }
    let mut b = vec![Block::Heading("Paired differences".into())];
    let mut level_rows = Vec::new();
    if s.kind == Kind::RealismGap && s.train_sets.len() > 1 {
        let first = &s.train_sets[0];
        for test in &s.test_sets {
            for v in VIEWS {
                let Some(base) = find(stats, Some(first), test, v, "TomoGRAF") else {
                    continue;
                };
                for t in &s.train_sets[1..] {
                    let Some(other) = find(stats, Some(t), test, v, "TomoGRAF") else {
                        continue;
                    };
                    let (psnr, ssim) = paired_psnr_ssim(other, base);
                    count(&psnr);
                    count(&ssim);
                    level_rows.push(vec![
                        format!("`{test}`"),
                        v.to_string(),
                        format!("`{t}` − `{first}`"),
                        cell(psnr, 2),
                        cell(ssim, 3),
                    ]);
                }
            }
        }
    }
    b.push(Block::Para(format!(
        "Differences paired over the test items (the same items in both), mean ± the \
         half-width of its 95 % t-interval; **bold**: the interval excludes zero (resolved). \
         {resolved} of the {shown} differences below are resolved; the others cannot be told \
         from the spread between items. {}",
        if study.pool.is_empty() {
            "One training run per model: the intervals cover the test items, not the training \
             seed (pool runs with other seeds with `--stage report --pool`)."
        } else {
            "Pooled over training seeds: the pairs of every seed are taken as one sample, so \
             the seeds' variation enters the spread (an effect shared by all items of one seed \
             would make the interval somewhat too narrow)."
        }
    )));
    b.push(Block::Table(
        [
            "test set",
            "views",
            "model",
            "best baseline (by mean PSNR)",
            "Δ PSNR (dB), TomoGRAF − baseline",
            "Δ SSIM",
            "items",
        ]
        .map(String::from)
        .to_vec(),
        best_rows,
    ));
    if !level_rows.is_empty() {
        b.push(Block::Para(
            "What training on a realism level buys: TomoGRAF trained on each level against \
             TomoGRAF trained on the first, on the same test items."
                .into(),
        ));
        b.push(Block::Table(
            ["test set", "views", "models", "Δ PSNR (dB)", "Δ SSIM"]
                .map(String::from)
                .to_vec(),
            level_rows,
        ));
    }
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

/// Named series of (x, mean, SD over the test items).
type Series = Vec<(String, Vec<(f64, f64, f64)>)>;

fn colours(series: &Series) -> String {
    series
        .iter()
        .enumerate()
        .map(|(i, (n, _))| format!("{} = {n}", COLOUR_NAMES[i % COLOUR_NAMES.len()]))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A plot of `series` over the view counts (`categories` `None`) or over the named test
/// sets, with ± 1 SD bars.
fn draw(
    study: &Study,
    file: &str,
    axes: &Axes,
    caption: String,
    series: Series,
    categories: Option<&[String]>,
) -> Result<Block> {
    let path = study.dir.join("figures").join(file);
    let named: Vec<BarSeries> = series
        .iter()
        .map(|(n, p)| (n.as_str(), p.clone()))
        .collect();
    match categories {
        Some(c) => plot_categories(&path, axes, c, &named)?,
        None => plot_with_bars(&path, axes, &named)?,
    }
    let (lo, hi) = series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.1))
        .filter(|y| y.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
    Ok(Block::Image(
        relative(&study.dir, &path),
        format!(
            "{caption} Bars: ± 1 SD over the test items. Colours: {}. The means span {lo:.3} \
             to {hi:.3}.",
            colours(&series)
        ),
    ))
}

fn plots(study: &Study, stats: &[Stat]) -> Result<Vec<Block>> {
    let s = &study.settings;
    let mut b = vec![Block::Heading("Plots".into())];
    let point = |train: Option<&str>, test: &str, v: usize, method: &str, m: Metric| {
        find(stats, train, test, v, method).map(|st| st.mean_std(m))
    };
    let vs_views = |train: Option<&str>, test: &str, method: &str, m: Metric| {
        VIEWS
            .iter()
            .filter_map(|&v| point(train, test, v, method, m).map(|(y, e)| (v as f64, y, e)))
            .collect::<Vec<_>>()
    };
    let across = |f: &dyn Fn(&str) -> Option<(f64, f64)>| {
        s.test_sets
            .iter()
            .enumerate()
            .filter_map(|(i, t)| f(t).map(|(y, e)| (i as f64, y, e)))
            .collect::<Vec<_>>()
    };
    // The plots over the view counts show the last test set with scores (a partial report
    // may have none yet for the last sets).
    let last = s
        .test_sets
        .iter()
        .rev()
        .find(|t| {
            stats
                .iter()
                .any(|st| st.test == **t && !st.scores.is_empty())
        })
        .or(s.test_sets.last())
        .context("no test sets")?;
    for m in Metric::ALL {
        let mut series: Series = Vec::new();
        let caption = match s.kind {
            Kind::RealismGap => {
                for t in &s.train_sets {
                    series.push((
                        format!("TomoGRAF ← {t}"),
                        vs_views(Some(t), last, "TomoGRAF", m),
                    ));
                }
                // The strongest baseline, from the first model's mean volume.
                let first = &s.train_sets[0];
                series.push((
                    format!("{MEAN_SART} ← {first}"),
                    vs_views(Some(first), last, MEAN_SART, m),
                ));
                for c in ["FDK", "SART-TV"] {
                    series.push((c.into(), vs_views(None, last, c, m)));
                }
                format!(
                    "{} vs views (x axis: 1 to 10 views), tested on `{last}`.",
                    m.name()
                )
            }
            Kind::DomainShift => {
                let t = &s.train_sets[0];
                for test in &s.test_sets {
                    series.push((
                        format!("TomoGRAF on {test}"),
                        vs_views(Some(t), test, "TomoGRAF", m),
                    ));
                }
                format!(
                    "{} of TomoGRAF vs views (x axis: 1 to 10 views), per test set.",
                    m.name()
                )
            }
        };
        let title = format!("{} vs views", m.name());
        let axes = Axes {
            title: &title,
            x: "views",
            y: m.name(),
        };
        b.push(draw(
            study,
            &format!("{}_vs_views.png", m.file()),
            &axes,
            caption,
            series,
            None,
        )?);

        // The metric across the test sets.
        let mut series: Series = Vec::new();
        let (file, caption) = match s.kind {
            Kind::RealismGap => {
                let first = &s.train_sets[0];
                series.push((
                    format!("TomoGRAF ← {first}"),
                    across(&|t| point(Some(first), t, 1, "TomoGRAF", m)),
                ));
                series.push((
                    "TomoGRAF ← the level tested".into(),
                    across(&|t| {
                        s.train_sets
                            .iter()
                            .any(|x| x == t)
                            .then(|| point(Some(t), t, 1, "TomoGRAF", m))
                            .flatten()
                    }),
                ));
                series.push((
                    format!("{MEAN_SART} ← {first}"),
                    across(&|t| point(Some(first), t, 1, MEAN_SART, m)),
                ));
                for c in ["FDK", "SART-TV"] {
                    series.push((c.into(), across(&|t| point(None, t, 1, c, m))));
                }
                (
                    format!("{}_vs_level.png", m.file()),
                    format!("{} from 1 view vs the realism level tested on.", m.name()),
                )
            }
            Kind::DomainShift => {
                let t = s.train_sets[0].as_str();
                for v in VIEWS {
                    series.push((
                        format!("TomoGRAF, {v} view(s)"),
                        across(&|x| point(Some(t), x, v, "TomoGRAF", m)),
                    ));
                }
                for c in ["FDK", "SART-TV"] {
                    series.push((
                        format!("{c}, 10 views"),
                        across(&|x| point(None, x, 10, c, m)),
                    ));
                }
                (
                    format!("{}_vs_shift.png", m.file()),
                    format!("{} vs test set.", m.name()),
                )
            }
        };
        let (title, x) = match s.kind {
            Kind::RealismGap => (
                format!("{}, 1 view, vs realism level", m.name()),
                "level tested on",
            ),
            Kind::DomainShift => (format!("{} vs test set", m.name()), "test set"),
        };
        let axes = Axes {
            title: &title,
            x,
            y: m.name(),
        };
        b.push(draw(
            study,
            &file,
            &axes,
            caption,
            series,
            Some(&s.test_sets),
        )?);
    }

    // SSIM histograms over the test items, 1 view (the paper's Fig. 4).
    let values = |train: Option<&str>, test: &str, method: &str| {
        find(stats, train, test, 1, method)
            .map(|st| st.scores.iter().map(|x| x.ssim).collect::<Vec<_>>())
            .unwrap_or_default()
    };
    let mut series: Vec<(String, Vec<f64>)> = Vec::new();
    let caption = match s.kind {
        Kind::RealismGap => {
            for t in &s.train_sets {
                series.push((format!("TomoGRAF ← {t}"), values(Some(t), last, "TomoGRAF")));
            }
            for c in ["FDK", "SART-TV"] {
                series.push((c.into(), values(None, last, c)));
            }
            format!(
                "Histogram of the per-phantom SSIM from 1 view, tested on `{last}` (20 bins on [0, 1]; fraction of phantoms)."
            )
        }
        Kind::DomainShift => {
            for test in &s.test_sets {
                series.push((
                    format!("TomoGRAF on {test}"),
                    values(Some(&s.train_sets[0]), test, "TomoGRAF"),
                ));
            }
            "Histogram of TomoGRAF's per-phantom SSIM from 1 view per test set (20 bins on [0, 1]; fraction of phantoms).".into()
        }
    };
    let path = study.dir.join("figures").join("ssim_histogram.png");
    let named: Vec<(&str, Vec<f64>)> = series
        .iter()
        .map(|(n, v)| (n.as_str(), v.clone()))
        .collect();
    let axes = Axes {
        title: "SSIM of TomoGRAF from 1 view",
        x: "SSIM",
        y: "fraction of phantoms",
    };
    plot_histograms(&path, &axes, &named, 0.0, 1.0, 20)?;
    let names: Series = series
        .iter()
        .map(|(n, _)| (n.clone(), Vec::new()))
        .collect();
    b.push(Block::Image(
        relative(&study.dir, &path),
        format!("{caption} Colours: {}.", colours(&names)),
    ));
    Ok(b)
}

/// The evaluations' example figures of the first test item.
fn examples(study: &Study, id: &str) -> Vec<Block> {
    let s = &study.settings;
    let mut b = vec![Block::Heading(format!("Example: test item {id}"))];
    let last = s.test_sets.last().map(String::as_str).unwrap_or_default();
    let mut cells: Vec<(String, Option<&str>, usize)> = Vec::new();
    match s.kind {
        Kind::RealismGap => {
            for t in s
                .train_sets
                .iter()
                .filter(|t| *t == &s.train_sets[0] || *t == last)
            {
                cells.push((last.into(), Some(t), 1));
            }
            cells.push((last.into(), None, 1));
            cells.push((last.into(), None, 10));
        }
        Kind::DomainShift => {
            for t in &s.test_sets {
                cells.push((t.clone(), Some(s.train_sets[0].as_str()), 1));
            }
        }
    }
    for (test, train, v) in cells {
        let dir = study.eval_dir(&test, train);
        let slices = dir.join(format!("{id}_{v}view_slices.png"));
        if !slices.exists() {
            continue;
        }
        let (what, cols, lines) = match train {
            Some(t) => (
                format!("TomoGRAF trained on `{t}`"),
                "truth, TomoGRAF, mean training volume, |TomoGRAF − truth| × 4",
                "blue = truth, red = TomoGRAF, green = mean volume",
            ),
            None => (
                "FDK and SART-TV".to_string(),
                "truth, FDK, SART-TV, |FDK − truth| × 4",
                "blue = truth, red = FDK, green = SART-TV",
            ),
        };
        b.push(Block::Image(
            relative(&study.dir, &slices),
            format!(
                "{what}, tested on `{test}`, {v} view(s). Rows: axial, coronal, sagittal \
                 mid-slices; columns: {cols}; window [0, 1] of the normalised CT."
            ),
        ));
        b.push(Block::Image(
            relative(&study.dir, &dir.join(format!("{id}_{v}view_profile.png"))),
            format!("Line profile through the centre of the axial slice: {lines}."),
        ));
    }
    b
}
