//! The baselines' settings, chosen on a validation set (`tomograf tune-baselines`): every
//! setting a user of SART-TV (from zero and from the mean training volume), PCA-MAP and FDK
//! would tune is searched on a grid ([`grid`]), each candidate is scored on every
//! validation item from each view count, and the one with the highest mean PSNR per method
//! and view count goes into `baselines.toml` ([`BaselineSettings`]), which `tomograf
//! evaluate --baselines` and `tomograf demo` read. The whole search is kept
//! (`search.csv`, `search.md`) so a reader can see how flat the optimum is.
//!
//! The search never touches a test set: it reads the data set it is given, which should be
//! a validation split (disjoint seeds from training and test).

use crate::evaluation::{Scores, score};
use crate::protocol::{correct_scatter, paper_poses, references};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use tomograf_datasets::atomic::write_atomic;
use tomograf_model::baseline::{Baseline, Fdk, SartTv, SartTvSettings};
use tomograf_model::data;
use tomograf_model::pca::{PcaMap, PcaSettings};
use tomograf_model::scatter_correction::ScatterCorrection;
use tomograf_scene::{Progress, Silent};
use tomograf_sim::Volume;
use tomograf_sim::recon::Window;

/// File name of the chosen settings in a tuning's output folder.
pub const FILE: &str = "baselines.toml";

/// The method names, as the evaluation tables print them.
pub const SART_TV: &str = "SART-TV";
pub const SART_TV_FROM_MEAN: &str = "SART-TV from the mean";
pub const PCA_MAP: &str = "PCA-MAP prior";
pub const FDK: &str = "FDK";

/// Every baseline's settings for one view count.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewSettings {
    pub sart_tv: SartTvSettings,
    pub sart_tv_from_mean: SartTvSettings,
    pub pca_map: PcaSettings,
    /// FDK's ramp-filter window.
    pub fdk_window: Window,
}

impl ViewSettings {
    fn validate(&self) -> Result<()> {
        self.sart_tv.options(1)?;
        self.sart_tv_from_mean.options(1)?;
        self.pca_map.validate()?;
        Ok(())
    }
}

/// `baselines.toml`: the settings per view count and what chose them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaselineSettings {
    /// The validation data (and training data) the search ran on.
    pub tuned_on: String,
    /// How the winner was chosen.
    pub rule: String,
    /// Settings per view count (keys "1", "2", …).
    pub views: BTreeMap<String, ViewSettings>,
}

impl BaselineSettings {
    /// Reads and checks a `baselines.toml`; errors name the file and the bad entry.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read the baselines' settings {}", path.display()))?;
        let s: Self = toml::from_str(&text).with_context(|| {
            format!(
                "{} is not a baselines.toml (written by `tomograf tune-baselines`)",
                path.display()
            )
        })?;
        if s.views.is_empty() {
            bail!("{}: no view counts tuned", path.display());
        }
        for (k, v) in &s.views {
            if !k.parse::<usize>().is_ok_and(|n| n >= 1) {
                bail!("{}: view count '{k}' is not a number ≥ 1", path.display());
            }
            v.validate()
                .with_context(|| format!("{}, views {k}", path.display()))?;
        }
        Ok(s)
    }

    /// The settings for `count` views; an error naming the counts tuned.
    pub fn for_views(&self, count: usize) -> Result<ViewSettings> {
        self.views
            .get(&count.to_string())
            .copied()
            .with_context(|| {
                format!(
                    "the baselines were tuned for {} view(s), not {count}: tune them for it \
                 (`tomograf tune-baselines --views …`) or leave out --baselines",
                    self.views.keys().cloned().collect::<Vec<_>>().join(", ")
                )
            })
    }
}

/// One setting of one method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Candidate {
    SartTv(SartTvSettings),
    SartTvFromMean(SartTvSettings),
    PcaMap(PcaSettings),
    Fdk(Window),
}

impl Candidate {
    /// The method's name in the evaluation tables.
    pub fn method(&self) -> &'static str {
        match self {
            Self::SartTv(_) => SART_TV,
            Self::SartTvFromMean(_) => SART_TV_FROM_MEAN,
            Self::PcaMap(_) => PCA_MAP,
            Self::Fdk(_) => FDK,
        }
    }

    /// The setting, in words (no commas: it is a CSV field).
    pub fn setting(&self) -> String {
        match self {
            Self::SartTv(s) | Self::SartTvFromMean(s) => {
                format!("{} sweeps; TV step {}", s.sweeps, s.tv_step)
            }
            Self::PcaMap(p) => format!(
                "noise {}; {} components",
                p.noise,
                p.components.map_or("all".to_string(), |c| c.to_string())
            ),
            Self::Fdk(w) => format!("{w:?} window"),
        }
    }
}

/// SART-TV's sweeps on the grid.
const SWEEPS: [usize; 5] = [5, 10, 20, 40, 80];
/// SART-TV's TV steps on the grid (0: plain SART).
const TV_STEPS: [f64; 5] = [0.0, 0.1, 0.2, 0.4, 0.8];
/// PCA-MAP's noise levels on the grid (fractions of the largest line integral).
const NOISES: [f64; 7] = [0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0];
/// PCA-MAP's component counts on the grid (`None`: all).
const COMPONENTS: [Option<usize>; 4] = [Some(4), Some(8), Some(16), None];

/// The search: SART-TV (both starts) over sweeps {5, 10, 20, 40, 80} × TV step {0, 0.1,
/// 0.2, 0.4, 0.8}; PCA-MAP over noise {0.1, 0.3, 1, 3, 10, 30, 100} % × the first {4, 8,
/// 16, all} components; FDK over the four ramp windows. The defaults (20 sweeps, TV step
/// 0.2; noise 1 %, all components; Ram-Lak) are on the grid.
pub fn grid() -> Vec<Candidate> {
    let mut out = Vec::new();
    for sweeps in SWEEPS {
        for tv_step in TV_STEPS {
            let s = SartTvSettings { sweeps, tv_step };
            out.push(Candidate::SartTv(s));
            out.push(Candidate::SartTvFromMean(s));
        }
    }
    for noise in NOISES {
        for components in COMPONENTS {
            out.push(Candidate::PcaMap(PcaSettings { noise, components }));
        }
    }
    for w in [
        Window::RamLak,
        Window::SheppLogan,
        Window::Cosine,
        Window::Hann,
    ] {
        out.push(Candidate::Fdk(w));
    }
    out
}

/// Whether `c` lies on an open edge of the grid (the most sweeps, the largest TV step, the
/// smallest or largest noise): a winner there may have a better setting beyond it.
pub fn on_edge(c: &Candidate) -> bool {
    let last = |a: &[f64], x: f64| a.last() == Some(&x);
    match c {
        Candidate::SartTv(s) | Candidate::SartTvFromMean(s) => {
            SWEEPS.last() == Some(&s.sweeps) || last(&TV_STEPS, s.tv_step)
        }
        Candidate::PcaMap(p) => NOISES.first() == Some(&p.noise) || last(&NOISES, p.noise),
        Candidate::Fdk(_) => false,
    }
}

/// What to tune on.
pub struct Tuning<'a> {
    /// Validation data set (items with CTs and the paper's views).
    pub data: &'a Path,
    /// Only its items of this split.
    pub split: Option<&'a str>,
    /// At most this many items.
    pub items: Option<usize>,
    /// The training set: its CTs give the mean volume and the PCA-MAP prior, its largest
    /// line integral PCA-MAP's noise scale (as `tomograf evaluate --train-data` does).
    pub train_data: &'a Path,
    pub views: &'a [usize],
    /// Correct the views for scatter first, as the evaluation the settings are for will
    /// (`prior`: from the training set's mean volume).
    pub scatter_correction: ScatterCorrection,
    /// Output folder: search.csv, search.md, baselines.toml, items/.
    pub output: &'a Path,
    pub progress: &'a dyn Progress,
}

/// One score of the search.
#[derive(Debug, Clone)]
struct Row {
    item: String,
    views: usize,
    method: &'static str,
    setting: String,
    scores: Scores,
}

const HEADER: &str = "item,views,method,setting,psnr_db,ssim,body_psnr_db,body_ssim";

/// The `job.json` of a search folder: a re-run with other inputs is refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Job {
    data: PathBuf,
    train_data: PathBuf,
    items: Vec<String>,
    views: Vec<usize>,
    candidates: Vec<String>,
    #[serde(default, skip_serializing_if = "is_none")]
    scatter_correction: ScatterCorrection,
}

fn is_none(c: &ScatterCorrection) -> bool {
    *c == ScatterCorrection::None
}

/// Runs the search (resuming: items already under `output/items/` are not re-scored),
/// writes `search.csv`, `search.md` and `baselines.toml`; returns the settings and the
/// search's markdown.
pub fn tune(t: &Tuning) -> Result<(BaselineSettings, String)> {
    if t.views.is_empty() || t.views.contains(&0) {
        bail!("view counts must be ≥ 1");
    }
    let mut items = data::load_dataset(t.data, t.split)?;
    if let Some(n) = t.items {
        if n == 0 {
            bail!("--items 0 tunes on nothing: give at least 1");
        }
        items.truncate(n);
    }
    let train = data::load_dataset(t.train_data, None)
        .with_context(|| format!("the training set {}", t.train_data.display()))?;
    let cts: Vec<&Volume> = train.iter().filter_map(|i| i.ct.as_ref()).collect();
    let pca = PcaMap::from_volumes(
        &cts,
        PcaSettings::default().noise,
        tomograf_model::train::projection_scale(&train)?,
    )?;
    let mean = &pca.mean;
    let candidates = grid();
    let job = Job {
        data: t.data.to_path_buf(),
        train_data: t.train_data.to_path_buf(),
        items: items.iter().map(|i| i.id.clone()).collect(),
        views: t.views.to_vec(),
        candidates: candidates
            .iter()
            .map(|c| format!("{}: {}", c.method(), c.setting()))
            .collect(),
        scatter_correction: t.scatter_correction,
    };
    std::fs::create_dir_all(t.output.join("items"))
        .with_context(|| format!("cannot create {}", t.output.display()))?;
    tomograf_datasets::atomic::remove_stale_temporaries(t.output)?;
    check_job(t.output, &job)?;
    let mut rows = Vec::new();
    for (n, item) in items.iter().enumerate() {
        let path = t.output.join("items").join(format!("{}.csv", item.id));
        if let Ok(text) = std::fs::read_to_string(&path) {
            rows.extend(
                parse_rows(&text, &candidates).with_context(|| path.display().to_string())?,
            );
            continue;
        }
        let mut poses = Vec::new();
        for &count in t.views {
            poses.extend(paper_poses(count)?);
        }
        let corrected =
            correct_scatter(item, t.scatter_correction, Some(mean), &poses, 0, &Silent)?;
        let item = corrected.as_ref().unwrap_or(item);
        let grid = item.ct.as_ref().context("item has no ground-truth CT")?;
        let mut mine = Vec::new();
        for &count in t.views {
            t.progress.note(&format!(
                "item {} ({}/{}), {count} view(s): {} settings",
                item.id,
                n + 1,
                items.len(),
                candidates.len()
            ));
            let refs = references(item, &paper_poses(count)?)?;
            let system = pca.system(&refs, grid, &item.scale)?;
            for c in &candidates {
                let volume = match *c {
                    Candidate::SartTv(s) => {
                        SartTv::from_zero()
                            .with(s)
                            .reconstruct(&refs, grid, &item.scale)?
                    }
                    Candidate::SartTvFromMean(s) => SartTv::from_mean(mean.clone())
                        .with(s)
                        .reconstruct(&refs, grid, &item.scale)?,
                    Candidate::PcaMap(p) => pca.volume_on(&pca.solve(&system, &p)?, grid)?,
                    Candidate::Fdk(window) => {
                        Fdk { window }.reconstruct(&refs, grid, &item.scale)?
                    }
                };
                mine.push(Row {
                    item: item.id.clone(),
                    views: count,
                    method: c.method(),
                    setting: c.setting(),
                    scores: score(item, &volume)?,
                });
            }
        }
        let text = csv(&mine);
        write_atomic(&path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
        // The choice is made from the scores as written, so a resumed search makes it alike.
        rows.extend(parse_rows(&text, &candidates)?);
    }
    write_atomic(&t.output.join("search.csv"), |w| {
        std::io::Write::write_all(w, csv(&rows).as_bytes())
    })?;
    let (settings, md) = choose(t, &candidates, &rows, items.len())?;
    write_atomic(&t.output.join("search.md"), |w| {
        std::io::Write::write_all(w, md.as_bytes())
    })?;
    let text = format!(
        "# Written by `tomograf tune-baselines`; see search.md beside it for the whole search.\n{}",
        toml::to_string(&settings)?
    );
    write_atomic(&t.output.join(FILE), |w| {
        std::io::Write::write_all(w, text.as_bytes())
    })?;
    Ok((settings, md))
}

/// The winner per method and view count (highest mean PSNR; the first on the grid on a
/// tie), and the search as markdown tables.
fn choose(
    t: &Tuning,
    candidates: &[Candidate],
    rows: &[Row],
    items: usize,
) -> Result<(BaselineSettings, String)> {
    let mut md = format!(
        "# Baselines tuned on {} ({items} item(s)), training set {}\n\nMean over the \
         validation items; the chosen setting (highest mean PSNR) in bold, the default marked \
         \"(default)\".\n",
        t.data.display(),
        t.train_data.display()
    );
    let mut views = BTreeMap::new();
    let mut edges = Vec::new();
    // (method, views, default's PSNR, chosen setting, its PSNR) for the summary.
    let mut summary: Vec<(&str, usize, f64, String, f64)> = Vec::new();
    let defaults = ViewSettings::default();
    for &count in t.views {
        let mut chosen = defaults;
        for method in [SART_TV, SART_TV_FROM_MEAN, PCA_MAP, FDK] {
            let _ = write!(
                md,
                "\n## {method}, {count} view(s)\n\n| setting | PSNR (dB) | SSIM | body PSNR \
                 (dB) | body SSIM |\n|---|---:|---:|---:|---:|\n"
            );
            let mut table = Vec::new();
            for c in candidates.iter().filter(|c| c.method() == method) {
                let s: Vec<&Scores> = rows
                    .iter()
                    .filter(|r| r.views == count && r.method == method && r.setting == c.setting())
                    .map(|r| &r.scores)
                    .collect();
                if s.len() != items {
                    bail!(
                        "{method} ({}), {count} view(s): {} of {items} item(s) scored",
                        c.setting(),
                        s.len()
                    );
                }
                let m = |f: fn(&Scores) -> f64| s.iter().map(|x| f(x)).sum::<f64>() / items as f64;
                table.push((
                    *c,
                    [
                        m(|x| x.psnr),
                        m(|x| x.ssim),
                        m(|x| x.body_psnr),
                        m(|x| x.body_ssim),
                    ],
                ));
            }
            let best = table
                .iter()
                .enumerate()
                .fold(0, |b, (i, r)| if r.1[0] > table[b].1[0] { i } else { b });
            let is_default = |c: &Candidate| match *c {
                Candidate::SartTv(s) | Candidate::SartTvFromMean(s) => {
                    s == SartTvSettings::default()
                }
                Candidate::PcaMap(p) => p == PcaSettings::default(),
                Candidate::Fdk(w) => w == Window::default(),
            };
            if let Some((_, d)) = table.iter().find(|(c, _)| is_default(c)) {
                summary.push((
                    method,
                    count,
                    d[0],
                    table[best].0.setting(),
                    table[best].1[0],
                ));
            }
            for (i, (c, v)) in table.iter().enumerate() {
                let is_default = is_default(c);
                let name = format!(
                    "{}{}",
                    c.setting(),
                    if is_default { " (default)" } else { "" }
                );
                let cell = match (i == best, on_edge(c)) {
                    (true, true) => {
                        edges.push(format!("{method}, {count} view(s)"));
                        format!("**{name}** (on the grid's edge)")
                    }
                    (true, false) => format!("**{name}**"),
                    _ => name,
                };
                let _ = writeln!(
                    md,
                    "| {cell} | {:.2} | {:.3} | {:.2} | {:.3} |",
                    v[0], v[1], v[2], v[3]
                );
            }
            match table[best].0 {
                Candidate::SartTv(s) => chosen.sart_tv = s,
                Candidate::SartTvFromMean(s) => chosen.sart_tv_from_mean = s,
                Candidate::PcaMap(p) => chosen.pca_map = p,
                Candidate::Fdk(w) => chosen.fdk_window = w,
            }
        }
        views.insert(count.to_string(), chosen);
    }
    let mut head = String::from(
        "\n## Summary\n\n| method | views | default: PSNR (dB) | chosen | PSNR (dB) | gain (dB) \
         |\n|---|---:|---:|---|---:|---:|\n",
    );
    for (method, count, d, chosen, p) in &summary {
        let _ = writeln!(
            head,
            "| {method} | {count} | {d:.2} | {chosen} | {p:.2} | {:+.2} |",
            p - d
        );
    }
    let at = md.find("\n## ").unwrap_or(md.len());
    md.insert_str(at, &head);
    if !edges.is_empty() {
        let _ = write!(
            md,
            "\nChosen on the grid's edge (a better setting may lie beyond it): {}.\n",
            edges.join("; ")
        );
        t.progress.note(&format!(
            "note: chosen on the grid's edge: {}",
            edges.join("; ")
        ));
    }
    Ok((
        BaselineSettings {
            tuned_on: format!(
                "{} ({items} validation item(s)); training set {}",
                t.data.display(),
                t.train_data.display()
            ),
            rule: "highest mean PSNR over the validation items, per method and view count".into(),
            views,
        },
        md,
    ))
}

fn csv(rows: &[Row]) -> String {
    let mut text = format!("{HEADER}\n");
    for r in rows {
        let _ = writeln!(
            text,
            "{},{},{},{},{:.6},{:.6},{:.6},{:.6}",
            r.item,
            r.views,
            r.method,
            r.setting,
            r.scores.psnr,
            r.scores.ssim,
            r.scores.body_psnr,
            r.scores.body_ssim
        );
    }
    text
}

/// An item's rows as [`csv`] wrote them (methods must be the grid's).
fn parse_rows(text: &str, candidates: &[Candidate]) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let bad = || anyhow::anyhow!("line {}: not a search row", n + 1);
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 8 {
            return Err(bad());
        }
        let method = candidates
            .iter()
            .map(Candidate::method)
            .find(|m| *m == f[2])
            .ok_or_else(bad)?;
        let num = |i: usize| f[i].parse::<f64>().map_err(|_| bad());
        rows.push(Row {
            item: f[0].into(),
            views: f[1].parse().map_err(|_| bad())?,
            method,
            setting: f[3].into(),
            scores: Scores {
                psnr: num(4)?,
                ssim: num(5)?,
                rmse_hu: f64::NAN,
                body_psnr: num(6)?,
                body_ssim: num(7)?,
                body_rmse_hu: f64::NAN,
            },
        });
    }
    Ok(rows)
}

fn check_job(output: &Path, job: &Job) -> Result<()> {
    let path = output.join("job.json");
    if let Ok(bytes) = std::fs::read(&path) {
        let old: Job = serde_json::from_slice(&bytes)
            .with_context(|| format!("{} is not a tuning's job.json", path.display()))?;
        if old != *job {
            bail!(
                "{} holds another search (other data, items, views or grid); choose another \
                 --output or remove it",
                output.display()
            );
        }
        return Ok(());
    }
    Ok(tomograf_datasets::atomic::write_json(
        &path,
        &serde_json::to_value(job)?,
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_on_the_grid_and_settings_round_trip() {
        let g = grid();
        let d = ViewSettings::default();
        assert!(g.contains(&Candidate::SartTv(d.sart_tv)));
        assert!(g.contains(&Candidate::SartTvFromMean(d.sart_tv_from_mean)));
        assert!(g.contains(&Candidate::PcaMap(d.pca_map)));
        assert!(g.contains(&Candidate::Fdk(d.fdk_window)));
        let labels: std::collections::BTreeSet<String> = g
            .iter()
            .map(|c| format!("{}{}", c.method(), c.setting()))
            .collect();
        assert_eq!(labels.len(), g.len(), "every candidate has its own label");
        assert!(g.iter().all(|c| !c.setting().contains(',')));
        assert!(
            !g.iter()
                .any(|c| on_edge(c) && *c == Candidate::SartTv(d.sart_tv))
        );
        let sart = |sweeps, tv_step| Candidate::SartTv(SartTvSettings { sweeps, tv_step });
        assert!(on_edge(&sart(80, 0.1)) && on_edge(&sart(10, 0.8)));
        assert!(!on_edge(&sart(40, 0.0)) && !on_edge(&sart(5, 0.4)));
        let pca = |noise| {
            Candidate::PcaMap(PcaSettings {
                noise,
                components: None,
            })
        };
        assert!(on_edge(&pca(1.0)) && on_edge(&pca(0.001)) && !on_edge(&pca(0.1)));
        let s = BaselineSettings {
            tuned_on: "val".into(),
            rule: "r".into(),
            views: [("1".to_string(), d), ("2".to_string(), d)].into(),
        };
        let dir = std::env::temp_dir().join(format!("tomograf-tuning-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(FILE);
        std::fs::write(&path, toml::to_string(&s).unwrap()).unwrap();
        let back = BaselineSettings::read(&path).unwrap();
        assert_eq!(back, s);
        assert_eq!(back.for_views(2).unwrap(), d);
        let e = back.for_views(5).unwrap_err().to_string();
        assert!(e.contains("1, 2") && e.contains("not 5"), "{e}");
        // Bad files name the problem.
        let bad = toml::to_string(&s)
            .unwrap()
            .replace("sweeps = 20", "sweeps = 0");
        std::fs::write(&path, bad).unwrap();
        let e = format!("{:#}", BaselineSettings::read(&path).unwrap_err());
        assert!(e.contains("sweeps 0"), "{e}");
        let bad = toml::to_string(&s).unwrap().replace("[views.2", "[views.x");
        std::fs::write(&path, bad).unwrap();
        let e = format!("{:#}", BaselineSettings::read(&path).unwrap_err());
        assert!(e.contains("'x'"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
