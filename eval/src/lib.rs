//! The evaluation protocol of tomograf, as library code that `tomograf reconstruct`,
//! `tomograf evaluate` and the studies call with typed arguments:
//! * [`protocol`]: the paper's view sets, an item's reference projections, scatter
//!   correction of its views, one reconstruction from a checkpoint, writing it in HU;
//! * [`evaluation`]: scoring TomoGRAF and the baselines on every test item (resumable and
//!   sharded, one CSV per item), and merging the items into `results.md` / `results.csv`;
//! * [`study`]: the realism-gap and domain-shift studies (data, training, evaluation,
//!   report), resumable and sharded by stage;
//! * [`tuning`]: the baselines' settings chosen on a validation set (`baselines.toml`);
//! * [`tg195`]: the AAPM TG-195 validation report (runs sim's cases, tables, figures);
//! * [`training`]: the training driver (checkpoints, resume, metrics, loss plot);
//! * [`figures`]: the plots of evaluations, studies, training and validation (PNG, with
//!   titles, axis labels and units).
//!
//! The scores themselves (PSNR, SSIM, RMSE in HU, whole volume and body) are
//! `tomograf_model::metrics::score`.

pub mod classical;
pub mod demo;
pub mod evaluation;
pub mod figures;
pub mod paired;
pub mod peak;
pub mod protocol;
pub mod study;
pub mod tg195;
pub mod tradeoff;
pub mod training;
pub mod tuning;
pub mod validation;
