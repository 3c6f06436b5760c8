//! Projector speed (`tomograf bench`) (rays/s, voxel steps/s) and the trilinear
//! speed/accuracy trade against exact Siddon, written as markdown.
//!
//! Times are medians of repeated renders in this process; voxel steps are counted once
//! with a counting accumulator (not timed).

use anyhow::Result;
use std::fmt::Write as _;
use std::time::Instant;
use tomograf_sim::trace::{PathAccumulator, siddon};
use tomograf_sim::{GridRay, Pose, Projection, Projector, Renderer, View, Volume};

use crate::Options;
use crate::fixtures::{thorax_mu, view};

/// Counts voxels with positive path length.
struct StepCount(u64);
impl PathAccumulator for StepCount {
    fn segment(&mut self, _: usize, len: f64) {
        self.0 += u64::from(len > 0.0);
    }
    fn run(&mut self, _: usize, _: usize, count: usize, _: f64) {
        self.0 += count as u64;
    }
}

fn median_ms(
    repeats: usize,
    mut f: impl FnMut() -> Result<Projection>,
) -> Result<(f64, Projection)> {
    let mut img = f()?; // warm-up
    let mut times = Vec::with_capacity(repeats);
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        img = f()?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    Ok((times[times.len() / 2], img))
}

fn voxel_steps(mu: &Volume, view: &View) -> u64 {
    let mut c = StepCount(0);
    for r in 0..view.rows {
        for col in 0..view.cols {
            if let Some(g) = GridRay::clip(mu, &view.ray(r as f64, col as f64)) {
                siddon::trace(mu.dims(), &g, &mut c);
            }
        }
    }
    c.0
}

fn rms_rel(a: &Projection, reference: &Projection) -> (f64, f64) {
    let (mut sq, mut max, mut n) = (0.0, 0.0f64, 0usize);
    let peak = reference.data.iter().fold(0.0f32, |m, &v| m.max(v)) as f64;
    for (&x, &r) in a.data.iter().zip(&reference.data) {
        // Relative to the pixel where it matters, to the image's peak in air.
        let d = (f64::from(x) - f64::from(r)) / f64::from(r).max(0.05 * peak);
        sq += d * d;
        max = max.max(d.abs());
        n += 1;
    }
    ((sq / n as f64).sqrt(), max)
}

/// The page's opening paragraph: how it was measured and what the columns mean.
pub fn header(args: &Options) -> Result<String> {
    let threads = rayon::current_num_threads();
    let cpu = crate::cpu_model();
    let mut md = String::new();
    writeln!(
        md,
        "Measured by `tomograf bench{}` on {cpu}, {threads} threads, SIMD kernel {}; median of {} renders.\n\n\
         Exact Siddon clips each ray to the box of non-zero attenuation (air adds exactly nothing) and \
         traces rows in packets of rays (`sim/src/trace/packet/`) or, with a SIMD kernel (AVX2 or AVX-512), \
         the rows of AP views as ray sheets (`sim/src/trace/sheet/`, docs/projector.md). \"Scalar tracer \
         only\" is neither. The phantom's air is exactly 0; a real \
         CT's air is noise around −1000 HU, so nothing can be skipped there — the column \"air at 1e-6 mm⁻¹\" \
         measures that case. \"Voxel steps\" count every voxel of the whole grid a ray crosses (as a full \
         traversal would, and as plastimatch does); the rate divides them by the render time.\n",
        if args.quick { " --quick" } else { "" },
        tomograf_sim::trace::packet::kernel()
            .map_or("none (scalar)".to_string(), |k| format!("{k:?}")),
        args.repeats
    )?;

    Ok(md)
}

/// The projector page (docs/benchmarks.md): [`header`], exact Siddon throughput, the
/// chest-sized case, trilinear against exact, then [`crate::accel`]'s sections.
pub fn page(args: &Options) -> Result<String> {
    let mut md = header(args)?;
    // 1. Throughput.
    let (sizes, dets): (&[usize], &[usize]) = if args.quick {
        (&[32, 64], &[64])
    } else {
        (&[128, 256, 512], &[256, 512])
    };
    writeln!(
        md,
        "### Exact Siddon throughput (thorax phantom in a 360 mm cube, cone beam θ = 20°, SAD 1000 / SID 1500, panel covering 396 mm at the isocentre)\n"
    )?;
    writeln!(
        md,
        "| volume | detector | render ms | Mrays/s | voxel steps/ray | G voxel steps/s |"
    )?;
    writeln!(md, "|---|---|---:|---:|---:|---:|")?;
    for &n in sizes {
        let mu = thorax_mu([n; 3], [360.0 / n as f64; 3])?;
        let r = Renderer::new(&mu, Projector::Siddon)?;
        for &d in dets {
            let v = view(d, Pose::new(20.0, 0.0))?;
            let (ms, _) = median_ms(args.repeats, || Ok(r.render(&v)?))?;
            let steps = voxel_steps(&mu, &v);
            let rays = (d * d) as f64;
            writeln!(
                md,
                "| {n}³ | {d}² | {ms:.1} | {:.2} | {:.0} | {:.3} |",
                rays / ms / 1e3,
                steps as f64 / rays,
                steps as f64 / ms / 1e6
            )?;
            eprintln!("throughput {n}³ at {d}²: {ms:.1} ms");
        }
    }

    // 2. The chest-sized target case and the trilinear trade-off.
    let (dims, spacing, det) = if args.quick {
        ([64, 64, 17], [5.6, 5.6, 19.6], 64)
    } else {
        ([512, 512, 133], [0.7, 0.7, 2.5], 256)
    };
    let mu = thorax_mu(dims, spacing)?;
    writeln!(
        md,
        "\n### Chest-sized CT: {}×{}×{} voxels of {}×{}×{} mm, {det}² detector, SAD 1000 / SID 1500\n",
        dims[0], dims[1], dims[2], spacing[0], spacing[1], spacing[2]
    )?;
    writeln!(
        md,
        "| view | Siddon render ms | scalar tracer only, ms | air at 1e-6 mm⁻¹ (no exact zeros), ms | voxel steps/ray | G voxel steps/s |"
    )?;
    writeln!(md, "|---|---:|---:|---:|---:|---:|")?;
    let siddon = Renderer::new(&mu, Projector::Siddon)?;
    let scalar = Renderer::new(&mu, Projector::Siddon)?
        .with_packet_threshold(f64::INFINITY)
        .with_sheets(false);
    // A real CT's air is noise around −1000 HU, not exact zeros: nothing can be skipped.
    let mu_noisy_air = mu.map(|v| v + 1e-6)?;
    let noisy_air = Renderer::new(&mu_noisy_air, Projector::Siddon)?;
    for (name, pose) in [
        ("AP", Pose::AP),
        ("lateral", Pose::LATERAL),
        ("θ = 30°", Pose::new(30.0, 0.0)),
        ("θ = 45°, φ = 20°", Pose::new(45.0, 20.0)),
    ] {
        let v = view(det, pose)?;
        let (ms, _) = median_ms(args.repeats, || Ok(siddon.render(&v)?))?;
        let (ms_scalar, _) = median_ms(args.repeats, || Ok(scalar.render(&v)?))?;
        let (ms_noisy, _) = median_ms(args.repeats, || Ok(noisy_air.render(&v)?))?;
        let steps = voxel_steps(&mu, &v);
        writeln!(
            md,
            "| {name} | {ms:.1} | {ms_scalar:.1} | {ms_noisy:.1} | {:.0} | {:.3} |",
            steps as f64 / (det * det) as f64,
            steps as f64 / ms / 1e6
        )?;
        eprintln!("chest {name}: {ms:.1} ms");
    }

    let v = view(det, Pose::new(30.0, 10.0))?;
    let (t_siddon, exact) = median_ms(args.repeats, || Ok(siddon.render(&v)?))?;
    let fine_step = if args.quick { 0.05 } else { 0.0625 };
    let fine = Renderer::new(
        &mu,
        Projector::Trilinear {
            step_voxels: fine_step,
        },
    )?
    .render(&v)?;
    writeln!(
        md,
        "\n### Trilinear marching against exact Siddon (same case, view θ = 30°, φ = 10°)\n"
    )?;
    writeln!(
        md,
        "Errors are per pixel relative to the reference value (floored at 5 % of the image's peak). "
    )?;
    writeln!(
        md,
        "\"vs Siddon\" compares two different fields (trilinear vs nearest-voxel); \"vs converged\" is the marcher's own "
    )?;
    writeln!(
        md,
        "discretisation error against trilinear at step {fine_step} voxel.\n"
    )?;
    writeln!(
        md,
        "| projector | step (voxels) | render ms | time / Siddon | RMS rel. diff vs Siddon | RMS rel. error vs converged | max rel. error vs converged |"
    )?;
    writeln!(md, "|---|---:|---:|---:|---:|---:|---:|")?;
    writeln!(
        md,
        "| Siddon (exact) | — | {t_siddon:.1} | 1.00 | 0 | — | — |"
    )?;
    let mut prev: Option<f64> = None;
    let mut orders = Vec::new();
    for step in [2.0, 1.0, 0.5, 0.25] {
        let r = Renderer::new(&mu, Projector::Trilinear { step_voxels: step })?;
        let (ms, img) = median_ms(args.repeats, || Ok(r.render(&v)?))?;
        let (vs_siddon, _) = rms_rel(&img, &exact);
        let (vs_fine, max_fine) = rms_rel(&img, &fine);
        if let Some(p) = prev {
            orders.push((p / vs_fine).log2());
        }
        prev = Some(vs_fine);
        writeln!(
            md,
            "| trilinear | {step} | {ms:.1} | {:.2} | {vs_siddon:.2e} | {vs_fine:.2e} | {max_fine:.2e} |",
            ms / t_siddon
        )?;
        eprintln!("trilinear step {step}: {ms:.1} ms");
    }
    let orders: Vec<String> = orders.iter().map(|o| format!("{o:.2}")).collect();
    writeln!(
        md,
        "\nObserved order of the marcher's error per halving of the step: {}.",
        orders.join(", ")
    )?;

    crate::accel::skipping(args, &mut md)?;
    crate::accel::meshes(args, &mut md)?;
    Ok(md)
}
