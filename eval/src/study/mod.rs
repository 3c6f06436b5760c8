//! The studies (`tomograf study realism-gap` and `tomograf study domain-shift`): generate the data sets,
//! train the models, evaluate every model on every test set (with FDK and SART-TV from
//! the same views) and write a report with tables and plots.
//!
//! A study folder holds `study.json` (its settings), `data/{train,val,test}/<set>/`,
//! `models/<set>/` (a `tomograf train` run; `done.json` when finished),
//! `tune/<test set>/` (the baselines' settings chosen on that set's validation phantoms, a
//! `tomograf tune-baselines` folder), `eval/<test set>/{classical,model-<train set>}/`
//! (`tomograf evaluate` folders),
//! `results.csv`, `report.md`, `report.html` and `figures/`. Every step is resumable —
//! finished items, models and scores are kept and skipped — and every file is written
//! atomically. Stages (`--stage data|train|evaluate|report`) and `--shard I/N` split the
//! work across machines: see docs/studies.md.

mod coverage;
pub mod effects;
pub mod levels;
pub mod peak;
mod render;
mod report;

use crate::evaluation::{DEFAULT_PCA_NOISE, Evaluation, evaluate};
use crate::training::{Training, train};
use crate::tuning::{BaselineSettings, Grid, Tuning, tune};
use anyhow::{Context, Result, bail};
use levels::DataSpec;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use tomograf_datasets::anatomy::Profile;
use tomograf_scene::dataset::{DatasetJob, ItemSettings, ItemSource};
use tomograf_scene::{Progress, Silent};

/// Sizes of a study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scale {
    pub name: String,
    /// CT grid (size³) and detector (size²).
    pub size: usize,
    /// Projections per rotation in the training sets, besides AP and lateral.
    pub views: usize,
    /// Projections per rotation in the test sets, besides AP and lateral: a multiple of 10,
    /// so that the 5- and 10-view sets (every 72° and 36°) are among them.
    pub test_views: usize,
    pub train_phantoms: usize,
    pub test_phantoms: usize,
    /// Model configuration preset (`tomograf train --config`).
    pub config: String,
    /// Photon histories per view of the scatter estimate.
    pub scatter_photons: u64,
}

impl Scale {
    /// Validation phantoms per test set (half the test phantoms, at least 1): the
    /// baselines' settings are chosen on them.
    pub fn val_phantoms(&self) -> usize {
        self.test_phantoms.div_ceil(2).max(1)
    }

    pub fn parse(name: &str) -> Result<Self> {
        let (size, views, test_views, train, test, config, photons) = match name {
            "tiny" => (16, 10, 10, 4, 2, "tiny", 100),
            "small" => (64, 36, 10, 32, 8, "small", 5_000),
            "medium" => (128, 36, 10, 32, 8, "medium", 5_000),
            other => bail!("unknown --scale '{other}': use tiny, small or medium"),
        };
        Ok(Self {
            name: name.into(),
            size,
            views,
            test_views,
            train_phantoms: train,
            test_phantoms: test,
            config: config.into(),
            scatter_photons: photons,
        })
    }
}

/// Which study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    RealismGap,
    DomainShift,
}

/// What a study folder holds (`study.json`): a re-run must ask for the same.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    pub kind: Kind,
    pub scale: Scale,
    pub seed: u64,
    pub train_sets: Vec<String>,
    pub test_sets: Vec<String>,
    /// The user's CTs the training sets are made of (empty: phantoms).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub train_cts: Vec<PathBuf>,
    /// The user's CTs the test sets (realism gap) or the `user-ct` set (domain shift) are
    /// made of.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub test_cts: Vec<PathBuf>,
}

/// A study: its folder, settings and data sets.
pub struct Study {
    pub dir: PathBuf,
    pub settings: Settings,
    pub train: Vec<DataSpec>,
    pub test: Vec<DataSpec>,
    pub backend: Option<String>,
    /// Studies whose scores the report pools (`--pool`): the same study run with other
    /// seeds, each in its own folder. Empty: this folder's own scores.
    pub pool: Vec<PathBuf>,
}

/// View counts every study evaluates (the paper's).
pub const VIEWS: [usize; 4] = [1, 2, 5, 10];

impl Study {
    /// Writes `study.json`, or checks that the folder's is the same study.
    pub fn check_settings(&self) -> Result<()> {
        std::fs::create_dir_all(&self.dir)
            .with_context(|| format!("cannot create {}", self.dir.display()))?;
        tomograf_datasets::atomic::remove_stale_temporaries(&self.dir)?;
        let path = self.dir.join("study.json");
        if let Ok(bytes) = std::fs::read(&path) {
            let old: Settings = serde_json::from_slice(&bytes)
                .with_context(|| format!("{} is not a study's settings", path.display()))?;
            if old != self.settings {
                bail!(
                    "{} holds another study ({:?}, scale {}, seed {}, sets {:?} → {:?}); choose \
                     another --output or the same settings",
                    self.dir.display(),
                    old.kind,
                    old.scale.name,
                    old.seed,
                    old.train_sets,
                    old.test_sets
                );
            }
            return Ok(());
        }
        Ok(tomograf_datasets::atomic::write_json(
            &path,
            &serde_json::to_value(&self.settings)?,
        )?)
    }

    /// The number of items of a test set: its CTs, or the scale's test phantoms.
    pub fn test_items(&self, name: &str) -> usize {
        match self.test.iter().find(|t| t.name == name) {
            Some(t) if !t.cts.is_empty() => t.cts.len(),
            _ => self.settings.scale.test_phantoms,
        }
    }

    fn data_dir(&self, split: &str, spec: &DataSpec) -> PathBuf {
        self.dir.join("data").join(split).join(spec.data_name())
    }

    fn model_dir(&self, spec: &DataSpec) -> PathBuf {
        self.dir.join("models").join(spec.name)
    }

    /// The evaluation folder of a model (`Some(train set)`) or of the classical baselines
    /// on a test set.
    pub fn eval_dir(&self, test: &str, train: Option<&str>) -> PathBuf {
        eval_dir_in(&self.dir, test, train)
    }

    /// The pooled studies (`--pool`): each one's folder and seed, after checking that it is
    /// this study but for the seed, that no seed repeats and that each is complete enough
    /// to report. Empty without `--pool`.
    pub fn pooled(&self) -> Result<Vec<(PathBuf, u64)>> {
        let mut out: Vec<(PathBuf, u64)> = Vec::new();
        for dir in &self.pool {
            let path = dir.join("study.json");
            let bytes = std::fs::read(&path)
                .with_context(|| format!("--pool: {} is not a study folder", dir.display()))?;
            let other: Settings = serde_json::from_slice(&bytes)
                .with_context(|| format!("--pool: {} is not a study's settings", path.display()))?;
            let same = Settings {
                seed: self.settings.seed,
                ..other.clone()
            };
            if same != self.settings {
                bail!(
                    "--pool: {} is another study ({:?}, scale {}, sets {:?} → {:?}); pool runs of \
                     the same study that differ only in --seed",
                    dir.display(),
                    other.kind,
                    other.scale.name,
                    other.train_sets,
                    other.test_sets
                );
            }
            if let Some((d, _)) = out.iter().find(|(_, s)| *s == other.seed) {
                bail!(
                    "--pool: {} and {} both hold seed {}: pool runs with different seeds",
                    d.display(),
                    dir.display(),
                    other.seed
                );
            }
            out.push((dir.clone(), other.seed));
        }
        Ok(out)
    }

    fn dataset_job(
        &self,
        split: &str,
        spec: &DataSpec,
        shard: (usize, usize),
    ) -> Result<DatasetJob> {
        let s = &self.settings;
        let (test, val) = (split == "test", split == "val");
        // Train, validation and test phantoms are disjoint; the same phantoms at every
        // realism level.
        let first = s.seed.wrapping_mul(100_000).wrapping_add(match split {
            "test" => 50_000,
            "val" => 70_000,
            _ => 0,
        });
        let mut physics = spec.physics.clone();
        if spec.real_physics() {
            physics.noise_seed = Some(if val {
                tomograf_sim::seed::frame_seed(s.seed, 0x7A1)
            } else {
                s.seed.wrapping_mul(2).wrapping_add(u64::from(test))
            });
        }
        let (count, views) = match split {
            "test" => (s.scale.test_phantoms, s.scale.test_views),
            "val" => (s.scale.val_phantoms(), s.scale.test_views),
            _ => (s.scale.train_phantoms, s.scale.views),
        };
        let profile = Profile::parse(spec.profile)?;
        // Validation sets are phantoms even when the test set is the user's CTs.
        let sources = if spec.cts.is_empty() || val {
            (0..count)
                .map(|n| ItemSource::phantom(first + n as u64, profile, spec.table, spec.pacemaker))
                .collect()
        } else {
            spec.cts
                .iter()
                .map(|path| ItemSource::File { path: path.clone() })
                .collect()
        };
        Ok(DatasetJob {
            sources,
            settings: ItemSettings {
                views,
                size: s.scale.size,
                split: split.into(),
                acquisition: physics.acquisition()?,
                ..ItemSettings::default()
            },
            output: self.data_dir(split, spec),
            shard,
        })
    }

    /// Every data set of `splits`, or this shard's items of each.
    pub fn data(
        &self,
        (i, n): (usize, usize),
        splits: &[&str],
        progress: &dyn Progress,
    ) -> Result<()> {
        // The validation sets (the baselines are tuned on them) come with the test sets.
        for (split, specs) in [
            ("train", &self.train),
            ("test", &self.test),
            ("val", &self.test),
        ] {
            let asked = if split == "val" { "test" } else { split };
            if !splits.contains(&asked) {
                continue;
            }
            for spec in specs.iter().filter(|s| s.data_of.is_none()) {
                progress.note(&format!("data: {split} set '{}'", spec.name));
                self.dataset_job(split, spec, (i, n))?
                    .make(progress)
                    .with_context(|| format!("{split} set '{}'", spec.name))?;
            }
        }
        Ok(())
    }

    /// Makes sure a data set is complete (generating what a shard left out) and its
    /// manifest lists every item.
    fn finish_data(
        &self,
        split: &str,
        spec: &DataSpec,
        progress: &dyn Progress,
    ) -> Result<PathBuf> {
        let job = self.dataset_job(split, spec, (0, 1))?;
        job.make(progress)
            .with_context(|| format!("{split} set '{}'", spec.name))?;
        Ok(job.output)
    }

    /// Trains every model not yet trained (this shard's: model k goes to shard k mod N).
    pub fn train(&self, (i, n): (usize, usize), progress: &dyn Progress) -> Result<()> {
        for (k, spec) in self.train.iter().enumerate() {
            if k % n != i {
                continue;
            }
            let dir = self.model_dir(spec);
            if dir.join("done.json").exists() {
                progress.note(&format!("train: model '{}' already trained", spec.name));
                continue;
            }
            // What the last stage or model freed is given back first: this model's peak is
            // its own.
            tomograf_sim::memory::release_freed();
            let data = self.finish_data("train", spec, progress)?;
            // `--resume` continues the checkpoint when there is one (putting back one whose
            // save was killed) and starts afresh otherwise.
            let resume = true;
            progress.note(&format!(
                "train: model '{}' ({})",
                spec.name,
                if resume { "resuming" } else { "new" }
            ));
            train(
                &Training {
                    data: &data,
                    output: &dir,
                    config: &self.settings.scale.config,
                    iterations: None,
                    seed: Some(self.settings.seed),
                    split: None,
                    resume,
                    init: None,
                    backend: self.backend.as_deref(),
                },
                progress,
            )
            .with_context(|| format!("training model '{}'", spec.name))?;
            tomograf_datasets::atomic::write_json(
                &dir.join("done.json"),
                &serde_json::json!({"train_set": spec.name}),
            )?;
        }
        Ok(())
    }

    /// Scores every model and the classical baselines on every test set (this shard's
    /// items of each).
    pub fn evaluate(&self, shard: (usize, usize), progress: &dyn Progress) -> Result<()> {
        // What the last stage freed is given back before this one starts (its peak is
        // this stage's alone).
        tomograf_sim::memory::release_freed();
        for spec in &self.train {
            if !self.model_dir(spec).join("done.json").exists() {
                bail!(
                    "model '{}' is not trained yet: run --stage train (on every shard) first",
                    spec.name
                );
            }
        }
        let mut scored = 0;
        // Where the classical cell's scatter correction takes its mean volume from (every
        // training set holds the same CTs).
        let prior_data = self.train.first().map(|m| self.data_dir("train", m));
        for test in &self.test {
            let baselines = self.tune(test, shard, progress)?;
            let data = self.finish_data("test", test, progress)?;
            let mut cells: Vec<(Option<PathBuf>, PathBuf, Option<PathBuf>)> =
                vec![(None, self.eval_dir(test.name, None), None)];
            for m in &self.train {
                cells.push((
                    Some(self.model_dir(m).join("checkpoint")),
                    self.eval_dir(test.name, Some(m.name)),
                    Some(self.data_dir("train", m)),
                ));
            }
            for (checkpoint, output, train_data) in &cells {
                progress.note(&format!("evaluate: {}", output.display()));
                tomograf_sim::memory::release_freed();
                scored += evaluate(&Evaluation {
                    data: &data,
                    checkpoint: checkpoint.as_deref(),
                    train_data: train_data.as_deref(),
                    output,
                    views: &VIEWS,
                    split: None,
                    items: None,
                    infer: Default::default(),
                    seed: self.settings.seed,
                    backend: self.backend.as_deref(),
                    shard,
                    pca_noise: DEFAULT_PCA_NOISE,
                    baselines: Some(&baselines),
                    classical: checkpoint.is_none(),
                    scatter_correction: test.correction,
                    scatter_prior_data: prior_data.as_deref(),
                    progress: &Silent,
                    all_figures: false,
                    replace: false,
                })?;
            }
        }
        progress.note(&format!(
            "evaluate: {scored} item evaluation(s) run, the rest were already scored"
        ));
        Ok(())
    }
}

impl Study {
    /// The folder of a test set's baseline tuning.
    pub fn tune_dir(&self, test: &str) -> PathBuf {
        self.dir.join("tune").join(test)
    }

    /// The baselines' settings for `test`, chosen on its validation set (the same
    /// population and acquisition, other phantoms; the views corrected as the test set's
    /// are) with the mean volume and PCA-MAP prior of the training set of the same
    /// acquisition, or of the first training set where none has it: each baseline at
    /// its best for that set, so that no lead of TomoGRAF's comes from untuned baselines.
    /// Resumable; the search is kept in [`Self::tune_dir`]. Every evaluation shard runs it
    /// (each needs the settings), each beginning at its own share of the items.
    fn tune(
        &self,
        test: &DataSpec,
        shard: (usize, usize),
        progress: &dyn Progress,
    ) -> Result<BaselineSettings> {
        let data_spec = match test.data_of {
            Some(name) => self.test.iter().find(|t| t.name == name).with_context(|| {
                format!(
                    "test set '{}' takes its data from unknown '{name}'",
                    test.name
                )
            })?,
            None => test,
        };
        // The training set of the same acquisition when there is one (realism gap), else
        // the first: its line integrals set PCA-MAP's noise scale.
        let train = self
            .train
            .iter()
            .find(|t| t.name == data_spec.name)
            .or(self.train.first())
            .context("a study without a training set has nothing to tune with")?;
        let train_data = self.finish_data("train", train, progress)?;
        let val = self.finish_data("val", data_spec, progress)?;
        progress.note(&format!("tune: the baselines for '{}'", test.name));
        let (settings, _) = tune(&Tuning {
            data: &val,
            split: None,
            items: None,
            train_data: &train_data,
            views: &VIEWS,
            scatter_correction: test.correction,
            // TomoGRAF's sweeps stay the checkpoint's: a search per model and test set
            // would multiply the study's inference by the grid.
            checkpoint: None,
            seed: 0,
            backend: None,
            // `tiny` is a smoke test of the pipeline: a grid of 12 settings, not 82.
            grid: if self.settings.scale.name == "tiny" {
                Grid::Smoke
            } else {
                Grid::Full
            },
            output: &self.tune_dir(test.name),
            shard,
            progress: &Silent,
        })
        .with_context(|| format!("tuning the baselines for test set '{}'", test.name))?;
        Ok(settings)
    }

    /// Writes `report.md`, `report.html`, `results.csv` and `figures/` from the scores so
    /// far (`partial`: an interim report while shards still run; otherwise every cell must
    /// be complete).
    pub fn report(&self, partial: bool) -> Result<()> {
        // What the last stage freed is given back before this one starts (its peak is
        // this stage's alone).
        tomograf_sim::memory::release_freed();
        report::write(self, partial)
    }

    /// Measures what each test set does to the projections (`effects.json`, written anew)
    /// and returns the report's table of it as markdown.
    pub fn effects(&self) -> Result<String> {
        let _ = std::fs::remove_file(self.dir.join("effects.json"));
        let e = effects::load_or_measure(self)?;
        Ok(report::effects_markdown(&e))
    }
}

/// The evaluation folder of a cell in the study folder `dir`.
pub fn eval_dir_in(dir: &Path, test: &str, train: Option<&str>) -> PathBuf {
    let cell = train.map_or("classical".to_string(), |t| format!("model-{t}"));
    dir.join("eval").join(test).join(cell)
}

/// Whether `path` is inside the study folder `dir` (for relative links in the report).
pub fn relative(dir: &Path, path: &Path) -> String {
    path.strip_prefix(dir)
        .unwrap_or(path)
        .to_string_lossy()
        .into_owned()
}

#[cfg(test)]
mod tests {
    use super::Scale;

    /// `tomograf evaluate` takes the 5- and 10-view sets every 72° and 36° of a test set's
    /// rotation: every scale must make test sets with a multiple of 10 views (`small` once
    /// made 36 and its evaluation stopped with "no projection at θ = 72°").
    #[test]
    fn every_scale_makes_test_sets_the_evaluation_can_use() {
        for name in ["tiny", "small", "medium"] {
            let s = Scale::parse(name).unwrap();
            assert!(
                s.test_views > 0 && s.test_views.is_multiple_of(10),
                "{name}: {} test views",
                s.test_views
            );
            // Its model must be trainable on its grid (the encoding within its Nyquist
            // limit; `train` refuses otherwise, after the data stage's hours).
            let config = tomograf_model::config::TrainConfig::load(&s.config).unwrap();
            config.check_grid(s.size).unwrap();
        }
        assert_eq!(Scale::parse("medium").unwrap().size, 128);
        let e = Scale::parse("large").unwrap_err().to_string();
        assert!(e.contains("'large'") && e.contains("medium"), "{e}");
    }
}
