//! End-to-end tests of `[scatter]` on the command line: the separate images (primary,
//! single Compton, single Rayleigh, multiple, scatter, total) and how they add up, their
//! independence of the thread count, the anti-scatter grid lowering the scatter-to-primary
//! ratio, and errors for bad sections.

mod common;

use common::*;
use std::path::Path;

const ALL: &str = r#"["primary", "compton", "rayleigh", "multiple", "scatter", "total"]"#;

/// Writes a scene (small phantom, 16 × 16 panel, raw signal) with `scatter` as the body of
/// its `[scatter]` table (plus `extra` tables after it), renders it into `dir/name` with
/// `global` flags and returns the output folder.
fn run(dir: &Path, name: &str, global: &[&str], scatter: &str, extra: &str) -> std::path::PathBuf {
    let out = dir.join(name);
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(
        &scene,
        format!(
            "[volume]\nphantom_dims = [48, 48, 30]\nphantom_spacing_mm = [7.5, 7.5, 11.0]\n\
             [detector]\nrows = 16\ncols = 16\n\
             [acquisition]\npreset = \"kv-flat-panel-120kvp\"\nsignal = \"raw\"\nseed = 5\n\
             [output]\ndir = \"{}\"\nformats = [\"npy\", \"exr\"]\n\
             [scatter]\n{scatter}\n{extra}",
            out.display()
        ),
    )
    .unwrap();
    let mut args = global.to_vec();
    args.extend(["project", "--scene", scene.to_str().unwrap()]);
    ok(&tomograf(&args));
    out
}

fn stack(out: &Path, image: &str) -> Vec<f64> {
    let (shape, v) = read_npy(&out.join(format!("drr_{image}.npy")));
    assert_eq!(shape, [1, 16, 16], "{image}");
    v.iter().map(|x| f64::from(*x)).collect()
}

const MC: &str = "model = \"monte-carlo\"\nphotons = 3000\ngrid = 4\n";

#[test]
fn separate_images_are_written_and_add_up() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = run(
        d,
        "a",
        &["--threads", "1"],
        &format!("{MC}images = {ALL}"),
        "",
    );
    let get = |i| stack(&out, i);
    let (p, c, r, m, s, t) = (
        get("primary"),
        get("compton"),
        get("rayleigh"),
        get("multiple"),
        get("scatter"),
        get("total"),
    );
    for i in 0..p.len() {
        assert!(
            p[i] > 0.0 && c[i] > 0.0 && r[i] > 0.0 && m[i] > 0.0,
            "pixel {i}"
        );
        // Written as f32: sums agree to f32 rounding.
        assert!(
            (c[i] + r[i] + m[i] - s[i]).abs() <= 1e-6 * s[i],
            "pixel {i}"
        );
        assert!((p[i] + s[i] - t[i]).abs() <= 1e-6 * t[i], "pixel {i}");
    }
    // Compton dominates single scatter at 120 kVp in soft tissue.
    assert!(c.iter().sum::<f64>() > r.iter().sum::<f64>());
    for name in ["primary", "compton", "total"] {
        assert!(out.join(format!("drr_{name}_000.exr")).is_file(), "{name}");
        let sidecar: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(format!("drr_{name}.json"))).unwrap())
                .unwrap();
        assert!(sidecar["quantity"].as_str().unwrap().contains(name));
    }
    // The main output is still written, and the scene's images round-trip in its sidecar.
    assert!(out.join("drr.npy").is_file());
    // Thread count does not change the bytes.
    let two = run(
        d,
        "b",
        &["--threads", "2"],
        &format!("{MC}images = {ALL}"),
        "",
    );
    for name in ["compton", "rayleigh", "multiple", "primary"] {
        assert_eq!(
            std::fs::read(out.join(format!("drr_{name}.npy"))).unwrap(),
            std::fs::read(two.join(format!("drr_{name}.npy"))).unwrap(),
            "{name}"
        );
    }
}

#[test]
fn an_anti_scatter_grid_lowers_the_scatter_to_primary_ratio() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let images = "images = [\"primary\", \"scatter\"]";
    let open = run(d, "open", &[], &format!("{MC}{images}"), "");
    let grid = "[scatter.anti_scatter_grid]\nratio = 10\nlines_per_cm = 40\n";
    let with = run(d, "grid", &[], &format!("{MC}{images}"), grid);
    let sum = |out: &Path, i| stack(out, i).iter().sum::<f64>();
    let tp = sum(&with, "primary") / sum(&open, "primary");
    let ts = sum(&with, "scatter") / sum(&open, "scatter");
    eprintln!("Tp {tp:.3}, Ts {ts:.3}");
    // Open fraction 0.856 times ≈ 2 mm of aluminium at 120 kVp: Tp ≈ 0.6–0.85.
    assert!((0.6..0.86).contains(&tp), "Tp {tp}");
    assert!(ts < 0.6 * tp, "Ts {ts} vs Tp {tp}");
    // The grid alone (no scatter model) still attenuates the primary.
    let only = run(
        d,
        "only",
        &[],
        "model = \"none\"\nimages = [\"primary\"]",
        grid,
    );
    assert_eq!(
        std::fs::read(only.join("drr_primary.npy")).unwrap(),
        std::fs::read(with.join("drr_primary.npy")).unwrap()
    );
}

#[test]
fn bad_scatter_sections_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fails = |scatter: &str, extra: &str| {
        let scene = d.join("bad.toml");
        std::fs::write(
            &scene,
            format!(
                "[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[output]\ndir = \"{}\"\n\
                 [scatter]\n{scatter}\n{extra}",
                d.join("o").display()
            ),
        )
        .unwrap();
        let out = tomograf(&["project", "--scene", scene.to_str().unwrap()]);
        assert!(!out.status.success(), "should fail: {scatter} {extra}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let e = fails("model = \"none\"\nimages = [\"compton\"]", "");
    assert!(e.contains("compton") && e.contains("model"), "{e}");
    let e = fails(&format!("{MC}images = [\"compton\", \"speckle\"]"), "");
    assert!(e.contains("speckle"), "{e}");
    let e = fails(
        MC,
        "[scatter.anti_scatter_grid]\nratio = -3\nlines_per_cm = 40\n",
    );
    assert!(e.contains("ratio"), "{e}");
    let e = fails(MC, "[scatter.anti_scatter_grid]\nratio = 8\n");
    assert!(e.contains("lines_per_cm"), "{e}");
}

/// `tomograf bench --scatter CT --quick`: the speed ladder on a small CT file, with its
/// reference cached and reused; every row scored, the cells' bias given for the rows
/// through cells, the orbit timed.
#[test]
fn the_scatter_bench_runs_on_a_ct_and_reuses_its_reference() {
    let dir = tempfile::tempdir().unwrap();
    let ct = dir.path().join("ct.nii.gz");
    ok(&tomograf(&[
        "phantom",
        "-o",
        ct.to_str().unwrap(),
        "--dims",
        "48,40,24",
        "--spacing",
        "7,7,10",
    ]));
    let cache = dir.path().join("ref.npy");
    let page = dir.path().join("speed.md");
    let run_on = |ct: &std::path::Path| {
        ok(&tomograf(&[
            "bench",
            "--scatter",
            ct.to_str().unwrap(),
            "--quick",
            "--reference-photons",
            "512",
            "--rounds",
            "1",
            "--reference-cache",
            cache.to_str().unwrap(),
            "--out",
            page.to_str().unwrap(),
        ]));
        std::fs::read_to_string(&page).unwrap()
    };
    let run = || run_on(&ct);
    let first = run();
    assert!(first.contains("512 histories, 16² points ("), "{first}");
    let rows: Vec<&str> = first
        .lines()
        .filter(|l| l.starts_with("| Monte Carlo") || l.starts_with("| estimate"))
        .collect();
    assert_eq!(rows.len(), 29, "{first}");
    // Six rungs split at the first collision (×2 and ×4).
    assert_eq!(
        rows.iter()
            .filter(|r| r.contains(" at the first collision"))
            .count(),
        6,
        "{first}"
    );
    // The reference's own noise, from its two halves, is stated.
    assert!(
        first.contains("in two halves of their own histories; its own noise"),
        "{first}"
    );
    for r in &rows {
        let cells: Vec<&str> = r.split('|').map(str::trim).collect();
        // setting | s | × | line-integral | scatter (the worst round) | converged: line
        // integral, scatter | bias
        for c in &cells[2..8] {
            let (mean, worst) = c.split_once(" (").unwrap_or((c, ""));
            for x in [mean, worst].into_iter().filter(|x| !x.is_empty()) {
                let v: f64 = x.trim_end_matches(['%', '×', ' ', ')']).parse().unwrap();
                assert!(v.is_finite() && v >= 0.0, "{r}");
            }
        }
    }
    // The bias is given where the same rung at full resolution is on the ladder: the
    // Monte Carlo through 4, 8 and 16 mm cells and the old estimate through 8 mm.
    let with_bias = rows
        .iter()
        .filter(|r| !r.split('|').map(str::trim).nth(8).unwrap_or("").is_empty())
        .count();
    assert_eq!(with_bias, 4, "{first}");
    // Eight orbits: 900, 1500 and 3500 histories, the last also with analog sampling (the
    // ablation), the estimate, and 900, 1500 and 2200 histories split ×2.
    assert_eq!(first.matches("Orbit of 4 views").count(), 8, "{first}");
    assert_eq!(
        first
            .lines()
            .filter(|l| l.starts_with("Orbit of 4 views") && l.contains(" split ×2 at the first"))
            .count(),
        3,
        "{first}"
    );
    assert_eq!(first.matches("analog sampling").count(), 1, "{first}");
    let second = run();
    assert!(second.contains("(read from the cache)"), "{second}");
    // The cache knows the CT by its contents: moved, it is still read; another CT at the
    // same path is not.
    let moved = dir.path().join("moved.nii.gz");
    std::fs::rename(&ct, &moved).unwrap();
    let fourth = run_on(&moved);
    assert!(fourth.contains("(read from the cache)"), "{fourth}");
    ok(&tomograf(&[
        "phantom",
        "-o",
        moved.to_str().unwrap(),
        "--dims",
        "48,40,24",
        "--spacing",
        "7,7,10",
        "--profile",
        "lidc",
    ]));
    let fifth = run_on(&moved);
    assert!(!fifth.contains("(read from the cache)"), "{fifth}");
    std::fs::rename(&moved, &ct).unwrap();
    // Another view of the orbit, its orbits alone; a view the orbit lacks is named.
    let third = tomograf(&[
        "bench",
        "--scatter",
        ct.to_str().unwrap(),
        "--quick",
        "--view",
        "1",
        "--orbit-only",
        "--reference-photons",
        "512",
        "--rounds",
        "1",
        "--out",
        page.to_str().unwrap(),
    ]);
    ok(&third);
    let third = std::fs::read_to_string(&page).unwrap();
    assert!(
        third.contains("--view 1 --orbit-only")
            && third.contains("view 1 of 4")
            && third.contains("View 1 against the reference")
            && !third.contains("| setting |"),
        "{third}"
    );
    // The ladder alone.
    ok(&tomograf(&[
        "bench",
        "--scatter",
        ct.to_str().unwrap(),
        "--quick",
        "--ladder-only",
        "--reference-photons",
        "512",
        "--rounds",
        "1",
        "--out",
        page.to_str().unwrap(),
    ]));
    let ladder = std::fs::read_to_string(&page).unwrap();
    assert!(
        ladder.contains("--ladder-only")
            && ladder.contains("| setting |")
            && !ladder.contains("Orbit of"),
        "{ladder}"
    );
    let bad = tomograf(&[
        "bench",
        "--scatter",
        ct.to_str().unwrap(),
        "--quick",
        "--view",
        "4",
    ]);
    assert!(!bad.status.success());
    let e = String::from_utf8_lossy(&bad.stderr);
    assert!(e.contains("--view 4: the orbit has views 0 to 3"), "{e}");
}
