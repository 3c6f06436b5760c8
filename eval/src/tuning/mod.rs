//! The baselines' settings, chosen on a validation set (`tomograf tune-baselines`): every
//! setting a user of SART-TV (from zero and from the mean training volume), PCA-MAP and FDK
//! would tune is searched on a grid ([`Grid`]), each candidate is scored on every
//! validation item from each view count, and the one with the highest mean PSNR per method
//! and view count goes into `baselines.toml` ([`BaselineSettings`]), which `tomograf
//! evaluate --baselines` and `tomograf demo` read. With a checkpoint, TomoGRAF's own
//! data-consistency sweeps are searched on the same grid as SART-TV's, by the same rule
//! (its network runs once per item and view count; only the sweeps after it vary). The
//! whole search is kept (`search.csv`, `search.md`) so a reader can see how flat the
//! optimum is.
//!
//! The search never touches a test set: it reads the data set it is given, which should be
//! a validation split (disjoint seeds from training and test).

use crate::protocol::{correct_scatter, load_items, paper_poses, references, run_one};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use tomograf_datasets::atomic::write_atomic;
use tomograf_model::baseline::{Baseline, Fdk, SartTv, SartTvSettings};
use tomograf_model::config::InferConfig;
use tomograf_model::data::Item;
use tomograf_model::metrics::{Scores, score};
use tomograf_model::pca::{PcaMap, PcaSettings};
use tomograf_model::prior::MeanVolume;
use tomograf_model::reconstruct::{NetworkVolume, Reference};
use tomograf_model::refine::{start_weights, sweep_from};
use tomograf_model::render::DensityScale;
use tomograf_model::scatter_correction::ScatterCorrection;
use tomograf_model::{backend, checkpoint, data};
use tomograf_scene::{Progress, Silent};
use tomograf_sim::{Pose, Volume};

mod choose;
mod grid;
mod settings;

use choose::choose;

pub use grid::{Candidate, Grid};
pub use settings::{
    BaselineSettings, FDK, FILE, PCA_MAP, SART_TV, SART_TV_FROM_MEAN, TOMOGRAF, ViewSettings,
};

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
    /// Also search this checkpoint's data-consistency sweeps (TomoGRAF), its network run
    /// with inference seed `seed` as `tomograf evaluate --seed` runs it.
    pub checkpoint: Option<&'a Path>,
    pub seed: u64,
    pub backend: Option<&'a str>,
    /// The grid searched.
    pub grid: Grid,
    /// Output folder: search.csv, search.md, baselines.toml, items/.
    pub output: &'a Path,
    /// This process's shard `(i, n)` of processes running the same search at once (a
    /// study's evaluation shards): shard i begins at item i·len/n and wraps around, so the
    /// shards score different items first instead of the same ones side by side; each
    /// still scores every item no other has written when it gets there, and the choice does
    /// not depend on the order. `(0, 1)`: one process.
    pub shard: (usize, usize),
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
    /// The checkpoint whose sweeps were searched, and its inference seed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    checkpoint: Option<(PathBuf, u64)>,
    /// SHA-256 of what inference reads from that checkpoint
    /// ([`checkpoint::fingerprint`]): a retrained checkpoint in the same folder is another
    /// search (absent without a checkpoint, and in folders written before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    checkpoint_sha256: Option<String>,
}

fn is_none(c: &ScatterCorrection) -> bool {
    *c == ScatterCorrection::None
}

/// Runs the search (resuming: items already under `output/items/` are not re-scored),
/// writes `search.csv`, `search.md` and `baselines.toml`; returns the settings and the
/// search's markdown.
pub fn tune(t: &Tuning) -> Result<(BaselineSettings, String)> {
    let items = load_items(t.data, t.split, t.items, t.views)?;
    let train = data::load_dataset(t.train_data, None)
        .with_context(|| format!("the training set {}", t.train_data.display()))?;
    let cts: Vec<&Volume> = train.iter().filter_map(|i| i.ct.as_ref()).collect();
    let pca = PcaMap::from_volumes(
        &cts,
        PcaSettings::default().noise,
        tomograf_model::train::projection_scale(&train)?,
    )?;
    let mean = &pca.mean;
    // The checkpoint's inference settings and mean volume (the sweeps' start), and the
    // device its network runs on.
    let model: Option<(&Path, InferConfig, MeanVolume, tomograf_model::Device)> = match t.checkpoint
    {
        Some(ck) => {
            let device = backend::device(t.backend.unwrap_or(backend::default_name()))?;
            let g = checkpoint::load_generator(ck, &device)
                .with_context(|| format!("checkpoint {}", ck.display()))?;
            Some((ck, g.config.infer, g.prior, device))
        }
        None => None,
    };
    let candidates = t.grid.candidates(model.is_some());
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
        checkpoint: t.checkpoint.map(|c| (c.to_path_buf(), t.seed)),
        checkpoint_sha256: t
            .checkpoint
            .map(|ck| {
                checkpoint::fingerprint(ck).with_context(|| format!("checkpoint {}", ck.display()))
            })
            .transpose()?,
    };
    std::fs::create_dir_all(t.output.join("items"))
        .with_context(|| format!("cannot create {}", t.output.display()))?;
    tomograf_datasets::atomic::remove_stale_temporaries(t.output)?;
    check_job(t.output, &job)?;
    // Each item's rows in its own slot, so the rows keep the items' order whatever order
    // they were scored in.
    let mut per_item: Vec<Vec<Row>> = vec![Vec::new(); items.len()];
    let first = t.shard.0 * items.len() / t.shard.1.max(1);
    for k in 0..items.len() {
        let n = (first + k) % items.len();
        let item = &items[n];
        let path = t.output.join("items").join(format!("{}.csv", item.id));
        if let Ok(text) = std::fs::read_to_string(&path) {
            per_item[n] =
                parse_rows(&text, &candidates).with_context(|| path.display().to_string())?;
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
            let poses = paper_poses(count)?;
            let refs = references(item, &poses)?;
            let system = pca.system(&refs, grid, &item.scale)?;
            let network = match &model {
                Some((ck, infer, _, device)) => Some(network(ck, item, &poses, infer, t, device)?),
                None => None,
            };
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
                    Candidate::Tomograf(s) => {
                        let (Some((_, infer, prior, _)), Some(net)) = (&model, &network) else {
                            bail!("TomoGRAF's sweeps are searched only with a checkpoint");
                        };
                        sweeps_after(net, &refs, prior, &item.scale, infer, s)?
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
        per_item[n] = parse_rows(&text, &candidates)?;
    }
    let rows: Vec<Row> = per_item.into_iter().flatten().collect();
    write_atomic(&t.output.join("search.csv"), |w| {
        std::io::Write::write_all(w, csv(&rows).as_bytes())
    })?;
    // TomoGRAF's default: the checkpoint's own sweeps.
    let own = model.as_ref().map(|(_, infer, _, _)| SartTvSettings {
        sweeps: infer.refine_iterations,
        tv_step: infer.refine_tv_step,
    });
    let (settings, md) = choose(t, &candidates, &rows, items.len(), own)?;
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

/// TomoGRAF's network volume for `item` from `poses`: the checkpoint's inference with one
/// data-consistency sweep, so that the network's volume and its views' projection PSNRs
/// (the sweeps' gate) are reported; the sweeps themselves are the candidates'.
fn network(
    ck: &Path,
    item: &Item,
    poses: &[Pose],
    infer: &InferConfig,
    t: &Tuning,
    device: &tomograf_model::Device,
) -> Result<NetworkVolume> {
    let mut infer = infer.clone();
    infer.refine_iterations = 1;
    let rec = run_one(ck, item, poses, Some(&infer), t.seed, device, t.progress)?;
    rec.network
        .context("the reconstruction did not report the network's volume")
}

/// TomoGRAF's volume with the sweeps `s` after its network (`infer`'s start and gate, as
/// `tomograf evaluate` runs them): the network's volume as it is when some view is
/// explained and the gate keeps the sweeps from running.
fn sweeps_after(
    net: &NetworkVolume,
    refs: &[Reference],
    prior: &MeanVolume,
    scale: &DensityScale,
    infer: &InferConfig,
    s: SartTvSettings,
) -> Result<Volume> {
    if !net.refined {
        return Ok(net.volume.clone());
    }
    let mut infer = infer.clone();
    infer.refine_iterations = s.sweeps;
    infer.refine_tv_step = s.tv_step;
    // The start the network's run chose (it does not depend on the sweeps after it, also
    // when left-out views chose it: model/src/held_out.rs).
    let weights = match net.start {
        Some(w) => w,
        None => start_weights(refs, &net.volume, prior, scale, &infer, &net.psnr)?,
    };
    Ok(sweep_from(
        refs,
        &net.volume,
        prior,
        scale,
        &infer,
        weights,
    )?)
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
                "{} holds another search (other data, items, views, grid or checkpoint); \
                 choose another --output or remove it",
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
        let g = Grid::Full.candidates(true);
        let smoke = Grid::Smoke.candidates(false);
        let d = ViewSettings::default();
        assert!(g.contains(&Candidate::SartTv(d.sart_tv)));
        assert!(g.contains(&Candidate::SartTvFromMean(d.sart_tv_from_mean)));
        assert!(g.contains(&Candidate::PcaMap(d.pca_map)));
        assert!(g.contains(&Candidate::Fdk(d.fdk_window)));
        assert!(g.contains(&Candidate::Tomograf(d.sart_tv)));
        for c in [
            Candidate::SartTv(d.sart_tv),
            Candidate::PcaMap(d.pca_map),
            Candidate::Fdk(d.fdk_window),
        ] {
            assert!(smoke.contains(&c), "{c:?}");
        }
        assert!(!smoke.iter().any(|c| matches!(c, Candidate::Tomograf(_))));
        assert!(smoke.len() * 5 < g.len());
        let labels: std::collections::BTreeSet<String> = g
            .iter()
            .map(|c| format!("{}{}", c.method(), c.setting()))
            .collect();
        assert_eq!(labels.len(), g.len(), "every candidate has its own label");
        assert!(g.iter().all(|c| !c.setting().contains(',')));
        assert!(
            !g.iter()
                .any(|c| Grid::Full.on_edge(c) && *c == Candidate::SartTv(d.sart_tv))
        );
        let sart = |sweeps, tv_step| Candidate::SartTv(SartTvSettings { sweeps, tv_step });
        let on_edge = |c: &Candidate| Grid::Full.on_edge(c);
        assert!(on_edge(&sart(80, 0.1)) && on_edge(&sart(10, 0.8)));
        assert!(!on_edge(&sart(40, 0.0)) && !on_edge(&sart(5, 0.4)));
        assert!(Grid::Smoke.on_edge(&sart(20, 0.0)) && !Grid::Smoke.on_edge(&sart(5, 0.0)));
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
