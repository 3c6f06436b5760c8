//! `tomograf evaluate`: reconstruct every test item from 1/2/5/10 views and compare with
//! the ground truth — PSNR, 3D SSIM and RMSE in HU, mean ± std per view count, next to the
//! baselines from the same views — as a markdown table, a CSV and PNG figures.

use crate::reconstruct::{paper_poses, references, run_one, write_hu};
use anyhow::{Context, Result, bail};
use clap::Args;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tomograf_model::baseline::Baseline;
use tomograf_model::config::Tune;
use tomograf_model::data::Item;
use tomograf_model::metrics::{mean_std, psnr, rmse, ssim3d};
use tomograf_model::{backend, checkpoint, data};
use tomograf_sim::{Projection, Volume};

#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// Test data set folder (made by `tomograf dataset`, with --views a multiple of 10).
    pub data: PathBuf,
    /// Checkpoint folder written by `tomograf train`.
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Output folder: results.md, results.csv, figures, reconstructions.
    #[arg(short, long)]
    pub output: PathBuf,
    /// View counts to evaluate.
    #[arg(long, value_delimiter = ',', default_value = "1,2,5,10")]
    pub views: Vec<usize>,
    /// Use only the items of this split.
    #[arg(long)]
    pub split: Option<String>,
    /// At most this many items.
    #[arg(long)]
    pub items: Option<usize>,
    /// Override the checkpoint's inference iteration cap.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// What to fine-tune: codes-and-generator (default) or codes.
    #[arg(long)]
    pub tune: Option<Tune>,
    /// Seed of inference.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Backend: flex (CPU, default), ndarray, cuda, wgpu (as compiled in).
    #[arg(long)]
    pub backend: Option<String>,
}

/// Metrics of one reconstruction.
#[derive(Debug, Clone, Copy)]
pub struct Scores {
    pub psnr: f64,
    pub ssim: f64,
    pub rmse_hu: f64,
}

pub fn score(item: &Item, volume: &Volume) -> Result<Scores> {
    let gt = item.ct.as_ref().context("item has no ground-truth CT")?;
    let width = f64::from(item.window.hi - item.window.lo);
    // The model's density is unbounded above; the ground truth is clamped to [0, 1].
    let v: Vec<f32> = volume.data().iter().map(|x| x.clamp(0.0, 1.0)).collect();
    Ok(Scores {
        psnr: psnr(&v, gt.data(), 1.0)?,
        ssim: ssim3d(&v, gt.data(), gt.dims(), 1.0)?,
        rmse_hu: rmse(&v, gt.data())? * width,
    })
}

pub fn run(args: EvaluateArgs) -> Result<()> {
    let device = backend::device(args.backend.as_deref().unwrap_or(backend::default_name()))?;
    if args.views.is_empty() || args.views.contains(&0) {
        bail!("view counts must be ≥ 1 (view count 0 given)");
    }
    let mut items = data::load_dataset(&args.data, args.split.as_deref())?;
    if let Some(n) = args.items {
        items.truncate(n.max(1));
    }
    let (config, _, _) = checkpoint::load_generator(&args.checkpoint, &device)?;
    let mut infer = config.infer.clone();
    if let Some(t) = args.tune {
        infer.tune = t;
    }
    if let Some(n) = args.iterations {
        infer.iterations = n;
    }
    let mean = checkpoint::load_mean(&args.checkpoint)?
        .context("the checkpoint has no mean_volume.npy (written by `tomograf train`)")?;
    let baselines: Vec<Box<dyn Baseline>> = vec![
        Box::new(mean),
        Box::new(tomograf_model::baseline::Fdk),
        Box::new(tomograf_model::baseline::SartTv),
    ];
    std::fs::create_dir_all(&args.output)?;
    // (views, method) → scores over items.
    let mut table: Vec<(usize, String, Vec<Scores>)> = Vec::new();
    let mut csv = String::from("item,views,method,psnr_db,ssim,rmse_hu,iterations,seconds\n");
    let mut push = |views: usize, method: &str, s: Scores| match table
        .iter_mut()
        .find(|(v, m, _)| *v == views && m == method)
    {
        Some(e) => e.2.push(s),
        None => table.push((views, method.to_string(), vec![s])),
    };
    let mut secs_per_iter = Vec::new();
    for (n, item) in items.iter().enumerate() {
        for &count in &args.views {
            let poses = paper_poses(count)?;
            let refs = references(item, &poses)?;
            let t0 = Instant::now();
            eprintln!(
                "item {} ({}/{}), {count} view(s)",
                item.id,
                n + 1,
                items.len()
            );
            let rec = run_one(
                &args.checkpoint,
                item,
                &poses,
                Some(&infer),
                args.seed,
                &device,
                true,
            )?;
            let secs = t0.elapsed().as_secs_f64();
            secs_per_iter.push(secs / rec.iterations.max(1) as f64);
            let s = score(item, &rec.volume)?;
            let _ = writeln!(
                csv,
                "{},{count},TomoGRAF,{:.4},{:.5},{:.2},{},{secs:.2}",
                item.id, s.psnr, s.ssim, s.rmse_hu, rec.iterations
            );
            push(count, "TomoGRAF", s);
            let grid = item.ct.as_ref().context("item has no ground-truth CT")?;
            let mut others = Vec::new();
            for b in &baselines {
                let v = b.reconstruct(&refs, grid, &item.scale)?;
                let s = score(item, &v)?;
                let _ = writeln!(
                    csv,
                    "{},{count},{},{:.4},{:.5},{:.2},0,0",
                    item.id,
                    b.name(),
                    s.psnr,
                    s.ssim,
                    s.rmse_hu
                );
                push(count, b.name(), s);
                others.push(v);
            }
            if n == 0 {
                let stem = args.output.join(format!("{}_{count}view", item.id));
                write_hu(item, &rec.volume, &stem.with_extension("nii.gz"))?;
                figures(item, &rec.volume, &others[0], &stem)?;
            }
        }
    }
    std::fs::write(args.output.join("results.csv"), &csv)?;
    let (spi, _) = mean_std(&secs_per_iter);
    let mut md = "| views | method | PSNR (dB) | SSIM | RMSE (HU) |\n|---:|---|---:|---:|---:|\n"
        .to_string();
    for (v, m, s) in &table {
        let f = |g: fn(&Scores) -> f64| mean_std(&s.iter().map(g).collect::<Vec<_>>());
        let (p, ps) = f(|s| s.psnr);
        let (q, qs) = f(|s| s.ssim);
        let (r, rs) = f(|s| s.rmse_hu);
        let _ = writeln!(
            md,
            "| {v} | {m} | {p:.2} ± {ps:.2} | {q:.3} ± {qs:.3} | {r:.1} ± {rs:.1} |"
        );
    }
    let _ = writeln!(
        md,
        "\n{} test item(s); inference: {} iterations cap, PSNR threshold {} dB, tune {:?}, {:.3} s per iteration on average (including loading and the final volume rendering).",
        items.len(),
        infer.iterations,
        infer.psnr_threshold,
        infer.tune,
        spi
    );
    std::fs::write(args.output.join("results.md"), &md)?;
    println!("{md}");
    Ok(())
}

/// Three orthogonal mid-slices (axial, coronal, sagittal) of a volume `n³`, `i` fastest,
/// head up in coronal and sagittal.
fn slices(v: &Volume) -> [Vec<f32>; 3] {
    let [nx, ny, nz] = v.dims();
    let d = v.data();
    let at = |i: usize, j: usize, k: usize| d[i + nx * (j + ny * k)];
    let (mi, mj, mk) = (nx / 2, ny / 2, nz / 2);
    let axial = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| (i, j)))
        .map(|(i, j)| at(i, j, mk))
        .collect();
    let coronal = (0..nz)
        .rev()
        .flat_map(|k| (0..nx).map(move |i| (i, k)))
        .map(|(i, k)| at(i, mj, k))
        .collect();
    let sagittal = (0..nz)
        .rev()
        .flat_map(|k| (0..ny).map(move |j| (j, k)))
        .map(|(j, k)| at(mi, j, k))
        .collect();
    [axial, coronal, sagittal]
}

/// `slices.png` (rows: axial, coronal, sagittal; columns: ground truth, TomoGRAF, mean
/// volume, |TomoGRAF − truth| × 4; normalised units, window [0, 1]) and `profile.png`
/// (the row through the centre of the axial slice).
fn figures(item: &Item, model: &Volume, mean: &Volume, stem: &Path) -> Result<()> {
    let gt = item.ct.as_ref().context("no ground truth")?;
    let [nx, ny, nz] = gt.dims();
    if nx != ny || ny != nz {
        return Ok(());
    }
    let n = nx;
    let residual = Volume::new(
        gt.dims(),
        gt.spacing(),
        gt.origin(),
        gt.direction(),
        model
            .data()
            .iter()
            .zip(gt.data())
            .map(|(a, b)| ((a - b).abs() * 4.0).min(1.0))
            .collect(),
    )?;
    let cols = [gt, model, mean, &residual].map(slices);
    let gap = 2;
    let (w, h) = (4 * n + 3 * gap, 3 * n + 2 * gap);
    let mut img = vec![1.0f32; w * h];
    for (c, s) in cols.iter().enumerate() {
        for (r, tile) in s.iter().enumerate() {
            for y in 0..n {
                for x in 0..n {
                    img[(r * (n + gap) + y) * w + c * (n + gap) + x] =
                        tile[y * n + x].clamp(0.0, 1.0);
                }
            }
        }
    }
    let p = Projection {
        rows: h,
        cols: w,
        data: img,
    };
    tomograf_datasets::image::write_png(
        &PathBuf::from(format!("{}_slices.png", stem.display())),
        &p,
        (0.0, 1.0),
    )?;
    let line = |v: &Volume| -> Vec<(f64, f64)> {
        let s = &slices(v)[0];
        (0..n)
            .map(|i| (i as f64, f64::from(s[(n / 2) * n + i])))
            .collect()
    };
    plot_lines(
        &PathBuf::from(format!("{}_profile.png", stem.display())),
        &[
            ("truth", line(gt)),
            ("TomoGRAF", line(model)),
            ("mean", line(mean)),
        ],
    )
}

/// A line plot of named series (no text: the colours are, in order, blue, red, green,
/// black, magenta); writes a 640×400 PNG.
pub fn plot_lines(path: &Path, series: &[(&str, Vec<(f64, f64)>)]) -> Result<()> {
    let pts = series.iter().flat_map(|(_, s)| s.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        if x.is_finite() && y.is_finite() {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if x0 >= x1 {
        x1 = x0 + 1.0;
    }
    if y0 >= y1 {
        y1 = y0 + 1.0;
    }
    let root = BitMapBackend::new(path, (640, 400)).into_drawing_area();
    root.fill(&WHITE)
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    let colours = [BLUE, RED, GREEN, BLACK, MAGENTA];
    for (n, (_, s)) in series.iter().enumerate() {
        chart
            .draw_series(LineSeries::new(
                s.iter().copied(),
                colours[n % 5].stroke_width(2),
            ))
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    }
    root.present()
        .map_err(|e| anyhow::anyhow!("plot {}: {e}", path.display()))?;
    Ok(())
}
