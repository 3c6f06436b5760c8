//! The evaluation protocol (`tomograf evaluate` and the studies): reconstruct every test
//! item from 1/2/5/10 views with TomoGRAF and the baselines and compare with the ground
//! truth — PSNR, 3D SSIM and RMSE in HU (`tomograf_model::metrics::score`), mean ± std per
//! view count — as a markdown table, a CSV and PNG figures.
//!
//! Each item's scores go to `items/<id>.csv` (written atomically) as soon as it is done, so
//! a re-run skips finished items, and a shard `(I, N)` scores items `I, I+N, …` only; the
//! shards' `items/` folders (one shared output folder, or copied together) are combined
//! into `results.md` / `results.csv` by [`merge`]. Without a checkpoint only the
//! classical baselines (FDK, SART-TV) are scored.

mod results;

use results::write_rows;
pub use results::{NETWORK_ONLY, Row, load_rows, merge, summarise};

use crate::figures::slices_and_profile;
use crate::protocol::{correct_scatter, load_items, paper_poses, references, run_one, write_hu};
use crate::tuning::{BaselineSettings, ViewSettings};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tomograf_model::baseline::{Baseline, Fdk, MeanVolume, SartTv};
use tomograf_model::config::{InferOverrides, Tune};
use tomograf_model::data::Item;
use tomograf_model::pca::{PcaMap, PcaSettings};
use tomograf_model::scatter_correction::ScatterCorrection;
use tomograf_model::{backend, checkpoint, data};
use tomograf_scene::Progress;
use tomograf_sim::{Pose, Volume};

/// The PCA-MAP prior's default projection noise (fraction of the largest line integral).
pub const DEFAULT_PCA_NOISE: f64 = 0.01;

pub use tomograf_model::metrics::{Scores, score};

/// `I/N` with 0 ≤ I < N.
pub fn parse_shard(text: &str) -> Result<(usize, usize)> {
    let bad = || anyhow::anyhow!("--shard '{text}' must be I/N with 0 ≤ I < N, e.g. 0/4");
    let (i, n) = text.split_once('/').ok_or_else(bad)?;
    let (i, n): (usize, usize) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

/// What an evaluation computes; `job.json` of its output folder, so results of different
/// settings are never mixed in one folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Job {
    /// Item ids to score (after --split and --items), in order.
    pub items: Vec<String>,
    pub views: Vec<usize>,
    /// Score TomoGRAF (and the mean training volume) from a checkpoint.
    pub model: bool,
    /// Score FDK and SART-TV.
    pub classical: bool,
    /// Inference seed, iteration cap and what is tuned (model only).
    pub seed: u64,
    pub iterations: Option<usize>,
    pub tune: Option<Tune>,
    /// Inference stopping threshold, dB (absent in folders written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub psnr_threshold: Option<f64>,
    /// Data-consistency sweeps override (absent in folders written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_iterations: Option<usize>,
    /// Their TV step override (absent in folders written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_tv_step: Option<f64>,
    /// The PCA-MAP prior's training set and noise, when it is scored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pca: Option<(PathBuf, f64)>,
    /// The views' scatter correction (absent: none, and in folders written before it).
    #[serde(default, skip_serializing_if = "is_none")]
    pub scatter_correction: ScatterCorrection,
    /// The baselines' tuned settings (absent: their defaults, and in folders written before
    /// them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baselines: Option<BaselineSettings>,
    /// Without a checkpoint: the mean volume and SART-TV from it scored from the training
    /// set's CTs (absent: not, and in folders written before they were).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub data_mean: bool,
    /// SHA-256 of what inference reads from the checkpoint
    /// ([`checkpoint::fingerprint`]): scores of one checkpoint are never taken for
    /// another's, whatever its folder is called (absent without a checkpoint).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint_sha256: Option<String>,
    /// SHA-256 of the scored items' `item.json` files in order: another data set whose item
    /// ids are the same is not taken for this one (absent only in folders written before it
    /// was recorded, which are refused).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub items_sha256: Option<String>,
}

fn is_none(c: &ScatterCorrection) -> bool {
    *c == ScatterCorrection::None
}

/// Where and how to evaluate, for [`evaluate`] (the CLI's and the studies' entry point).
pub struct Evaluation<'a> {
    pub data: &'a Path,
    pub checkpoint: Option<&'a Path>,
    /// The training set: also score the PCA-MAP prior built from its CTs.
    pub train_data: Option<&'a Path>,
    pub output: &'a Path,
    pub views: &'a [usize],
    pub split: Option<&'a str>,
    pub items: Option<usize>,
    /// Overrides of the checkpoint's inference settings.
    pub infer: InferOverrides,
    pub seed: u64,
    pub backend: Option<&'a str>,
    pub shard: (usize, usize),
    /// The PCA-MAP prior's noise (with `train_data`; `baselines`' per view count when given).
    pub pca_noise: f64,
    /// The baselines' settings per view count, tuned on validation (`None`: defaults).
    pub baselines: Option<&'a BaselineSettings>,
    /// Also score FDK and SART-TV.
    pub classical: bool,
    /// Correct the views for scatter first (every method sees the corrected views).
    pub scatter_correction: ScatterCorrection,
    /// Without a checkpoint: the training set whose mean volume the `prior` scatter
    /// correction starts from (`None`: `train_data`'s).
    pub scatter_prior_data: Option<&'a Path>,
    /// Where inference progress and notes go ([`tomograf_scene::Silent`]: nowhere).
    pub progress: &'a dyn Progress,
    /// Figures and the reconstruction for every item scored, not only the data set's first.
    pub all_figures: bool,
    /// A folder holding another evaluation's scores has them removed and re-scored, not
    /// refused (the demo, whose output folder is its own).
    pub replace: bool,
}

/// Scores this shard's items not yet scored under `e.output/items/`; returns how many it
/// scored. Figures (slices, residual, profile) and the reconstruction are written for the
/// data set's first item, by the shard that holds it (for every item with
/// [`Evaluation::all_figures`]).
pub fn evaluate(e: &Evaluation) -> Result<usize> {
    let items = load_items(e.data, e.split, e.items, e.views)?;
    let device = backend::device(e.backend.unwrap_or(backend::default_name()))?;
    let job = Job {
        items: job_ids(&items),
        views: e.views.to_vec(),
        model: e.checkpoint.is_some(),
        classical: e.classical,
        seed: e.seed,
        iterations: e.infer.iterations,
        tune: e.infer.tune,
        psnr_threshold: e.infer.psnr_threshold,
        refine_iterations: e.infer.refine_iterations,
        refine_tv_step: e.infer.refine_tv_step,
        pca: e.train_data.map(|p| (p.to_path_buf(), e.pca_noise)),
        scatter_correction: e.scatter_correction,
        baselines: e.baselines.cloned(),
        data_mean: e.checkpoint.is_none() && e.train_data.is_some(),
        checkpoint_sha256: e
            .checkpoint
            .map(|ck| {
                checkpoint::fingerprint(ck).with_context(|| format!("checkpoint {}", ck.display()))
            })
            .transpose()?,
        items_sha256: Some(items_fingerprint(e.data, &job_ids(&items))?),
    };
    if let Some(b) = e.baselines {
        for &count in e.views {
            let s = b.for_views(count)?;
            if s.tomograf_sweeps.is_some()
                && e.checkpoint.is_some()
                && (e.infer.refine_iterations.is_some() || e.infer.refine_tv_step.is_some())
            {
                bail!(
                    "the baselines' settings also hold TomoGRAF's data-consistency sweeps \
                     (tuned for {count} view(s)): leave out --refine and --refine-tv-step, or \
                     the file"
                );
            }
        }
    }
    if !job.model && !job.classical {
        bail!("nothing to evaluate: give a checkpoint or score the classical baselines");
    }
    // The checkpoint's inference settings, mean training volume and projection scale.
    let mut inference_peak = None;
    let model = match e.checkpoint {
        Some(ck) => {
            for item in &items {
                crate::protocol::warn_population(&e.data.join(&item.id), ck, e.progress)?;
            }
            let generator = checkpoint::load_generator(ck, &device)
                .with_context(|| format!("checkpoint {}", ck.display()))?;
            let infer = generator.config.infer.overridden(&e.infer)?;
            let (_, pixels) = crate::peak::largest(&items);
            inference_peak = Some(generator.config.inference_peak_bytes(&infer, pixels));
            Some((ck, infer, generator.prior, generator.state.proj_scale))
        }
        None => None,
    };
    crate::peak::check_evaluation(&items, e.train_data, inference_peak, e.progress)?;
    std::fs::create_dir_all(e.output.join("items"))
        .with_context(|| format!("cannot create {}", e.output.display()))?;
    tomograf_datasets::atomic::remove_stale_temporaries(e.output)?;
    check_job(e.output, &job, e.replace, e.progress)?;
    // The PCA-MAP prior of the training set's CTs, and without a checkpoint their mean (the
    // mean volume and SART-TV from it are then scored from it: the baselines alone).
    let (pca, data_mean) = match e.train_data {
        Some(dir) => {
            let train = data::load_dataset(dir, None)
                .with_context(|| format!("the PCA prior's training set {}", dir.display()))?;
            let cts: Vec<&Volume> = train.iter().filter_map(|i| i.ct.as_ref()).collect();
            // The model's projection scale when there is one, so both read noise alike.
            let scale = match &model {
                Some((_, _, _, proj_scale)) => *proj_scale,
                None => tomograf_model::train::projection_scale(&train)?,
            };
            e.progress
                .note(&format!("PCA prior from {} training volumes", cts.len()));
            let pca = PcaMap::from_volumes(&cts, e.pca_noise, scale)?;
            let mean = model.is_none().then(|| pca.mean.clone());
            (Some(pca), mean)
        }
        None => (None, None),
    };
    let population_mean = model
        .as_ref()
        .map(|(_, _, mean, _)| mean)
        .or(data_mean.as_ref());
    // The scatter correction's prior: the mean training volume, the checkpoint's or that of
    // a training set's CTs.
    let train_mean = match (&model, e.scatter_prior_data.or(e.train_data)) {
        (None, Some(dir)) if e.scatter_correction == ScatterCorrection::Prior => {
            let train = data::load_dataset(dir, None)
                .with_context(|| format!("the scatter prior's training set {}", dir.display()))?;
            Some(MeanVolume::from_volumes(
                train.iter().filter_map(|i| i.ct.as_ref()),
            )?)
        }
        _ => None,
    };
    let prior_mean = model
        .as_ref()
        .map(|(_, _, mean, _)| mean)
        .or(train_mean.as_ref())
        .or(data_mean.as_ref());
    if e.scatter_correction == ScatterCorrection::Prior && prior_mean.is_none() {
        bail!(
            "--scatter-correction prior estimates scatter from the mean training volume: give \
             --checkpoint or --train-data"
        );
    }
    let (shard, shards) = e.shard;
    let mut made = 0;
    for (n, item) in items.iter().enumerate() {
        let path = item_path(e.output, &item.id);
        if n % shards != shard || path.exists() {
            continue;
        }
        let corrected = correct_views(item, e, prior_mean)?;
        let item = corrected.as_ref().unwrap_or(item);
        let mut rows = Vec::new();
        for &count in e.views {
            let poses = paper_poses(count)?;
            let refs = references(item, &poses)?;
            let grid = item.ct.as_ref().context("item has no ground-truth CT")?;
            let settings = match e.baselines {
                Some(b) => b.for_views(count)?,
                None => ViewSettings {
                    pca_map: PcaSettings {
                        noise: e.pca_noise,
                        components: None,
                    },
                    ..ViewSettings::default()
                },
            };
            // Every baseline, in the tables' order: those built from the model's training
            // population (mean volume, SART-TV from it, PCA-MAP), then the classical ones.
            let sart_mean = population_mean.map(|mean| {
                SartTv::from_mean(MeanVolume::clone(mean)).with(settings.sart_tv_from_mean)
            });
            let pca = pca.as_ref().map(|p| p.fitted_with(settings.pca_map));
            let classical: Vec<Box<dyn Baseline>> = if e.classical {
                vec![
                    Box::new(Fdk {
                        window: settings.fdk_window,
                    }),
                    Box::new(SartTv::from_zero().with(settings.sart_tv)),
                ]
            } else {
                Vec::new()
            };
            let mut baselines: Vec<&dyn Baseline> = Vec::new();
            if let Some(mean) = population_mean {
                baselines.push(mean);
            }
            if let Some(s) = &sart_mean {
                baselines.push(s);
            }
            if let Some(p) = &pca {
                baselines.push(p);
            }
            baselines.extend(classical.iter().map(|b| b.as_ref()));
            let mut volumes: Vec<Volume> = Vec::new();
            if let Some((ck, infer, _, _)) = &model {
                // TomoGRAF's sweeps for this view count, when the search chose them.
                let mut infer = infer.clone();
                if let Some(s) = settings.tomograf_sweeps {
                    infer.refine_iterations = s.sweeps;
                    infer.refine_tv_step = s.tv_step;
                }
                e.progress.note(&format!(
                    "item {} ({}/{}), {count} view(s)",
                    item.id,
                    n + 1,
                    items.len()
                ));
                let t0 = Instant::now();
                let rec = run_one(ck, item, &poses, Some(&infer), e.seed, &device, e.progress)?;
                let seconds = t0.elapsed().as_secs_f64();
                rows.push(Row {
                    item: item.id.clone(),
                    views: count,
                    method: "TomoGRAF".into(),
                    scores: score(item, &rec.volume)?,
                    iterations: rec.iterations,
                    seconds,
                });
                volumes.push(rec.volume);
                if let Some(net) = rec.network {
                    let start = net.start.map_or(String::new(), |w| {
                        format!(
                            " (sweeps from {:.2} × network + {:.2} × mean)",
                            w.network, w.mean
                        )
                    });
                    if let Some(scores) = &net.held_out {
                        let s: Vec<String> = scores
                            .iter()
                            .map(|(w, db)| match w {
                                Some(w) => format!(
                                    "{:.2} × network + {:.2} × mean: {db:.2}",
                                    w.network, w.mean
                                ),
                                None => format!("no sweeps: {db:.2}"),
                            })
                            .collect();
                        e.progress.note(&format!(
                            "  left-out views' projection PSNR (dB) per candidate: {}",
                            s.join("; ")
                        ));
                    }
                    e.progress.note(&format!(
                        "  projection PSNR (dB) of the network's volume {:.1?}, after data \
                         consistency {:.1?}{start}",
                        net.psnr, rec.psnr
                    ));
                    rows.push(Row {
                        item: item.id.clone(),
                        views: count,
                        method: NETWORK_ONLY.into(),
                        scores: score(item, &net.volume)?,
                        iterations: rec.iterations,
                        seconds: seconds - net.refine_seconds,
                    });
                    volumes.push(net.volume);
                }
            }
            for b in &baselines {
                let t0 = Instant::now();
                let v = b.reconstruct(&refs, grid, &item.scale)?;
                rows.push(Row {
                    item: item.id.clone(),
                    views: count,
                    method: b.name().into(),
                    scores: score(item, &v)?,
                    iterations: 0,
                    seconds: t0.elapsed().as_secs_f64(),
                });
                volumes.push(v);
            }
            if n == 0 || e.all_figures {
                let stem = e.output.join(format!("{}_{count}view", item.id));
                write_hu(item, &volumes[0], &stem.with_extension("nii.gz"))?;
                let refs: Vec<&Volume> = volumes.iter().collect();
                let names: Vec<&str> = rows[rows.len() - volumes.len()..]
                    .iter()
                    .map(|r| r.method.as_str())
                    .collect();
                slices_and_profile(item, &refs, &names, &stem)?;
            }
        }
        write_rows(&path, &rows)?;
        made += 1;
    }
    Ok(made)
}

/// `item` with the views that `e.views` use corrected for scatter as `e` asks (`None`: no
/// correction asked).
fn correct_views(item: &Item, e: &Evaluation, prior: Option<&MeanVolume>) -> Result<Option<Item>> {
    let mut poses: Vec<Pose> = Vec::new();
    for &count in e.views {
        for pose in paper_poses(count)? {
            if !poses.contains(&pose) {
                poses.push(pose);
            }
        }
    }
    correct_scatter(
        item,
        e.scatter_correction,
        prior,
        &poses,
        e.seed,
        e.progress,
    )
}

fn item_path(output: &Path, id: &str) -> PathBuf {
    output.join("items").join(format!("{id}.csv"))
}

fn job_ids(items: &[Item]) -> Vec<String> {
    items.iter().map(|i| i.id.clone()).collect()
}

/// SHA-256 (hex) of the items' `item.json` files under `data`, in `ids`' order.
fn items_fingerprint(data: &Path, ids: &[String]) -> Result<String> {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    for id in ids {
        let p = data.join(id).join("item.json");
        let bytes = std::fs::read(&p).with_context(|| format!("cannot read {}", p.display()))?;
        h.update(id.as_bytes());
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(&bytes);
    }
    Ok(format!("{:x}", h.finalize()))
}

/// Writes `job.json`, or checks that the one already there asks for the same evaluation.
/// A folder holding another evaluation's scores is refused, naming what differs; with
/// `replace` (the demo, whose folder is its own) its scores are removed instead.
fn check_job(output: &Path, job: &Job, replace: bool, progress: &dyn Progress) -> Result<()> {
    let path = output.join("job.json");
    if let Ok(bytes) = std::fs::read(&path) {
        let old: Job = serde_json::from_slice(&bytes)
            .with_context(|| format!("{} is not an evaluation's job.json", path.display()))?;
        if old == *job {
            return Ok(());
        }
        let why = job_difference(&old, job);
        if !replace {
            bail!(
                "{} holds results of another evaluation ({why}); choose another --output or \
                 remove it",
                output.display()
            );
        }
        progress.note(&format!(
            "{} held results of another evaluation ({why}): they are removed and re-scored",
            output.display()
        ));
        let items = output.join("items");
        std::fs::remove_dir_all(&items)
            .with_context(|| format!("cannot remove {}", items.display()))?;
        std::fs::create_dir_all(&items)
            .with_context(|| format!("cannot create {}", items.display()))?;
    }
    Ok(tomograf_datasets::atomic::write_json(
        &path,
        &serde_json::to_value(job)?,
    )?)
}

/// What differs between two jobs, in words: the fields by name, or that the old one was
/// written before checkpoints and items were recorded.
fn job_difference(old: &Job, new: &Job) -> String {
    if old.items_sha256.is_none() {
        return "written before evaluations recorded their checkpoint and items, so its \
                scores cannot be told to be this checkpoint's"
            .into();
    }
    let (a, b) = (
        serde_json::to_value(old).unwrap_or_default(),
        serde_json::to_value(new).unwrap_or_default(),
    );
    let (Some(a), Some(b)) = (a.as_object(), b.as_object()) else {
        return "other settings".into();
    };
    let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
    keys.sort();
    keys.dedup();
    let names: Vec<String> = keys
        .into_iter()
        .filter(|k| a.get(*k) != b.get(*k))
        .map(|k| match k.as_str() {
            "checkpoint_sha256" => "another checkpoint".to_string(),
            "items_sha256" => "other items' contents".to_string(),
            k => format!("other {}", k.replace('_', " ")),
        })
        .collect();
    names.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(checkpoint: &str, items: &str) -> Job {
        Job {
            items: vec!["00000".into()],
            views: vec![1],
            model: true,
            classical: false,
            seed: 0,
            iterations: None,
            tune: None,
            psnr_threshold: None,
            refine_iterations: None,
            refine_tv_step: None,
            pca: None,
            scatter_correction: ScatterCorrection::None,
            baselines: None,
            data_mean: false,
            checkpoint_sha256: Some(checkpoint.into()),
            items_sha256: Some(items.into()),
        }
    }

    /// A folder scored with one checkpoint (or items) is refused to another, naming what
    /// differs; a folder written before checkpoints were recorded is refused as such; with
    /// `replace` the old scores go and the new job is written.
    #[test]
    fn scores_of_another_checkpoint_are_never_reused() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path();
        std::fs::create_dir_all(out.join("items")).unwrap();
        let silent = &tomograf_scene::Silent;
        check_job(out, &job("aa", "11"), false, silent).unwrap();
        std::fs::write(out.join("items/00000.csv"), "old scores").unwrap();
        check_job(out, &job("aa", "11"), false, silent).unwrap();
        assert!(out.join("items/00000.csv").exists(), "the same job resumes");

        let e = check_job(out, &job("bb", "11"), false, silent).unwrap_err();
        assert!(format!("{e:#}").contains("(another checkpoint)"), "{e:#}");
        let e = check_job(out, &job("aa", "22"), false, silent).unwrap_err();
        assert!(
            format!("{e:#}").contains("(other items' contents)"),
            "{e:#}"
        );
        let mut other = job("aa", "11");
        other.views = vec![2];
        other.seed = 3;
        let e = check_job(out, &other, false, silent).unwrap_err();
        assert!(
            format!("{e:#}").contains("(other seed, other views)"),
            "{e:#}"
        );
        assert!(
            out.join("items/00000.csv").exists(),
            "a refusal removes nothing"
        );

        // A job.json from before the fields existed.
        let mut old = serde_json::to_value(job("aa", "11")).unwrap();
        let o = old.as_object_mut().unwrap();
        o.remove("checkpoint_sha256");
        o.remove("items_sha256");
        std::fs::write(out.join("job.json"), old.to_string()).unwrap();
        let e = check_job(out, &job("aa", "11"), false, silent).unwrap_err();
        assert!(format!("{e:#}").contains("written before"), "{e:#}");

        check_job(out, &job("bb", "11"), true, silent).unwrap();
        assert!(
            !out.join("items/00000.csv").exists(),
            "replaced scores are removed"
        );
        assert!(out.join("items").is_dir());
        check_job(out, &job("bb", "11"), false, silent).unwrap();
    }
}
