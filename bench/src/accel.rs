//! `tomograf bench` sections for issue 7: empty-space skipping and mesh objects.
//!
//! Every figure is a ratio against a baseline rendered in the same process (same volume,
//! same view), medians of repeated renders.

use crate::Options;
use crate::fixtures::{thorax_mu, view};
use anyhow::Result;
use std::fmt::Write as _;
use std::time::Instant;
use tomograf_sim::accel::{EmptySpace, Finder, SkipOptions};
use tomograf_sim::{Pose, Projection, Projector, Renderer};

/// Median render times (ms) of `renderers` on `view`, measured interleaved (one render of
/// each per round, after a warm-up round) so that a change in machine load during the
/// measurement affects all of them alike; also returns each renderer's image.
fn interleaved(
    repeats: usize,
    renderers: &[&Renderer],
    v: &tomograf_sim::View,
) -> Result<(Vec<f64>, Vec<Projection>)> {
    let mut images = renderers
        .iter()
        .map(|r| r.render(v))
        .collect::<Result<Vec<_>, _>>()?;
    let mut times = vec![Vec::new(); renderers.len()];
    for _ in 0..repeats.max(1) {
        for (i, r) in renderers.iter().enumerate() {
            let t = Instant::now();
            images[i] = r.render(v)?;
            times[i].push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let medians = times
        .into_iter()
        .map(|mut t| {
            t.sort_by(f64::total_cmp);
            t[t.len() / 2]
        })
        .collect();
    Ok((medians, images))
}

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
pub fn skipping(args: &Options, md: &mut String) -> Result<()> {
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
        "Renders of all columns are interleaved (one of each per round, median over rounds) so that \
         load changes on a shared machine hit every column alike.\n"
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
    for (pname, projector, packets) in [
        ("Siddon", Projector::Siddon, true),
        ("Siddon, scalar tracer only", Projector::Siddon, false),
        (
            "trilinear 0.5",
            Projector::Trilinear { step_voxels: 0.5 },
            false,
        ),
    ] {
        let mut off = Renderer::new(&mu, projector)?.with_skipping(None)?;
        if !packets {
            off = off.with_packet_threshold(f64::INFINITY).with_sheets(false);
        }
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
        let poses = if pname.starts_with("trilinear") {
            &poses[1..]
        } else {
            &poses[..]
        };
        for &(name, pose) in poses {
            let v = view(det, pose)?;
            let all: Vec<&Renderer> = std::iter::once(&off).chain(&on).collect();
            let (times, images) = interleaved(args.repeats, &all, &v)?;
            let t_off = times[0];
            let mut row = format!("| {name} | {pname} | {t_off:.1} |");
            let (mut best, mut diff) = (f64::INFINITY, 0.0f64);
            for (t, img) in times[1..].iter().zip(&images[1..]) {
                best = best.min(*t);
                diff = diff.max(max_rel(img, &images[0]));
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
        "\nAir at 1e-6 mm⁻¹ (no exact zeros, like a real CT), Siddon, AP. With threshold 0 no brick is empty; \
         a threshold of 1e-5 mm⁻¹ skips the air at a bounded cost (≤ threshold × skipped length \
         per ray); the last column is the measured max abs. line-integral difference. The SIMD \
         packets take each ray trimmed to its first and last occupied brick; the scalar tracer \
         skips every empty brick; the ray sheets (the default without skipping at AP with a \
         SIMD kernel) skip only exact zeros, by rows, so skipping bricks turns them off.\n"
    )?;
    writeln!(md, "| tracer | skipping | render ms | × | max abs. diff |")?;
    writeln!(md, "|---|---|---:|---:|---:|")?;
    let v = view(det, Pose::AP)?;
    for (tracer, packet_threshold) in [
        ("default (packets, or sheets)", None),
        ("scalar only", Some(f64::INFINITY)),
    ] {
        let mut off = Renderer::new(&noisy, Projector::Siddon)?;
        if let Some(t) = packet_threshold {
            off = off.with_packet_threshold(t).with_sheets(false);
        }
        let thresholds = [0.0f32, 1e-5];
        let on = thresholds
            .iter()
            .map(|&threshold| {
                off.clone().with_skipping(Some(SkipOptions {
                    threshold,
                    ..SkipOptions::default()
                }))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let all: Vec<&Renderer> = std::iter::once(&off).chain(&on).collect();
        let (times, images) = interleaved(args.repeats, &all, &v)?;
        let (t_off, img_off) = (times[0], &images[0]);
        writeln!(md, "| {tracer} | off | {t_off:.1} | 1.00 | 0 |")?;
        for ((threshold, t), img) in thresholds.iter().zip(&times[1..]).zip(&images[1..]) {
            let d = img
                .data
                .iter()
                .zip(&img_off.data)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            writeln!(
                md,
                "| {tracer} | DDA 8³, threshold {threshold:e} | {t:.1} | {:.2} | {d:.1e} |",
                t_off / t
            )?;
        }
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

/// Mesh objects: cost of adding meshes to a DRR of the chest-sized case.
pub fn meshes(args: &Options, md: &mut String) -> Result<()> {
    use std::sync::Arc;
    use tomograf_sim::mesh::{MeshObject, MeshScene, Placement, shapes};
    let (dims, spacing, det, segments) = if args.quick {
        ([64, 64, 17], [5.6, 5.6, 19.6], 64, (64, 32))
    } else {
        ([512, 512, 133], [0.7, 0.7, 2.5], 256, (320, 160))
    };
    let mu = thorax_mu(dims, spacing)?;
    let sphere = shapes::uv_sphere(60.0, segments.0, segments.1)?;
    let t = Instant::now();
    let big = MeshObject::new(
        "sphere",
        &sphere,
        &Placement::translation(glam::DVec3::new(40.0, 0.0, 0.0)),
        "titanium",
        Some(0.1),
        false,
    )?;
    let t_build = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let (pairs, _) = big.self_intersections();
    let t_self = t.elapsed().as_secs_f64() * 1e3;
    let mut devices = Vec::new();
    for (name, m) in shapes::pacemaker(32)? {
        let p = Placement::translation(glam::DVec3::new(60.0, -90.0, 60.0));
        devices.push(MeshObject::new(&name, &m, &p, "titanium", Some(0.1), true)?);
    }
    let table = shapes::table_top(450.0, 1900.0, 40.0)?;
    let p = Placement::translation(glam::DVec3::new(0.0, 205.0, 0.0));
    devices.push(MeshObject::new(
        "table",
        &table,
        &p,
        "carbon",
        Some(0.005),
        true,
    )?);
    let device_tris: usize = devices.iter().map(MeshObject::triangle_count).sum();
    writeln!(
        md,
        "\n### Mesh objects in a DRR: same chest case, Siddon, {det}² detector\n"
    )?;
    writeln!(
        md,
        "A UV sphere of {} triangles (radius 60 mm, in the chest): BVH build {t_build:.1} ms, \
         {:.1} MiB (triangles in f64 + BVH); self-intersection check {t_self:.0} ms ({pairs} crossing pairs). \
         Pacemaker (can + 2 leads, on the chest) and table top (under the body, outside the CT grid): {device_tris} triangles. \
         \"+ %\" is the render-time increase over the voxels alone, same renderer.\n",
        big.triangle_count(),
        big.memory_bytes() as f64 / (1 << 20) as f64
    )?;
    fans(args, md, (t_build, t_self, big.triangle_count()))?;
    writeln!(
        md,
        "\n| view | voxels only ms | + sphere ms | + % | + devices ms | + % |"
    )?;
    writeln!(md, "|---|---:|---:|---:|---:|---:|")?;
    let base = Renderer::new(&mu, Projector::Siddon)?;
    let with_big = base
        .clone()
        .with_meshes(Arc::new(MeshScene::new(vec![big])))?;
    let with_dev = base
        .clone()
        .with_meshes(Arc::new(MeshScene::new(devices)))?;
    for (name, pose) in [("AP", Pose::AP), ("lateral", Pose::LATERAL)] {
        let v = view(det, pose)?;
        let (t, _) = interleaved(args.repeats, &[&base, &with_big, &with_dev], &v)?;
        let (t0, t1, t2) = (t[0], t[1], t[2]);
        writeln!(
            md,
            "| {name} | {t0:.1} | {t1:.1} | {:+.0} | {t2:.1} | {:+.0} |",
            100.0 * (t1 / t0 - 1.0),
            100.0 * (t2 / t0 - 1.0)
        )?;
        eprintln!("meshes {name}: {t0:.1} / {t1:.1} / {t2:.1} ms");
    }
    Ok(())
}

/// Fans: a cylinder's caps are fans of `sides` triangles around one vertex, the shape on
/// which a BVH build over equal boxes and a self-intersection check by neighbourhoods
/// degrade (issue 51). Each cylinder's mesh build and self-intersection check, once, as
/// time per triangle against the UV sphere's of the same run (`sphere`: build ms, check ms,
/// triangles), and the growth exponent between successive sizes (1: linear).
fn fans(args: &Options, md: &mut String, sphere: (f64, f64, usize)) -> Result<()> {
    use tomograf_sim::mesh::{MeshObject, Placement, shapes};
    let sides: &[u32] = if args.quick {
        &[1024, 4096]
    } else {
        &[4096, 16384, 65536]
    };
    writeln!(
        md,
        "Fans (issue 51): a cylinder of radius 20 mm, height 60 mm, whose two caps are fans \
         of `sides` triangles around one vertex; one run each. \"÷ sphere\" is the time per \
         triangle over the UV sphere's above; the exponent is log(time ratio) / log(size \
         ratio) from the row above (1: linear).\n"
    )?;
    writeln!(
        md,
        "| sides | triangles | build ms | ÷ sphere | exponent | check ms | ÷ sphere | exponent |"
    )?;
    writeln!(md, "|---:|---:|---:|---:|---:|---:|---:|---:|")?;
    let per = |ms: f64, n: usize| ms / n as f64;
    let mut last: Option<(f64, f64, usize)> = None;
    for &n in sides {
        let mesh = shapes::cylinder(20.0, 60.0, n)?;
        let t = Instant::now();
        let obj = MeshObject::new(
            "fan",
            &mesh,
            &Placement::translation(glam::DVec3::ZERO),
            "titanium",
            Some(0.1),
            false,
        )?;
        let build = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let (pairs, _) = obj.self_intersections();
        let check = t.elapsed().as_secs_f64() * 1e3;
        anyhow::ensure!(
            pairs == 0,
            "a cylinder of {n} sides has {pairs} crossing pairs"
        );
        let tris = obj.triangle_count();
        let exponent = |now: f64, before: Option<(f64, usize)>| {
            before.map_or("–".to_string(), |(t0, n0)| {
                format!("{:.2}", (now / t0).ln() / (tris as f64 / n0 as f64).ln())
            })
        };
        let eb = exponent(build, last.map(|(b, _, n0)| (b, n0)));
        let ec = exponent(check, last.map(|(_, c, n0)| (c, n0)));
        writeln!(
            md,
            "| {n} | {tris} | {build:.1} | {:.1} | {eb} | {check:.1} | {:.1} | {ec} |",
            per(build, tris) / per(sphere.0, sphere.2),
            per(check, tris) / per(sphere.1, sphere.2),
        )?;
        eprintln!("fans {n}: build {build:.1} ms, check {check:.1} ms");
        last = Some((build, check, tris));
    }
    Ok(())
}

/// `tomograf bench --accel-only`: these sections alone after `md`; `section` is
/// `skipping` or `meshes` for one of them.
pub fn page(args: &Options, section: Option<&str>, mut md: String) -> Result<String> {
    if !matches!(section, None | Some("skipping") | Some("meshes")) {
        anyhow::bail!("unknown --section: use skipping or meshes");
    }
    if section != Some("meshes") {
        skipping(args, &mut md)?;
    }
    if section != Some("skipping") {
        meshes(args, &mut md)?;
    }
    Ok(md)
}
