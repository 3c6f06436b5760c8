//! `tomograf phantom --mesh-devices`: the pacemaker and table come out as closed meshes and
//! a scene that places them; the phantom then holds no device voxels (the rest of it is
//! unchanged, byte for byte), and projecting the scene shows the devices where the
//! voxelised devices are (same pixels), through the ideal DRR and real detector physics.

mod common;

use common::{ok, read_npy, tomograf};
use std::path::Path;

const GRID: [&str; 4] = ["--dims", "96,96,60", "--spacing", "5,5,7"];

fn phantom(dir: &Path, name: &str, extra: &[&str]) -> String {
    let path = dir.join(name).to_str().unwrap().to_string();
    let mut args = vec![
        "phantom",
        "-o",
        &path,
        "--profile",
        "full-chest",
        "--seed",
        "3",
    ];
    args.extend(GRID);
    args.extend(extra);
    ok(&tomograf(&args));
    path
}

fn ap(dir: &Path, name: &str, input: &[&str]) -> Vec<f32> {
    let out = dir.join(name);
    let mut args = vec!["project"];
    args.extend(input);
    args.extend(["--rows", "64", "--cols", "64", "--format", "npy"]);
    args.extend(["--output", out.to_str().unwrap()]);
    ok(&tomograf(&args));
    read_npy(&out.join("drr.npy")).1
}

#[test]
fn phantom_devices_as_meshes_end_to_end() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let plain = phantom(dir, "plain.nii", &[]);
    let voxels = phantom(dir, "voxels.nii", &["--pacemaker", "--table"]);
    let devices = dir.join("devices");
    let meshed = phantom(
        dir,
        "meshed.nii",
        &[
            "--pacemaker",
            "--table",
            "--mesh-devices",
            devices.to_str().unwrap(),
        ],
    );
    // The devices are not in the voxels; nothing else changed.
    assert_eq!(
        std::fs::read(&plain).unwrap(),
        std::fs::read(&meshed).unwrap()
    );
    for name in [
        "pacemaker-can",
        "pacemaker-lead-1",
        "pacemaker-lead-2",
        "table-pad",
        "table-top",
        "table-core",
    ] {
        let mesh = tomograf_sim::mesh::io::load(&devices.join(format!("{name}.obj"))).unwrap();
        tomograf_sim::mesh::topology::check(&mesh).unwrap();
    }
    let scene = devices.join("scene.toml");
    let scene = scene.to_str().unwrap();
    let base = ap(dir, "base", &[&plain]);
    let with_voxels = ap(dir, "vox", &[&voxels]);
    let with_meshes = ap(dir, "mesh", &["--scene", scene]);
    let dv: Vec<f64> = with_voxels
        .iter()
        .zip(&base)
        .map(|(a, b)| f64::from(a - b))
        .collect();
    let dm: Vec<f64> = with_meshes
        .iter()
        .zip(&base)
        .map(|(a, b)| f64::from(a - b))
        .collect();
    // The pacemaker (titanium, > 0.5 added) shows on the same pixels. The voxel can is
    // 8 mm thick on 5 mm voxels (HU clipped at 3071), the mesh can solid titanium: the
    // supports overlap by IoU 0.65 here, their centroids within a pixel.
    let strong = |d: &[f64]| -> Vec<bool> { d.iter().map(|&x| x > 0.5).collect() };
    let (sv, sm) = (strong(&dv), strong(&dm));
    let both = sv.iter().zip(&sm).filter(|(a, b)| **a && **b).count();
    let either = sv.iter().zip(&sm).filter(|(a, b)| **a || **b).count();
    let iou = both as f64 / either.max(1) as f64;
    let centroid = |m: &[bool]| {
        let px: Vec<(f64, f64)> = (0..m.len())
            .filter(|&i| m[i])
            .map(|i| ((i / 64) as f64, (i % 64) as f64))
            .collect();
        let n = px.len() as f64;
        (
            px.iter().map(|p| p.0).sum::<f64>() / n,
            px.iter().map(|p| p.1).sum::<f64>() / n,
        )
    };
    let (cv, cm) = (centroid(&sv), centroid(&sm));
    // The table lies under the whole body: nearly every ray through the body crosses it.
    // (Its 2.5 mm carbon-fibre skins are thinner than these voxels, so the voxel table is
    // no reference for how much it adds.)
    let body: Vec<usize> = (0..base.len()).filter(|&i| base[i] > 1.0).collect();
    let crossed = body.iter().filter(|&&i| dm[i] > 0.01).count() as f64 / body.len() as f64;
    eprintln!(
        "pacemaker IoU {iou:.3} ({both}/{either}), centroids {cv:?} {cm:?}; table under {crossed:.3} of the body"
    );
    assert!(
        either > 10 && iou > 0.5,
        "pacemaker pixels overlap: IoU {iou}"
    );
    assert!(
        (cv.0 - cm.0).abs() < 2.0 && (cv.1 - cm.1).abs() < 2.0,
        "pacemaker centroids {cv:?} vs {cm:?}"
    );
    assert!(
        crossed > 0.9,
        "the table is under {crossed} of the body's pixels"
    );
    // Real detector physics reads the same scene (materials and densities).
    let physics = ap(
        dir,
        "physics",
        &["--scene", scene, "--preset", "kv-flat-panel-120kvp"],
    );
    assert!(physics.iter().all(|v| v.is_finite()));
    // Devices without a procedural patient, or nothing to write, are clear errors.
    let out = tomograf(&["phantom", "-o", "x.nii", "--mesh-devices", "d"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("procedural patient"));
    // A seed for the analytic thorax, which has none, was ignored; it is refused.
    let out = tomograf(&["phantom", "-o", "x.nii", "--seed", "3"]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("--seed") && e.contains("procedural patient"),
        "{e}"
    );
    let out = tomograf(&[
        "phantom",
        "-o",
        "x.nii",
        "--profile",
        "lidc",
        "--mesh-devices",
        "d",
    ]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("(--pacemaker, --table)"));
}
