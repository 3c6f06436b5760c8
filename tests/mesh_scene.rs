//! `tomograf project` with `[[mesh]]` entries: a slab mesh outside the CT adds exactly its
//! chord × mu to every pixel; results do not depend on the thread count; bad entries are
//! clear errors.

use std::path::Path;
use std::process::Command;

fn tomograf(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tomograf"))
        .args(args)
        .output()
        .expect("runs")
}

fn scene(dir: &Path, name: &str, meshes: &str) -> String {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            "[volume]\nphantom_dims = [48, 48, 20]\nphantom_spacing_mm = [7.5, 7.5, 16.0]\n[detector]\nrows = 32\ncols = 32\n[views]\nposes = [\"ap\"]\n[output]\ndir = \"{}\"\nformats = [\"npy\"]\n{meshes}",
            dir.join(name).display()
        ),
    )
    .unwrap();
    path.to_str().unwrap().to_string()
}

fn render(dir: &Path, name: &str, meshes: &str, global: &[&str]) -> Vec<f32> {
    let s = scene(dir, name, meshes);
    let mut args = global.to_vec();
    args.extend(["project", "--scene", &s]);
    let out = tomograf(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(dir.join(name).join("drr.npy")).unwrap();
    npyz::NpyFile::new(&bytes[..])
        .unwrap()
        .into_vec::<f32>()
        .unwrap()
}

/// A 20 mm slab (mu 0.01 mm⁻¹) across the whole beam, 400 mm anterior of the isocentre
/// (between source and patient for AP, outside the CT grid): every ray gains
/// 0.01 × 20 / |cos| with |cos| ≥ 0.95 for this small panel, i.e. 0.2 to 0.21.
#[test]
fn slab_mesh_adds_its_chord_to_every_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let slab = "[[mesh]]\nname = \"slab\"\nkind = \"box\"\nsize_mm = [3000.0, 20.0, 3000.0]\nmaterial = \"plastic\"\nmu_per_mm = 0.01\ntranslation_mm = [0.0, -400.0, 0.0]\n";
    let base = render(dir.path(), "base", "", &[]);
    let with = render(dir.path(), "with", slab, &[]);
    for (a, b) in base.iter().zip(&with) {
        let d = f64::from(b - a);
        assert!((0.2 - 1e-5..0.2 / 0.95).contains(&d), "{d}");
    }
    // Same bytes with one thread.
    let one = render(dir.path(), "one", slab, &["--threads", "1"]);
    assert_eq!(one, with);
    // A pacemaker inside the chest changes some pixels only.
    let pm = "[[mesh]]\nname = \"pm\"\nkind = \"pacemaker\"\nmaterial = \"titanium\"\nmu_per_mm = 0.2\ntranslation_mm = [60.0, -90.0, 40.0]\n";
    let with_pm = render(dir.path(), "pm", pm, &[]);
    let changed = base.iter().zip(&with_pm).filter(|(a, b)| a != b).count();
    assert!(changed > 5 && changed < base.len() / 4, "{changed}");
}

#[test]
fn bad_mesh_entries_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let open = dir.path().join("open.obj");
    std::fs::write(
        &open,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n",
    )
    .unwrap();
    for (mesh, expect) in [
        (
            "kind = \"sphere\"\nmaterial = \"x\"\n",
            "unknown material: 'x'",
        ),
        ("kind = \"sphere\"\n", "give mu_per_mm"),
        (
            "kind = \"sphere\"\nmaterial = \"titanium\"\ndensity_g_cm3 = -1.0\n",
            "density_g_cm3 = -1",
        ),
        ("kind = \"cone\"\nmu_per_mm = 0.1\n", "unknown kind 'cone'"),
        ("mu_per_mm = 0.1\n", "exactly one of path and kind"),
        ("path = \"missing.stl\"\nmu_per_mm = 0.1\n", "missing.stl"),
        ("path = \"open.obj\"\nmu_per_mm = 0.1\n", "3 boundary edges"),
        (
            "kind = \"box\"\nmu_per_mm = 0.1\nscale = [1.0, 0.0, 1.0]\n",
            "singular",
        ),
    ] {
        let s = scene(
            dir.path(),
            "bad",
            &format!("[[mesh]]\nname = \"thing\"\n{mesh}"),
        );
        let out = tomograf(&["project", "--scene", &s]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(expect),
            "{mesh}: {err}"
        );
        assert!(err.contains("thing"), "names the mesh: {err}");
    }
}

/// The same scenes with real detector physics (ideal detector, flat-field signal): a
/// titanium mesh names its material and its density; a 1 mm titanium slab outside the CT
/// lowers every pixel's transmission; a pacemaker changes some pixels; same bytes with one
/// thread; mu_per_mm is refused there.
#[test]
fn meshes_with_real_detector_physics() {
    let dir = tempfile::tempdir().unwrap();
    let physics = "[spectrum]\nkvp = 100\nbins = 20\n[acquisition]\nsignal = \"flat-field\"\n";
    let slab = format!(
        "{physics}[[mesh]]\nname = \"slab\"\nkind = \"box\"\nsize_mm = [3000.0, 1.0, 3000.0]\nmaterial = \"titanium\"\ntranslation_mm = [0.0, -400.0, 0.0]\n"
    );
    let base = render(dir.path(), "pbase", physics, &[]);
    let with = render(dir.path(), "pslab", &slab, &[]);
    for (a, b) in base.iter().zip(&with) {
        // 1 mm of titanium passes 60–80 % of a 100 kVp beam, less behind more tissue
        // (harder beam: more); never more than without it.
        let ratio = b / a;
        assert!((0.5..0.9).contains(&ratio), "{a} → {b}");
    }
    let one = render(dir.path(), "pone", &slab, &["--threads", "1"]);
    assert_eq!(one, with);
    let pm = format!(
        "{physics}[[mesh]]\nname = \"pm\"\nkind = \"pacemaker\"\nmaterial = \"titanium\"\ndensity_g_cm3 = 4.5\ntranslation_mm = [60.0, -90.0, 40.0]\n"
    );
    let with_pm = render(dir.path(), "ppm", &pm, &[]);
    let changed = base.iter().zip(&with_pm).filter(|(a, b)| a != b).count();
    assert!(changed > 5 && changed < base.len() / 4, "{changed}");
    let bad = scene(
        dir.path(),
        "pbad",
        &format!(
            "{physics}[[mesh]]\nname = \"thing\"\nkind = \"box\"\nmaterial = \"titanium\"\nmu_per_mm = 0.1\n"
        ),
    );
    let out = tomograf(&["project", "--scene", &bad]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("mu_per_mm is for the ideal DRR"),
        "{err}"
    );
}

/// `kind = "cylinder"` is an exact solid (issue 25): a 200 mm water-like cylinder
/// (mu 0.02 mm⁻¹) in front of the patient, its axis along z, adds exactly mu × 2r = 4 to
/// the central pixel of an odd detector (whose ray crosses the axis at right angles),
/// whatever its rotation about the axis; the same cylinder as 64 facets (`resolution`),
/// turned so the ray crosses two edge midpoints, is short by 1 − cos(π/64) = 0.12 %.
/// Tolerance 1e-4: the f32 pixels are ~5, so their difference carries ~1e-6 of rounding.
#[test]
fn an_exact_cylinder_adds_its_diameter_and_a_faceted_one_falls_short() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, mesh: &str| {
        let path = dir.path().join(format!("{name}.toml"));
        std::fs::write(
            &path,
            format!(
                "[volume]\nphantom_dims = [48, 48, 20]\nphantom_spacing_mm = [7.5, 7.5, 16.0]\n[detector]\nrows = 33\ncols = 33\npitch_mm = [2.0, 2.0]\n[views]\nposes = [\"ap\"]\n[output]\ndir = \"{}\"\nformats = [\"npy\"]\n{mesh}",
                dir.path().join(name).display()
            ),
        )
        .unwrap();
        let out = tomograf(&["project", "--scene", path.to_str().unwrap()]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let bytes = std::fs::read(dir.path().join(name).join("drr.npy")).unwrap();
        let v = npyz::NpyFile::new(&bytes[..])
            .unwrap()
            .into_vec::<f32>()
            .unwrap();
        f64::from(v[16 * 33 + 16])
    };
    let cylinder = |extra: &str| {
        format!(
            "[[mesh]]\nname = \"cyl\"\nkind = \"cylinder\"\nradius_mm = 100.0\nheight_mm = 400.0\nmu_per_mm = 0.02\ntranslation_mm = [0.0, -400.0, 0.0]\n{extra}"
        )
    };
    let base = write("base", "");
    for (name, rotation) in [("exact0", 0.0), ("exact1", 2.8125), ("exact2", 17.0)] {
        let got = write(
            name,
            &cylinder(&format!("rotation_deg = [0.0, 0.0, {rotation}]\n")),
        ) - base;
        assert!((got - 4.0).abs() < 1e-4, "{name}: {got}");
    }
    let faceted = write(
        "facets",
        &cylinder("resolution = 64\nrotation_deg = [0.0, 0.0, 2.8125]\n"),
    ) - base;
    let short = 1.0 - faceted / 4.0;
    let expect = 1.0 - (std::f64::consts::PI / 64.0).cos();
    assert!(
        (short - expect).abs() < 5e-5,
        "short by {short}, expected {expect}"
    );
    // Clear errors for exact-solid keys where they do not apply.
    for (mesh, words) in [
        (cylinder("exact = true\nresolution = 64\n"), "drop one of them"),
        (
            "[[mesh]]\nname = \"cyl\"\nkind = \"pacemaker\"\nexact = true\nmu_per_mm = 0.1\n"
                .to_string(),
            "exact = true is for",
        ),
        (
            "[[mesh]]\nname = \"cyl\"\nkind = \"sphere\"\nradii_mm = [1.0, 2.0, 3.0]\nmu_per_mm = 0.1\n"
                .to_string(),
            "radii_mm is for kind = \"ellipsoid\"",
        ),
        (
            "[[mesh]]\nname = \"cyl\"\nkind = \"ellipsoid\"\nradii_mm = [1.0, 0.0, 3.0]\nmu_per_mm = 0.1\n"
                .to_string(),
            "ellipsoid radius y is 0",
        ),
    ] {
        let path = dir.path().join("bad.toml");
        std::fs::write(&path, format!("[views]\nposes = [\"ap\"]\n{mesh}")).unwrap();
        let out = tomograf(&["project", "--scene", path.to_str().unwrap(), "-o", dir.path().join("bad").to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(words) && err.contains("cyl"), "{mesh}: {err}");
    }
}
