//! TomoGRAF from Python: `tomograf.reconstruct` (one data-set item with a checkpoint) and
//! `tomograf.evaluate` (a test set scored against the baselines), through the same library
//! functions as `tomograf reconstruct` and `tomograf evaluate` (`tomograf_eval`), so both
//! give the same volumes and scores.

use crate::errors;
use crate::progress::PyProgress;
use crate::volume::PyVolume;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use tomograf_eval::evaluation::{DEFAULT_PCA_NOISE, Evaluation, evaluate as run_evaluation, merge};
use tomograf_eval::protocol::{ItemReconstruction, hu, paper_poses, reconstruct_item, spread_hu};
use tomograf_eval::tuning::BaselineSettings;
use tomograf_model::config::{InferOverrides, Tune};
use tomograf_model::scatter_correction::ScatterCorrection;
use tomograf_sim::geometry::angles::parse_pose;

fn overrides(
    tune: Option<&str>,
    iterations: Option<usize>,
    psnr_threshold: Option<f64>,
    refine: Option<usize>,
) -> PyResult<InferOverrides> {
    Ok(InferOverrides {
        tune: tune
            .map(str::parse::<Tune>)
            .transpose()
            .map_err(|e| errors::value(format!("tune: {e}")))?,
        iterations,
        psnr_threshold,
        refine_iterations: refine,
        refine_tv_step: None,
    })
}

fn correction(name: &str) -> PyResult<ScatterCorrection> {
    name.parse()
        .map_err(|e| errors::value(format!("scatter_correction: {e}")))
}

/// Reconstructs a CT from 1–10 projections of a data-set item (a folder made by
/// `tomograf dataset` or :func:`make_item`) with a checkpoint written by `tomograf train`,
/// as `tomograf reconstruct` does.
///
/// ``views`` picks the paper's view sets (1 = AP, 2 = AP + lateral, 5 = every 72°, 10 =
/// every 36°); ``poses`` (e.g. ``["ap", "lateral"]`` or ``["0", "45,10"]``, θ or θ,φ in
/// degrees) picks views by pose instead. ``iterations``, ``psnr_threshold`` (dB),
/// ``refine`` and ``tune`` (``"codes-and-generator"`` or ``"codes"``) override the
/// checkpoint's inference settings; ``scatter_correction`` is ``"none"``, ``"prior"`` or
/// ``"oracle"``. ``progress(stage, done, total, message)`` is called per iteration.
///
/// Returns a dict: ``volume`` (a :class:`Volume` in HU on the item's CT grid), ``spread``
/// (where a checkpoint averages several fits for this view count: each voxel's standard
/// deviation across them, a :class:`Volume` in HU; else ``None``), ``iterations``,
/// ``psnr_db`` (per input view, of the rendered rays), ``blend`` (where the checkpoint blended
/// SART-TV from the mean in: a dict with its ``weight`` W and ``views_psnr_db``, the views'
/// mean projection PSNR before the blend that chose W; else ``None``) and ``notes`` (the lines
/// the command line prints).
#[pyfunction]
#[pyo3(signature = (item, checkpoint, *, views=1, poses=None, iterations=None,
    psnr_threshold=None, refine=None, tune=None, seed=0, backend=None,
    scatter_correction="none", progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn reconstruct<'py>(
    py: Python<'py>,
    item: PathBuf,
    checkpoint: PathBuf,
    views: usize,
    poses: Option<Vec<String>>,
    iterations: Option<usize>,
    psnr_threshold: Option<f64>,
    refine: Option<usize>,
    tune: Option<&str>,
    seed: u64,
    backend: Option<String>,
    scatter_correction: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let poses = match poses {
        Some(p) => p
            .iter()
            .map(|t| parse_pose(t).map_err(errors::sim))
            .collect::<PyResult<Vec<_>>>()?,
        None => paper_poses(views).map_err(|e| errors::value(format!("{e:#}")))?,
    };
    let job = ItemReconstruction {
        item: &item,
        checkpoint: &checkpoint,
        poses,
        infer: overrides(tune, iterations, psnr_threshold, refine)?,
        seed,
        backend: backend.as_deref(),
        scatter_correction: correction(scatter_correction)?,
    };
    let reporter = PyProgress::new(progress);
    let done = py.detach(|| -> anyhow::Result<_> {
        let (item, rec) = reconstruct_item(&job, &reporter)?;
        let spread = rec
            .spread
            .as_ref()
            .map(|s| spread_hu(&item, s))
            .transpose()?;
        Ok((
            hu(&item, &rec.volume)?,
            spread,
            rec.iterations,
            rec.psnr,
            rec.blend,
        ))
    });
    let notes = reporter.finish(py)?;
    let (volume, spread, iterations, psnr, blend) =
        done.map_err(|e| errors::value(format!("{e:#}")))?;
    let d = PyDict::new(py);
    d.set_item("volume", Py::new(py, PyVolume::wrap(volume))?)?;
    match spread {
        Some(s) => d.set_item("spread", Py::new(py, PyVolume::wrap(s))?)?,
        None => d.set_item("spread", py.None())?,
    }
    d.set_item("iterations", iterations)?;
    d.set_item("psnr_db", psnr)?;
    match blend {
        Some(b) => {
            let bd = PyDict::new(py);
            bd.set_item("weight", b.weight)?;
            bd.set_item("views_psnr_db", b.views_psnr_db)?;
            d.set_item("blend", bd)?;
        }
        None => d.set_item("blend", py.None())?,
    }
    d.set_item("notes", notes)?;
    Ok(d)
}

/// Scores TomoGRAF (with ``checkpoint``) and the baselines — the mean training volume,
/// PCA-MAP (with ``train_data``), FDK and SART-TV (``classical``) — on a test data set
/// (``views`` multiple of 10 when it was made), per item and view count, as `tomograf
/// evaluate` does: results, per-item CSVs, figures and the first item's reconstruction go
/// to ``output``; items already scored there are skipped (resumable). ``baselines``: a
/// ``baselines.toml`` of `tomograf tune-baselines` (settings chosen on validation).
/// ``all_figures``: figures and the reconstruction for every item, not only the first.
///
/// Returns a dict: ``markdown`` (the results table `tomograf evaluate` prints),
/// ``notes`` (the other lines it prints) and ``rows``, one dict per item, view count and
/// method (``item``, ``views``, ``method``,
/// ``psnr_db``, ``ssim``, ``rmse_hu``, ``body_psnr_db``, ``body_ssim``, ``body_rmse_hu``,
/// ``iterations``, ``seconds``).
#[pyfunction]
#[pyo3(signature = (data, output, *, checkpoint=None, views=vec![1, 2, 5, 10],
    train_data=None, split=None, items=None, classical=true, iterations=None,
    psnr_threshold=None, refine=None, tune=None, seed=0, backend=None,
    scatter_correction="none", pca_noise=DEFAULT_PCA_NOISE, baselines=None, progress=None,
    all_figures=false))]
#[allow(clippy::too_many_arguments)]
pub fn evaluate<'py>(
    py: Python<'py>,
    data: PathBuf,
    output: PathBuf,
    checkpoint: Option<PathBuf>,
    views: Vec<usize>,
    train_data: Option<PathBuf>,
    split: Option<String>,
    items: Option<usize>,
    classical: bool,
    iterations: Option<usize>,
    psnr_threshold: Option<f64>,
    refine: Option<usize>,
    tune: Option<&str>,
    seed: u64,
    backend: Option<String>,
    scatter_correction: &str,
    pca_noise: f64,
    baselines: Option<PathBuf>,
    progress: Option<Py<PyAny>>,
    all_figures: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let infer = overrides(tune, iterations, psnr_threshold, refine)?;
    let baselines = baselines
        .as_deref()
        .map(BaselineSettings::read)
        .transpose()
        .map_err(|e| errors::value(format!("{e:#}")))?;
    let scatter_correction = correction(scatter_correction)?;
    let reporter = PyProgress::new(progress);
    let done = py.detach(|| -> anyhow::Result<_> {
        run_evaluation(&Evaluation {
            data: &data,
            checkpoint: checkpoint.as_deref(),
            train_data: train_data.as_deref(),
            output: &output,
            views: &views,
            split: split.as_deref(),
            items,
            infer,
            seed,
            backend: backend.as_deref(),
            shard: (0, 1),
            pca_noise,
            baselines: baselines.as_ref(),
            classical,
            scatter_correction,
            scatter_prior_data: None,
            progress: &reporter,
            all_figures,
            replace: false,
        })?;
        merge(&output, false)
    });
    let notes = reporter.finish(py)?;
    let (markdown, rows) = done.map_err(|e| errors::value(format!("{e:#}")))?;
    let d = PyDict::new(py);
    d.set_item("markdown", markdown)?;
    d.set_item("notes", notes)?;
    let list = rows
        .iter()
        .map(|r| {
            let row = PyDict::new(py);
            row.set_item("item", &r.item)?;
            row.set_item("views", r.views)?;
            row.set_item("method", &r.method)?;
            row.set_item("psnr_db", r.scores.psnr)?;
            row.set_item("ssim", r.scores.ssim)?;
            row.set_item("rmse_hu", r.scores.rmse_hu)?;
            row.set_item("body_psnr_db", r.scores.body_psnr)?;
            row.set_item("body_ssim", r.scores.body_ssim)?;
            row.set_item("body_rmse_hu", r.scores.body_rmse_hu)?;
            row.set_item("iterations", r.iterations)?;
            row.set_item("seconds", r.seconds)?;
            Ok(row)
        })
        .collect::<PyResult<Vec<_>>>()?;
    d.set_item("rows", list)?;
    Ok(d)
}
