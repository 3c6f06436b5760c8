//! `tomograf bench --scatter CT`: the scatter engine's speed against its error on a real CT
//! (docs/scatter.md, "Scatter at data-set speed").
//!
//! One view (the AP view of a 72-view orbit unless `view` says another, 256² pixels, preset `kv-flat-panel-120kvp`,
//! noise off) is scattered under a ladder of settings: the full-resolution Monte Carlo as
//! the engine had it (the baseline of the speed ratios), the same with forced detection
//! traced through coarse cells ([`tomograf_physics::scatter::detection_grid`]), and the fast
//! estimate. Each is compared with a converged full-resolution Monte Carlo (the reference,
//! `reference_photons` histories; cached in a file when asked, as it takes minutes):
//! * `line-integral rms` = RMS(a − r)/RMS(r) of −ln((primary + scatter)/open field), the
//!   preset's output, which `tomograf tradeoff` measures too (what the image a data set
//!   stores is off by), here before the detector's blur, gain and quantisation;
//! * `scatter rms` the same of the scatter image alone.
//!
//! Both include the reference's own noise. The reference is made as two halves with their own
//! random streams; half the RMS of their difference is the noise of their mean (the
//! reference), and the squared error less that noise's square estimates the error against
//! the converged answer (the candidate's and the reference's noise are independent, so their
//! squares add): the `converged` columns. Times are wall seconds of the scatter alone on
//! all threads (the primary, the same for every row, is given once), median of `rounds`
//! runs taken in turn (A, B, C, A, B, C), after the per-CT set-up, which is timed on its
//! own. Then the orbit: every view of the 72 with the chosen settings, from a fresh engine,
//! the set-up included, and the time per view.

use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;
use tomograf_datasets::image::{read_npy, write_npy};
use tomograf_physics::acquisition::Acquisition;
use tomograf_physics::scatter::orbit::{angle_on_orbit, combine, neighbours};
use tomograf_physics::scatter::{ScatterEngine, ScatterImages, ScatterModel};
use tomograf_scene::Scene;
use tomograf_scene::job::resolve;
use tomograf_scene::physics::acquisition;
use tomograf_scene::volume::load_hu;
use tomograf_sim::{Projector, View, Volume};

/// What to measure.
#[derive(Debug, Clone)]
pub struct ScatterOptions {
    /// Small sizes only (64² pixels, 4 views, few photons): a smoke test.
    pub quick: bool,
    /// Runs of each setting, taken in turn (median).
    pub rounds: usize,
    /// Histories of the full-resolution reference (≥ 4·10⁵ for a converged one).
    pub reference_photons: u64,
    /// The view scored (0: AP; 18: the lateral of the 72).
    pub view: usize,
    /// The orbit's rows only (the per-view ladder skipped).
    pub orbit_only: bool,
    /// The per-view ladder only (the orbits skipped).
    pub ladder_only: bool,
    /// Reads the reference scatter image from here when it was made with the same CT,
    /// photons and view; writes it here otherwise.
    pub reference_cache: Option<std::path::PathBuf>,
}

/// The angular windows (degrees each side) the orbit's Monte Carlo rows are fitted over.
const WINDOWS_DEG: [f64; 7] = [0.0, 15.0, 20.0, 25.0, 30.0, 35.0, 45.0];

/// The rungs' seed (every rung draws the same histories, so a rung with detection cells
/// differs from the same rung at full resolution by the cells' bias alone).
const SEED: u64 = 0x5ca7;
/// The reference's halves' seeds (this and the next).
const REFERENCE_SEED: u64 = 0x7e7e_7e7e;

/// One rung of the ladder.
struct Rung {
    label: String,
    model: ScatterModel,
}

fn mc(photons: u64, cell: f64) -> ScatterModel {
    mc_multiple(photons, cell, 0)
}

/// The Monte Carlo with the multiple-scatter image on `multiple` points per side (0: 16).
fn mc_multiple(photons: u64, cell: f64, multiple: usize) -> ScatterModel {
    ScatterModel::MonteCarlo {
        photons,
        grid: 16,
        multiple_grid: multiple,
        max_order: 50,
        detection_cell_mm: cell,
        angular_window_deg: 0.0,
        split: 1,
        sparse_multiple: false,
        sampler: Default::default(),
        cell_check: 0,
    }
}

/// [`mc_multiple`] with every history split into `split` branches at its first collision.
fn mc_split(photons: u64, cell: f64, multiple: usize, split: u32) -> ScatterModel {
    let mut m = mc_multiple(photons, cell, multiple);
    if let ScatterModel::MonteCarlo { split: s, .. } = &mut m {
        *s = split;
    }
    m
}

fn estimate(photons: u64, grid: usize, cell: f64) -> ScatterModel {
    estimate_multiple(photons, grid, cell, 0)
}

fn estimate_multiple(photons: u64, grid: usize, cell: f64, multiple: usize) -> ScatterModel {
    ScatterModel::Estimate {
        photons,
        grid,
        multiple_grid: multiple,
        smoothing: 1.0,
        detection_cell_mm: cell,
    }
}

fn label(m: &ScatterModel) -> String {
    let cell = |c: f64| {
        if c == 0.0 {
            "full resolution".to_string()
        } else {
            format!("{c} mm cells")
        }
    };
    let points = |g: usize, m: usize| {
        if m == 0 || m == g {
            format!("{g}² points")
        } else {
            format!("{g}² points ({m}² for multiple scatter)")
        }
    };
    match m {
        ScatterModel::MonteCarlo {
            photons,
            grid,
            multiple_grid,
            detection_cell_mm,
            split,
            ..
        } => format!(
            "Monte Carlo, {photons} histories{}, {}, {}",
            if *split > 1 {
                format!(" split ×{split} at the first collision")
            } else {
                String::new()
            },
            points(*grid, *multiple_grid),
            cell(*detection_cell_mm)
        ),
        ScatterModel::Estimate {
            photons,
            grid,
            multiple_grid,
            detection_cell_mm,
            ..
        } => format!(
            "estimate, {photons} histories, {}, {}",
            points(*grid, *multiple_grid),
            cell(*detection_cell_mm)
        ),
        ScatterModel::None => "none".into(),
    }
}

/// Channel 0 of the total scatter of `view` under `model`, and the wall seconds it took.
fn scatter(
    engine: &ScatterEngine,
    model: &ScatterModel,
    view: &View,
    seed: u64,
) -> Result<(Vec<f64>, f64)> {
    let t = Instant::now();
    let s = engine
        .run(model, view, seed)?
        .context("the model scatters nothing")?;
    let secs = t.elapsed().as_secs_f64();
    let total = s.total();
    Ok((total.mean[..total.rows * total.cols].to_vec(), secs))
}

/// RMS(a − r)/RMS(r).
fn rms(a: &[f64], r: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(r).map(|(x, y)| (x - y) * (x - y)).sum();
    let n: f64 = r.iter().map(|y| y * y).sum();
    (d / n).sqrt()
}

/// The bench's scene: the CT, the preset, a 256² panel, 72 views every 5° (quick: 64², 4 views).
pub fn scene(ct: &Path, quick: bool) -> Result<Scene> {
    let (px, arc) = if quick {
        (64, "0:90:4")
    } else {
        (256, "0:5:72")
    };
    let text = format!(
        "[volume]\npath = {:?}\n[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n\
         [detector]\nrows = {px}\ncols = {px}\npitch_mm = [{p}, {p}]\n[views]\narc = \"{arc}\"\n",
        ct.display().to_string(),
        p = 430.0 / px as f64,
    );
    Ok(toml::from_str(&text)?)
}

/// The reference's two halves, as cached: a `[2, rows, cols]` array.
fn load_reference(cache: &Path, key: &str, n: usize) -> Option<[Vec<f64>; 2]> {
    let stored = std::fs::read_to_string(cache.with_extension("txt")).ok()?;
    if stored.trim() != key {
        return None;
    }
    let (data, _) = read_npy(cache).ok()?;
    if data.len() != 2 * n {
        return None;
    }
    let half = |k: usize| {
        data[k * n..(k + 1) * n]
            .iter()
            .map(|&v| f64::from(v))
            .collect()
    };
    Some([half(0), half(1)])
}

/// The reference's own noise, relative: RMS((A − B)/2)/RMS(reference) of its halves A and
/// B, each under `f` (the identity, or the line integrals).
fn reference_noise(halves: &[Vec<f64>; 2], f: impl Fn(&[f64]) -> Vec<f64>) -> f64 {
    let (a, b) = (f(&halves[0]), f(&halves[1]));
    let d: f64 = a.iter().zip(&b).map(|(x, y)| (x - y) * (x - y)).sum();
    let m: f64 = a.iter().zip(&b).map(|(x, y)| (x + y) * (x + y)).sum();
    (d / m).sqrt()
}

/// The error against the converged answer: each round's relative error `errors` with the
/// reference's noise `noise` removed in quadrature (0 where the noise exceeds it), the mean
/// over the rounds (as the plain columns are).
fn converged(errors: impl Iterator<Item = f64>, noise: f64) -> f64 {
    let (mut sum, mut k) = (0.0, 0.0);
    for e in errors {
        sum += (e * e - noise * noise).max(0.0).sqrt();
        k += 1.0;
    }
    sum / k
}

/// The markdown section.
pub fn section(ct: &Path, o: &ScatterOptions) -> Result<String> {
    if o.reference_photons == 0 {
        bail!("--reference-photons 0: give the reference's histories (≥ 400000 to converge)");
    }
    let scene = scene(ct, o.quick)?;
    let (mut acq, seed) = acquisition(&scene)?.context("the scene has no physics")?;
    acq.detector.quantum_noise = false;
    acq.detector.readout.electronic_noise_adu = 0.0;
    let (hu, _) = load_hu(&scene, acq.materials.calibration_kev)?;
    let job = resolve(&scene, &hu)?;
    let views = job.views;
    let at = o.view;
    if at >= views.len() {
        bail!("--view {at}: the orbit has views 0 to {}", views.len() - 1);
    }
    let view = &views[at];
    let n = view.rows * view.cols;

    let mut md = String::new();
    let t = Instant::now();
    let (prepared, engine) = prepare(&acq, &hu, seed)?;
    let setup = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let primary = prepared.primary(Projector::Siddon, view)?.mean[..n].to_vec();
    let primary_s = t.elapsed().as_secs_f64();
    let open = prepared.integrator().open(view, acq.spectrum.mas)?.mean[..n].to_vec();
    // −ln((primary + scatter)/open): the preset's output.
    let line_integrals = |scatter: &[f64]| -> Vec<f64> {
        primary
            .iter()
            .zip(scatter)
            .zip(&open)
            .map(|((p, s), o)| -((p + s) / o).ln())
            .collect()
    };

    // The CT by its contents, not its path: a file moved keeps its reference, another file
    // at the same path does not.
    let key = format!(
        "ct-sha256={} photons={} halves=2 rows={} cols={} view={at}",
        tomograf_scene::dataset::sha256_of(ct)?,
        o.reference_photons,
        view.rows,
        view.cols
    );
    let (halves, ref_s) = match o
        .reference_cache
        .as_deref()
        .and_then(|c| load_reference(c, &key, n))
    {
        Some(r) => (r, None),
        None => {
            // Its own random streams: the rungs' histories are not a part of it.
            let half = mc(o.reference_photons.div_ceil(2), 0.0);
            let (a, sa) = scatter(&engine, &half, view, REFERENCE_SEED)?;
            let (b, sb) = scatter(&engine, &half, view, REFERENCE_SEED + 1)?;
            if let Some(c) = &o.reference_cache {
                let f: Vec<f32> = a.iter().chain(&b).map(|&v| v as f32).collect();
                write_npy(c, &f, &[2, view.rows, view.cols])?;
                std::fs::write(c.with_extension("txt"), &key)?;
            }
            ([a, b], Some(sa + sb))
        }
    };
    let reference: Vec<f64> = halves[0]
        .iter()
        .zip(&halves[1])
        .map(|(a, b)| 0.5 * (a + b))
        .collect();
    let noise_s = reference_noise(&halves, |s| s.to_vec());
    let noise_li = reference_noise(&halves, |s| line_integrals(s));
    let ref_li = line_integrals(&reference);
    let spr = reference.iter().sum::<f64>() / primary.iter().sum::<f64>();

    let q = |full: u64| if o.quick { (full / 20).max(64) } else { full };
    let rungs: Vec<Rung> = [
        mc(q(6_250), 0.0),
        mc(q(6_250), 4.0),
        mc(q(6_250), 8.0),
        mc(q(6_250), 16.0),
        mc(q(10_000), 8.0),
        mc_multiple(q(10_000), 8.0, 12),
        mc_multiple(q(12_500), 8.0, 12),
        mc(q(1_500), 8.0),
        mc(q(1_500), 16.0),
        mc_multiple(q(6_250), 8.0, 8),
        mc_multiple(q(14_000), 8.0, 8),
        mc_multiple(q(25_000), 8.0, 8),
        mc_multiple(q(3_500), 8.0, 8),
        mc_multiple(q(2_000), 8.0, 8),
        mc_multiple(q(1_500), 8.0, 8),
        mc_split(q(3_000), 8.0, 8, 2),
        mc_split(q(6_000), 8.0, 8, 2),
        mc_split(q(10_000), 8.0, 8, 2),
        mc_split(q(14_000), 8.0, 8, 2),
        mc_split(q(5_000), 8.0, 8, 4),
        mc_split(q(8_000), 8.0, 8, 4),
        estimate(q(5_000), 8, 0.0),
        estimate(q(5_000), 8, 8.0),
        estimate(q(2_000), 8, 8.0),
        estimate(q(2_000), 16, 8.0),
        estimate(q(1_000), 16, 8.0),
        estimate_multiple(q(2_000), 8, 8.0, 4),
        estimate_multiple(q(4_000), 8, 8.0, 4),
        estimate_multiple(q(2_000), 16, 8.0, 8),
    ]
    .into_iter()
    .filter(|_| !o.orbit_only)
    .map(|model| Rung {
        label: label(&model),
        model,
    })
    .collect();
    // Detection grids are made once per CT: make them before timing, and time that alone.
    let mut grid_s = Vec::new();
    for cell in [4.0, 8.0, 16.0] {
        let t = Instant::now();
        let g = engine.detection_grid(cell)?.context("a cell size > 0")?;
        grid_s.push((cell, g.dims(), t.elapsed().as_secs_f64()));
    }
    let mut times = vec![Vec::new(); rungs.len()];
    let mut images = vec![Vec::new(); rungs.len()];
    // Errors of each round's image (line integrals, scatter): a round draws its own
    // histories (seed SEED + round), so the rounds sample the error's spread as well.
    let mut errors = vec![Vec::new(); rungs.len()];
    for round in 0..o.rounds.max(1) {
        for (i, r) in rungs.iter().enumerate() {
            let (img, s) = scatter(&engine, &r.model, view, SEED + round as u64)?;
            times[i].push(s);
            errors[i].push((rms(&line_integrals(&img), &ref_li), rms(&img, &reference)));
            images[i] = img;
        }
    }
    let median = |t: &mut Vec<f64>| {
        t.sort_by(f64::total_cmp);
        t[t.len() / 2]
    };
    let base = times.first().map_or(1.0, |t| median(&mut t.clone()));

    writeln!(
        md,
        "CT `{}` ({}×{}×{} voxels of {:.2}×{:.2}×{:.2} mm), view {at}{} of {} ({}×{} pixels), \
         preset `kv-flat-panel-120kvp`, noise off, {} threads, {}. Whole-panel scatter-to-primary \
         ratio {spr:.3}.\n",
        ct.display(),
        hu.dims()[0],
        hu.dims()[1],
        hu.dims()[2],
        hu.spacing().x,
        hu.spacing().y,
        hu.spacing().z,
        if at == 0 { " (AP)" } else { "" },
        views.len(),
        view.rows,
        view.cols,
        rayon::current_num_threads(),
        crate::cpu_model()
    )?;
    writeln!(
        md,
        "Per-CT set-up (materials, tables, majorants) {setup:.2} s; the primary {primary_s:.3} s; \
         detection grids {}. Reference: full-resolution Monte Carlo, {} histories, 16² points{}, \
         in two halves of their own histories; its own noise (half the RMS of the halves' \
         difference, relative) {:.2} % of the line integrals, {:.2} % of the scatter.\n",
        grid_s
            .iter()
            .map(|(c, d, s)| format!("{c} mm → {}×{}×{} cells in {s:.2} s", d[0], d[1], d[2]))
            .collect::<Vec<_>>()
            .join(", "),
        o.reference_photons,
        match ref_s {
            Some(s) => format!(" ({s:.0} s)"),
            None => " (read from the cache)".into(),
        },
        100.0 * noise_li,
        100.0 * noise_s,
    )?;
    if !rungs.is_empty() {
        writeln!(
            md,
            "| setting | scatter s | × vs first row | line-integral rms | scatter rms (worst of {}) | \
             converged: line-integral rms | converged: scatter rms | cells' bias |\n\
             |---|---:|---:|---:|---:|---:|---:|---:|",
            o.rounds.max(1)
        )?;
        for (i, r) in rungs.iter().enumerate() {
            let s = median(&mut times[i]);
            // The same rung at full resolution (same histories): the difference is the cells'.
            let at_full = r.model.clone().with_detection_cell_mm(0.0);
            let full = rungs
                .iter()
                .position(|f| f.model == at_full && f.model != r.model);
            let n = errors[i].len() as f64;
            let mean_li = errors[i].iter().map(|e| e.0).sum::<f64>() / n;
            let mean_s = errors[i].iter().map(|e| e.1).sum::<f64>() / n;
            let worst_s = errors[i].iter().map(|e| e.1).fold(0.0, f64::max);
            writeln!(
                md,
                "| {} | {s:.2} | {:.1}× | {:.2} % | {:.2} % ({:.2} %) | {:.2} % | {:.2} % | {} |",
                r.label,
                base / s,
                100.0 * mean_li,
                100.0 * mean_s,
                100.0 * worst_s,
                100.0 * converged(errors[i].iter().map(|e| e.0), noise_li),
                100.0 * converged(errors[i].iter().map(|e| e.1), noise_s),
                full.map_or("".into(), |f| format!(
                    "{:.2} %",
                    100.0 * rms(&images[i], &images[f])
                )),
            )?;
        }
        writeln!(
            md,
            "\n`line-integral rms`: of −ln((primary + scatter)/open field), the preset's output, \
             against the reference's (what `tomograf tradeoff` measures, but before the detector's \
             blur, gain and quantisation); `scatter rms`: of the scatter image alone; both the mean \
             over the rounds, each round its own histories (the worst round in brackets), and both \
             include the reference's own noise. `converged`: each round's error with the \
             reference's noise removed in quadrature (the error against the converged answer), the mean over the rounds. `cells' bias`: the scatter image against the same histories traced at full \
             resolution (no noise in it: the histories are the same)."
        )?;
    }

    // The orbit, from a fresh engine each round: set-up and detection grid included, each
    // round its own histories. The view's scatter is then also fitted in angle with its
    // neighbours' (physics::scatter::orbit) over each window of WINDOWS_DEG. The settings
    // are taken in turn within each round (A, B, C, A, B, C), so that their times share the
    // machine's load; 900 histories is the data-set setting of ≤ 0.5 s per view; the
    // 3500-history orbit also with the engine's analog sampling (its
    // sampling before 2026-12-01), the ablation of the strata and the forced first collision;
    // 900, 1500 and 2200 histories split ×2 at the first collision (8² multiple-scatter
    // points; 2200 the most that fitted in 1 s per view once forced detection's walk through
    // the cells was unrolled, 2026-12-01).
    let widest = WINDOWS_DEG.iter().fold(0.0f64, |a, &b| a.max(b));
    let orbits: Vec<(ScatterModel, bool)> = [
        (mc(q(900), 8.0), false),
        (mc(q(1_500), 8.0), false),
        (mc_multiple(q(3_500), 8.0, 8), false),
        (mc_multiple(q(3_500), 8.0, 8), true),
        (ScatterModel::estimate_default(), false),
        (mc_split(q(900), 8.0, 8, 2), false),
        (mc_split(q(1_500), 8.0, 8, 2), false),
        (mc_split(q(2_200), 8.0, 8, 2), false),
    ]
    .into_iter()
    .filter(|_| !o.ladder_only)
    .collect();
    let windows_of = |model: &ScatterModel| -> &[f64] {
        if matches!(model, ScatterModel::MonteCarlo { .. }) {
            &WINDOWS_DEG
        } else {
            &[0.0]
        }
    };
    let mut secs = vec![Vec::new(); orbits.len()];
    let mut errs: Vec<Vec<Vec<(f64, f64)>>> = orbits
        .iter()
        .map(|(m, _)| vec![Vec::new(); windows_of(m).len()])
        .collect();
    for round in 0..o.rounds.max(1) {
        for (i, (model, analog)) in orbits.iter().enumerate() {
            let t = Instant::now();
            let (_, engine) = prepare(&acq, &hu, seed)?;
            let engine = engine.with_analog_sampling(*analog);
            let mut kept = Vec::new();
            for (k, v) in views.iter().enumerate() {
                let s = engine
                    .run(model, v, SEED + (round * 100_000 + k) as u64)?
                    .context("the model scatters nothing")?;
                let near = k == at
                    || angle_on_orbit(&views[at], v).is_some_and(|a| a.abs() <= widest + 1e-9);
                if near {
                    kept.push((k, s));
                }
            }
            secs[i].push(t.elapsed().as_secs_f64());
            for (w, errs) in windows_of(model).iter().zip(errs[i].iter_mut()) {
                let parts: Vec<(f64, &ScatterImages)> = neighbours(&views, at, *w)
                    .into_iter()
                    .filter_map(|(j, wt)| kept.iter().find(|(k, _)| *k == j).map(|(_, s)| (wt, s)))
                    .collect();
                let img = combine(&parts).total().mean[..n].to_vec();
                errs.push((rms(&line_integrals(&img), &ref_li), rms(&img, &reference)));
            }
        }
    }
    for (i, (model, analog)) in orbits.iter().enumerate() {
        let s = median(&mut secs[i]);
        writeln!(
            md,
            "\nOrbit of {} views, {}{}: {s:.1} s with the set-up (median of {}), **{:.2} s per \
             view**. View {at} against the reference, each view alone and fitted in angle with its \
             neighbours (`angular_window_deg`), mean of the rounds (the worst in brackets):\n\n\
             | angular window | views in the fit | line-integral rms | scatter rms | converged: line-integral rms | converged: scatter rms |\n|---:|---:|---:|---:|---:|---:|",
            views.len(),
            label(model),
            if *analog {
                ", analog sampling (the engine before 2026-12-01)"
            } else {
                ""
            },
            secs[i].len(),
            s / views.len() as f64,
        )?;
        for (w, e) in windows_of(model).iter().zip(&errs[i]) {
            let k = e.len() as f64;
            writeln!(
                md,
                "| {} | {} | {:.2} % ({:.2} %) | {:.2} % ({:.2} %) | {:.2} % | {:.2} % |",
                if *w == 0.0 {
                    "none".to_string()
                } else {
                    format!("±{w}°")
                },
                neighbours(&views, at, *w).len(),
                100.0 * e.iter().map(|x| x.0).sum::<f64>() / k,
                100.0 * e.iter().map(|x| x.0).fold(0.0, f64::max),
                100.0 * e.iter().map(|x| x.1).sum::<f64>() / k,
                100.0 * e.iter().map(|x| x.1).fold(0.0, f64::max),
                100.0 * converged(e.iter().map(|x| x.0), noise_li),
                100.0 * converged(e.iter().map(|x| x.1), noise_s),
            )?;
        }
    }
    Ok(md)
}

fn prepare(
    acq: &Acquisition,
    hu: &Volume,
    seed: u64,
) -> Result<(tomograf_physics::acquisition::Prepared, ScatterEngine)> {
    let mut a = acq.clone();
    a.scatter = mc(1, 0.0);
    let p = a.prepare(hu, seed)?;
    let engine = p.scatter_engine().context("scatter is modelled")?.clone();
    Ok((p, engine))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Halves that differ by ±d about a mean m: the mean's noise is d/m, exactly.
    #[test]
    fn the_reference_noise_is_half_its_halves_difference() {
        let a = vec![1.1, 2.2, 3.3];
        let b = vec![0.9, 1.8, 2.7];
        assert!((reference_noise(&[a, b], |s| s.to_vec()) - 0.1).abs() < 1e-12);
    }

    /// Errors of 5 % and 13 % with a reference noise of 3 %: 4 % and 12.65 % against the
    /// converged answer, their mean; a noise above the error gives 0, not a NaN.
    #[test]
    fn the_converged_error_removes_the_reference_noise_in_quadrature() {
        let expected = 0.5 * (0.04 + (0.13f64 * 0.13 - 0.03 * 0.03).sqrt());
        assert!((converged([0.05, 0.13].into_iter(), 0.03) - expected).abs() < 1e-12);
        assert_eq!(converged([0.01].into_iter(), 0.03), 0.0);
    }
}
