//! The peak memory of a whole study, estimated before its first stage runs: the largest of
//! its stages' peaks, each from the estimate that stage checks on its own (docs/reliability.md,
//! "Memory budget"), with the sizes the study fixes — the scale's grid, views and phantom
//! counts — instead of the files the earlier stages would write.
//!
//! * **data**: the largest item, [`tomograf_scene::peak::item_peak_bytes`] of a phantom at
//!   its generated size, rendered into the set's views (a user's CT is checked as
//!   `tomograf dataset` checks it, once its header is read: its size is not known before);
//! * **training**: [`TrainConfig::training_peak_bytes`] of the scale's configuration on the
//!   largest training set;
//! * **evaluation** (the baselines' tuning on the validation sets runs inside it):
//!   [`crate::peak::evaluation_peak_bytes`] of the largest test set with PCA-MAP's training
//!   set held and TomoGRAF's inference;
//! * **report**: measuring what each test set does to the projections, on a phantom of the
//!   set ([`effects_peak_bytes`]).
//!
//! Stages run one after another and each frees what it held, so the study's peak is the
//! largest of the four.

use super::Study;
use crate::peak::{Held, MIB, evaluation_peak_bytes};
use anyhow::Result;
use tomograf_model::config::TrainConfig;
use tomograf_scene::Progress;
use tomograf_scene::dataset::ItemSource;
use tomograf_scene::peak::{item_peak_bytes, item_prepare_peak_bytes, item_render_peak_bytes};

/// A study's estimated peak per stage, bytes (0 where a stage has nothing to estimate).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StudyPeak {
    pub data: u128,
    pub training: u128,
    pub evaluation: u128,
    /// The report, which first measures what each test set does to the projections
    /// ([`super::effects`]): a phantom generated, cropped and rendered with the set's
    /// physics beside a copy of it.
    pub report: u128,
}

impl StudyPeak {
    /// The largest stage's peak and its name.
    pub fn largest(&self) -> (u128, &'static str) {
        [
            (self.data, "data"),
            (self.training, "training"),
            (self.evaluation, "evaluation"),
            (self.report, "report"),
        ]
        .into_iter()
        .fold((0, "data"), |a, b| if b.0 > a.0 { b } else { a })
    }

    /// "data 120 MiB, training 380 MiB, evaluation 210 MiB, report 150 MiB".
    pub fn describe(&self) -> String {
        let mib = |b: u128| format!("{:.0} MiB", b as f64 / MIB);
        format!(
            "data {}, training {}, evaluation {}, report {}",
            mib(self.data),
            mib(self.training),
            mib(self.evaluation),
            mib(self.report)
        )
    }
}

impl Study {
    /// Estimates the peak memory of each stage from the study's settings alone (no file of
    /// the study is read).
    pub fn peak(&self) -> Result<StudyPeak> {
        let scale = &self.settings.scale;
        let size = scale.size as u128;
        let grid = size * size * size;
        // An item as loaded: its f32 CT on the grid and its views (+ AP and lateral).
        let item_bytes = |views: usize| 4 * (grid + (views as u128 + 2) * size * size);
        let (mut data, mut report) = (0, 0);
        let mut train_items = 0u128;
        for (split, specs) in [
            ("train", &self.train),
            ("test", &self.test),
            ("val", &self.test),
        ] {
            for spec in specs.iter().filter(|s| s.data_of.is_none()) {
                let job = self.dataset_job(split, spec, (0, 1))?;
                if split == "train" {
                    train_items = train_items.max(job.sources.len() as u128);
                }
                let pixels = (job.settings.views as u128 + 2) * size * size;
                let physics = job.settings.acquisition.is_some();
                for source in &job.sources {
                    if let ItemSource::Phantom { spec } = source {
                        let voxels = spec.dims.iter().map(|&n| n as u128).product::<u128>();
                        data = data.max(item_peak_bytes(
                            item_prepare_peak_bytes(false, voxels),
                            item_render_peak_bytes(physics, voxels, pixels, grid),
                        ));
                        if split == "test" {
                            report = report.max(effects_peak_bytes(voxels, physics));
                        }
                    }
                }
            }
        }
        let config = TrainConfig::load(&scale.config)?;
        // The models train one after another in one process, which keeps a little of each
        // (the `tiny` studies' training stage measured 28–30 MiB for four models, 26 for
        // one, against 24–25 for one `train` job).
        let training = config.training_peak_bytes(train_items * item_bytes(scale.views)) as u128
            + (6.0 * MIB) as u128;
        let test_items = self
            .test
            .iter()
            .map(|t| self.test_items(t.name) as u128)
            .max()
            .unwrap_or(0);
        let held = Held {
            test_bytes: test_items * item_bytes(scale.test_views),
            train_items,
            train_voxels: grid,
            train_pixels: (scale.views as u128 + 2) * size * size,
        };
        let inference = config.inference_peak_bytes(&config.infer, size * size);
        let evaluation = evaluation_peak_bytes(grid, held, Some(inference));
        Ok(StudyPeak {
            data,
            training,
            evaluation,
            report,
        })
    }
}

/// Peak of measuring one test set's effects on the projections ([`super::effects`]) on a
/// phantom of `voxels`, bytes: the phantom generated and cropped, then rendered (with the
/// set's detector physics and scatter when `physics`) beside a copy of it, `37 MiB (60 MiB
/// with physics) + 1.51 · 4·voxels` — fitted to `/usr/bin/time -v` peaks of the report
/// stage of `tiny` studies (`scripts/memory_peaks_study.sh`; lidc phantoms: 66 MiB ideal,
/// 83–94 with physics; full-chest with physics 129), each item made from what is really
/// held ([`tomograf_sim::memory::release_freed`]).
fn effects_peak_bytes(voxels: u128, physics: bool) -> u128 {
    let base = if physics { 60.0 } else { 37.0 };
    (base * MIB) as u128 + (1.51 * 4.0 * voxels as f64) as u128
}

/// Which stages a run of `tomograf study` will run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stages {
    pub data: bool,
    pub training: bool,
    pub evaluation: bool,
    pub report: bool,
}

impl Study {
    /// Refuses a study whose largest stage among `stages` (estimated by [`Study::peak`]),
    /// beyond what the process holds now, exceeds the memory available — before the first
    /// stage allocates anything — naming each stage's estimate; else notes the estimate.
    /// Each stage checks its own peak again when it runs, from the files it reads.
    pub fn check_memory(&self, stages: Stages, progress: &dyn Progress) -> Result<StudyPeak> {
        let all = self.peak()?;
        let peak = StudyPeak {
            data: if stages.data { all.data } else { 0 },
            training: if stages.training { all.training } else { 0 },
            evaluation: if stages.evaluation { all.evaluation } else { 0 },
            report: if stages.report { all.report } else { 0 },
        };
        let (largest, stage) = peak.largest();
        if largest == 0 {
            return Ok(peak);
        }
        let s = &self.settings;
        let what = format!(
            "the study (--scale {}: {}³ grids, {} training and {} test phantoms per set; {} \
             training and {} test set(s); {}) in its {stage} stage (estimated peak {:.0} MiB; \
             a smaller --scale, fewer sets or fewer CTs need less)",
            s.scale.name,
            s.scale.size,
            s.scale.train_phantoms,
            s.scale.test_phantoms,
            self.train.len(),
            self.test.len(),
            peak.describe(),
            largest as f64 / MIB
        );
        crate::peak::check_beyond_held(largest, &what)?;
        progress.note(&format!(
            "study: estimated peak memory {:.0} MiB, in its {stage} stage ({})",
            largest as f64 / MIB,
            peak.describe()
        ));
        Ok(peak)
    }
}

#[cfg(test)]
mod tests {
    use super::StudyPeak;

    #[test]
    fn the_largest_stage_is_named() {
        let p = StudyPeak {
            data: 3,
            training: 7,
            evaluation: 5,
            report: 6,
        };
        assert_eq!(p.largest(), (7, "training"));
        let p = StudyPeak { evaluation: 9, ..p };
        assert_eq!(p.largest(), (9, "evaluation"));
    }
}
