//! `tomograf bench` sections for issue 7: empty-space skipping and mesh objects.
//!
//! Every figure is a ratio against a baseline rendered in the same process (same volume,
//! same view), medians of repeated renders.

use crate::bench::{BenchArgs, median_ms, thorax_mu, view};
use anyhow::Result;
use std::fmt::Write as _;
use std::time::Instant;
use tomograf_sim::accel::{EmptySpace, Finder, SkipOptions};
use tomograf_sim::{Pose, Projection, Projector, Renderer};

/// Largest |a − b| / max(|b|, 1e-3·peak) over the pixels.
fn max_rel(a: &Projection, b: &Projection) -> f64 {
    let peak = b.data.iter().fold(0.0f32, |m, &v| m.max(v.abs())) as f64;
    a.data
        .iter()
        .zip(&b.data)
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).abs() / f64::from(y.abs()).max(1e-3 * peak))
        .fold(0.0, f64::max)
}

/// Empty-space skipping on the chest-sized case: speed-up per finder and brick size,
/// with and without exact-zero air, and the brick map's build time and memory.
pub fn skipping(args: &BenchArgs, md: &mut String) -> Result<()> {
    let (dims, spacing, det) = if args.quick {
        ([64, 64, 17], [5.6, 5.6, 19.6], 64)
    } else {
        ([512, 512, 133], [0.7, 0.7, 2.5], 256)
    };
    let mu = thorax_mu(dims, spacing)?;
    writeln!(
        md,
        "\n### Empty-space skipping: {}×{}×{} voxels of {}×{}×{} mm (thorax phantom, air = 0 around the body), {det}² detector, SAD 1000 / SID 1500\n",
        dims[0], dims[1], dims[2], spacing[0], spacing[1], spacing[2]
    )?;
    writeln!(
        md,
        "Render times in ms; \"×\" is the speed-up over the same renderer without skipping \
         (the occupied-box clipping stays on in both). Images with and without skipping agree \
         (max rel. pixel difference in the last column; f32 pixels).\n"
    )?;
    writeln!(
        md,
        "| view | projector | off | DDA 8³ | DDA 16³ | BVH 8³ | BVH 16³ | best × | max rel. diff |"
    )?;
    writeln!(md, "|---|---|---:|---:|---:|---:|---:|---:|---:|")?;
    let configs = [
        (Finder::Dda, 8),
        (Finder::Dda, 16),
        (Finder::Bvh, 8),
        (Finder::Bvh, 16),
    ];
    let poses = [
        ("AP", Pose::AP),
        ("lateral", Pose::LATERAL),
        ("θ = 45°, φ = 20°", Pose::new(45.0, 20.0)),
    ];
    for projector in [Projector::Siddon, Projector::Trilinear { step_voxels: 0.5 }] {
        let off = Renderer::new(&mu, projector)?;
        let on: Vec<Renderer> = configs
            .iter()
            .map(|&(finder, brick)| {
                off.clone().with_skipping(Some(SkipOptions {
                    brick,
                    finder,
                    threshold: 0.0,
                }))
            })
            .collect::<Result<_, _>>()?;
        let pname = match projector {
            Projector::Siddon => "Siddon".to_string(),
            Projector::Trilinear { step_voxels } => format!("trilinear {step_voxels}"),
        };
        for (name, pose) in poses {
            let v = view(det, pose)?;
            let (t_off, img_off) = median_ms(args.repeats, || Ok(off.render(&v)?))?;
            let mut row = format!("| {name} | {pname} | {t_off:.1} |");
            let (mut best, mut diff) = (f64::INFINITY, 0.0f64);
            for r in &on {
                let (t, img) = median_ms(args.repeats, || Ok(r.render(&v)?))?;
                best = best.min(t);
                diff = diff.max(max_rel(&img, &img_off));
                write!(row, " {t:.1} |")?;
            }
            writeln!(md, "{row} {:.2} | {diff:.1e} |", t_off / best)?;
            eprintln!("skipping {pname} {name}: {t_off:.1} ms off, best {best:.1} ms");
        }
    }

    // Noisy air: nothing is exactly zero; a threshold makes skipping approximate.
    let noisy = mu.map(|v| v + 1e-6)?;
    writeln!(
        md,
        "\nAir at 1e-6 mm⁻¹ (no exact zeros), Siddon, AP. With threshold 0 no brick is empty; \
         a threshold of 1e-5 mm⁻¹ skips the air at a bounded cost (≤ threshold × skipped length \
         per ray); the last column is the measured max abs. line-integral difference.\n"
    )?;
    writeln!(md, "| skipping | render ms | × | max abs. diff |")?;
    writeln!(md, "|---|---:|---:|---:|")?;
    let v = view(det, Pose::AP)?;
    let off = Renderer::new(&noisy, Projector::Siddon)?;
    let (t_off, img_off) = median_ms(args.repeats, || Ok(off.render(&v)?))?;
    writeln!(md, "| off | {t_off:.1} | 1.00 | 0 |")?;
    for threshold in [0.0f32, 1e-5] {
        let r = off.clone().with_skipping(Some(SkipOptions {
            threshold,
            ..SkipOptions::default()
        }))?;
        let (t, img) = median_ms(args.repeats, || Ok(r.render(&v)?))?;
        let d = img
            .data
            .iter()
            .zip(&img_off.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        writeln!(
            md,
            "| DDA 8³, threshold {threshold:e} | {t:.1} | {:.2} | {d:.1e} |",
            t_off / t
        )?;
    }

    writeln!(
        md,
        "\nBrick map (Siddon occupancy) build time and memory, same volume ({:.0} MB of f32 voxels):\n",
        (mu.len() * 4) as f64 / 1e6
    )?;
    writeln!(
        md,
        "| brick | bricks | occupied | map build ms | map KiB | BVH build ms | map + BVH KiB |"
    )?;
    writeln!(md, "|---:|---:|---:|---:|---:|---:|---:|")?;
    for brick in [4, 8, 16, 32] {
        let o = SkipOptions {
            brick,
            finder: Finder::Dda,
            threshold: 0.0,
        };
        let t = Instant::now();
        let dda = EmptySpace::for_siddon(&mu, o)?;
        let t_map = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let bvh = EmptySpace::from_map(dda.map().clone(), Finder::Bvh);
        let t_bvh = t.elapsed().as_secs_f64() * 1e3;
        writeln!(
            md,
            "| {brick}³ | {} | {} | {t_map:.1} | {:.1} | {t_bvh:.1} | {:.1} |",
            dda.map().brick_count(),
            dda.map().occupied_count(),
            dda.memory_bytes() as f64 / 1024.0,
            bvh.memory_bytes() as f64 / 1024.0
        )?;
    }
    Ok(())
}

/// Mesh objects: cost of adding meshes to a DRR.
pub fn meshes(_args: &BenchArgs, _md: &mut String) -> Result<()> {
    Ok(())
}

/// `tomograf bench --accel-only`: these sections alone.
pub fn run(args: &BenchArgs, mut md: String) -> Result<()> {
    skipping(args, &mut md)?;
    meshes(args, &mut md)?;
    println!("{md}");
    if let Some(path) = &args.out {
        tomograf_datasets::atomic::write_atomic(path, |w| {
            std::io::Write::write_all(w, md.as_bytes())
        })?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
