//! What each speed setting costs in accuracy on the user's own scene (`tomograf
//! tradeoff`; [`ladder`] does the measuring): the table, a CSV, a plot and
//! a recommendation for an error budget.

pub mod ladder;

use crate::figures::{Axes, plot_points};
use crate::peak::MIB;
use anyhow::{Context, Result, bail};
use ladder::{Knob, Ladder, Options};
use std::fmt::Write as _;
use std::path::PathBuf;
use tomograf_scene::{Progress, Scene, prepare};

/// The ladder to measure and where to write the report.
#[derive(Debug, Clone)]
pub struct Tradeoff {
    /// Error budget: the largest acceptable RMS error relative to the reference image's
    /// RMS (0.01 = 1 %).
    pub budget: f64,
    /// Trilinear steps to try, voxels.
    pub steps: Vec<f64>,
    /// Energy-bin counts to try (real physics only).
    pub bins: Vec<usize>,
    /// Fractions of the reference's scatter photons to try (scatter scenes only).
    pub scatter_fractions: Vec<f64>,
    /// Detection cells to try for the scatter's forced detection, mm (scatter scenes only).
    pub scatter_cells: Vec<f64>,
    /// Histories of the reference's scatter Monte Carlo (`None`: see
    /// [`ladder::Options::scatter_reference_photons`]).
    pub scatter_reference_photons: Option<u64>,
    /// Renders per timing (the median is reported).
    pub repeats: usize,
    /// Folder for tradeoff.md, tradeoff.csv and tradeoff.png.
    pub report: PathBuf,
}

/// Renders the scene's first view with the reference setting and each rung of the
/// ladder, and writes `tradeoff.md`, `tradeoff.csv` and `tradeoff.png` into `t.report`
/// (stage "setting" of `progress`); returns the markdown report.
pub fn tradeoff(scene: &Scene, t: &Tradeoff, progress: &dyn Progress) -> Result<String> {
    if !(t.budget.is_finite() && t.budget > 0.0) {
        bail!(
            "--budget {}: give a relative RMS error > 0 (e.g. 0.01 for 1 %)",
            t.budget
        );
    }
    if !scene.mesh.is_empty() {
        bail!("tradeoff measures voxel scenes: the scene's [[mesh]] objects are not supported yet");
    }
    if t.repeats == 0 {
        bail!("--repeats 0: give at least 1 render per timing");
    }
    if let Some(b) = t.bins.iter().find(|&&b| b == 0) {
        bail!("--bins {b}: an energy-bin count must be at least 1");
    }
    if let Some(f) = t
        .scatter_fractions
        .iter()
        .find(|f| !(f.is_finite() && **f > 0.0 && **f <= 1.0))
    {
        bail!(
            "--scatter-fractions {f}: each fraction of the reference's photons must lie in (0, 1]"
        );
    }
    if let Some(x) = t.steps.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
        bail!("--steps {x}: a trilinear step must be > 0 voxels");
    }
    if let Some(c) = t
        .scatter_cells
        .iter()
        .find(|c| !(c.is_finite() && **c > 0.0))
    {
        bail!("--scatter-cells {c}: a cell size must be > 0 mm");
    }
    let options = Options {
        steps: t.steps.clone(),
        bins: t.bins.clone(),
        scatter_fractions: t.scatter_fractions.clone(),
        scatter_cells: t.scatter_cells.clone(),
        scatter_reference_photons: t.scatter_reference_photons,
        repeats: t.repeats,
    };
    // The scene as `project` makes it ready (its volume, views, tracer and physics); the
    // ladder measures its first view.
    let mut prepared = prepare(scene)?;
    for w in &prepared.warnings {
        progress.warn(w);
    }
    prepared.job.views.truncate(1);
    let view = prepared
        .job
        .views
        .first()
        .cloned()
        .context("the scene has no view")?;
    let physics = match &prepared.acquisition {
        None => Physics::IdealDrr,
        Some((acq, _)) if acq.scatter != tomograf_physics::scatter::ScatterModel::None => {
            Physics::Scatter
        }
        Some(_) => Physics::Detector,
    };
    let file_bytes = scene
        .volume
        .path
        .as_deref()
        .filter(|p| p.is_file())
        .and_then(|p| std::fs::metadata(p).ok())
        .map_or(0, |m| u128::from(m.len()));
    let vol = &prepared.volume;
    let peak = peak_bytes(physics, vol.len() as u128, file_bytes);
    let [nx, ny, nz] = vol.dims();
    let what = format!(
        "the trade-off ladder on a {nx}×{ny}×{nz} volume ({}; estimated peak {:.0} MiB)",
        physics.words(),
        peak as f64 / MIB
    );
    crate::peak::check_peak(peak, &what, progress)?;
    let view = &view;
    let mut started = false;
    let ladder = ladder::ladder(&prepared, view, &options, |done, total| {
        if !started {
            progress.start("setting", total as u64, 0);
            started = true;
        }
        progress.set(done as u64);
    });
    progress.finish();
    let ladder = ladder?;
    let combined = ladder::combine(&ladder, t.budget);
    let (img, seconds) = ladder::render(&prepared, view, &combined, options.repeats)?;
    let (rms, max) = ladder::errors(&img, &ladder.reference_image)?;

    std::fs::create_dir_all(&t.report)
        .with_context(|| format!("cannot create {}", t.report.display()))?;
    let md = report(
        &ladder,
        t,
        view,
        &combined,
        seconds,
        rms,
        max,
        prepared.acquisition.is_some(),
    )?;
    write(&t.report.join("tradeoff.md"), &md)?;
    write(&t.report.join("tradeoff.csv"), &csv(&ladder))?;
    plot(&ladder, t.budget, &t.report.join("tradeoff.png"))?;
    progress.note(&format!(
        "wrote tradeoff.md, tradeoff.csv and tradeoff.png to {}",
        t.report.display()
    ));
    Ok(md)
}

/// What the ladder's renders hold beside the volume.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Physics {
    /// The ideal DRR (μ only).
    IdealDrr,
    /// Detector physics: the material composition and its mass thicknesses.
    Detector,
    /// Detector physics with scatter: the scatter medium too.
    Scatter,
}

impl Physics {
    fn words(self) -> &'static str {
        match self {
            Self::IdealDrr => "ideal DRR",
            Self::Detector => "detector physics",
            Self::Scatter => "detector physics and scatter",
        }
    }
}

/// Estimated peak memory of a trade-off (bytes) on a volume of `voxels` read from a file of
/// `file_bytes` (0 for a phantom or a DICOM folder): the larger of reading it, `13 MiB +
/// file_bytes + 4·voxels` (a .nii.gz is held compressed while it is inflated into the
/// volume's buffer), and the ladder's renders beside the f32 volume, `4·voxels + 15 MiB` for
/// the ideal DRR, `+ 43 MiB + 0.9 · 4·voxels` with detector physics, `+ 54 MiB + 1.97 ·
/// 4·voxels` with scatter. Fitted to `/usr/bin/time -v` peaks on CTs of 8.7·10⁶ to
/// 34.9·10⁶ voxels (`scripts/memory_peaks_tradeoff.sh`; docs/reliability.md, "Memory
/// budget").
pub fn peak_bytes(physics: Physics, voxels: u128, file_bytes: u128) -> u128 {
    let volume = 4.0 * voxels as f64;
    let read = 13.0 * MIB + file_bytes as f64 + volume;
    let (base_mib, factor) = match physics {
        Physics::IdealDrr => (15.0, 0.0),
        Physics::Detector => (43.0, 0.9),
        Physics::Scatter => (54.0, 1.97),
    };
    let render = volume + base_mib * MIB + factor * volume;
    read.max(render) as u128
}

fn write(path: &std::path::Path, text: &str) -> Result<()> {
    tomograf_datasets::atomic::write_atomic(path, |w| {
        use std::io::Write;
        w.write_all(text.as_bytes())
    })?;
    Ok(())
}

/// Speed-up against log₁₀ of the rms error, one series per knob, and the budget's line.
fn plot(ladder: &Ladder, budget: f64, path: &std::path::Path) -> Result<()> {
    let mut series: Vec<(&str, Vec<(f64, f64)>)> = Vec::new();
    for k in [
        Knob::Projector,
        Knob::EnergyBins,
        Knob::Scatter,
        Knob::ScatterCells,
        Knob::Blur,
    ] {
        let mut pts: Vec<(f64, f64)> = ladder
            .rungs
            .iter()
            .filter(|r| r.knob == k)
            .map(|r| (r.reference_seconds / r.seconds, r.rms.log10()))
            .collect();
        if !pts.is_empty() {
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            series.push((knob_name(k), pts));
        }
    }
    let xs = series.iter().flat_map(|(_, p)| p.iter().map(|q| q.0));
    let (lo, hi) = xs.fold((1.0f64, 1.0f64), |(a, b), x| (a.min(x), b.max(x)));
    series.push(("budget", vec![(lo, budget.log10()), (hi, budget.log10())]));
    plot_points(
        path,
        &Axes {
            title: "Speed against accuracy (one knob changed from the reference)",
            x: "speed-up over the reference (×)",
            y: "log10 RMS error (relative)",
        },
        &series,
    )
}

fn knob_name(k: Knob) -> &'static str {
    match k {
        Knob::Reference => "reference",
        Knob::Projector => "projector",
        Knob::EnergyBins => "energy bins",
        Knob::Scatter => "scatter",
        Knob::ScatterCells => "scatter cells",
        Knob::Blur => "blur",
    }
}

/// The reference, the primary reference (when there is scatter), then every rung.
fn rows(ladder: &Ladder) -> impl Iterator<Item = &ladder::Rung> {
    std::iter::once(&ladder.reference)
        .chain(&ladder.primary)
        .chain(&ladder.rungs)
}

fn csv(ladder: &Ladder) -> String {
    let mut s = String::from("knob,setting,seconds,speedup,rms_rel,max_rel\n");
    for r in rows(ladder) {
        let _ = writeln!(
            s,
            "{},\"{}\",{:.6},{:.3},{:.6e},{:.6e}",
            knob_name(r.knob),
            r.label,
            r.seconds,
            r.reference_seconds / r.seconds,
            r.rms,
            r.max
        );
    }
    s
}

#[allow(clippy::too_many_arguments)]
fn report(
    ladder: &Ladder,
    t: &Tradeoff,
    view: &tomograf_sim::View,
    combined: &ladder::Setting,
    seconds: f64,
    rms: f64,
    max: f64,
    physics: bool,
) -> Result<String> {
    let mut md = String::new();
    writeln!(
        md,
        "# Speed against accuracy for this scene\n\n\
         One view ({}×{} pixels); {}. Each row changes one setting from the reference \
         (the most accurate); time is the median of {} renders of the view (one with \
         scatter; the per-volume preparation excluded); errors are against the reference in \
         the output quantity: rms = RMS(a − r)/RMS(r), max = max|a − r|/max|r|; the speed-up \
         is against the reference the row is compared with.{}\n",
        view.rows,
        view.cols,
        if physics {
            "real detector physics, noise off in every render (noise is not a setting)"
        } else {
            "ideal DRR"
        },
        t.repeats.max(1),
        if ladder
            .rungs
            .iter()
            .any(|r| matches!(r.knob, Knob::Scatter | Knob::ScatterCells))
        {
            " Scatter adds the same image whatever the other settings, so the projector, \
             energy-bin and blur rows are measured without it, against the reference without \
             scatter; the scatter rows against the full reference, whose own Monte Carlo \
             noise their error includes."
        } else {
            ""
        }
    )?;
    writeln!(
        md,
        "| knob | setting | ms | speed-up | rms | max |\n|---|---|---:|---:|---:|---:|"
    )?;
    for r in rows(ladder) {
        writeln!(
            md,
            "| {} | {} | {:.1} | {:.2}× | {:.2e} | {:.2e} |",
            knob_name(r.knob),
            r.label,
            r.seconds * 1e3,
            r.reference_seconds / r.seconds,
            r.rms,
            r.max
        )?;
    }
    let verdict = if rms <= t.budget {
        "within the budget"
    } else {
        "over the budget: the knobs' errors do not add independently here; use the reference's setting for the knob with the largest error above"
    };
    writeln!(
        md,
        "\n**For an error budget of {} (rms):** {} — measured {:.1} ms ({:.2}× the \
         reference), rms {:.2e}, max {:.2e}: {verdict}.",
        t.budget,
        ladder::describe(combined, physics),
        seconds * 1e3,
        ladder.reference.seconds / seconds,
        rms,
        max
    )?;
    Ok(md)
}
