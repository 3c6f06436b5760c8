//! Numerical extremes through the command line (issue 23): a 1×1×1 volume, a
//! 2×2048×2048 slab, one voxel of μ = 10⁶ mm⁻¹, and a 1-keV-wide spectrum each render a
//! finite image that equals its closed form; a source inside the volume renders a finite
//! image with a warning. Parallel beams with 1 mm pixels keep the expected values exact.

mod common;

use common::{nifti_f32, ok, read_npy, tomograf};

/// Projects `input` with `args`, returns the image(s) and stderr.
fn project(input: &std::path::Path, out: &std::path::Path, args: &[&str]) -> (Vec<f32>, String) {
    let mut a = vec!["project", input.to_str().unwrap()];
    a.extend(args);
    a.extend(["--format", "npy", "-o", out.to_str().unwrap()]);
    let o = tomograf(&a);
    ok(&o);
    let (_, v) = read_npy(&out.join("drr.npy"));
    assert!(
        v.iter().all(|x| x.is_finite()),
        "non-finite pixel: {args:?}"
    );
    (v, String::from_utf8_lossy(&o.stderr).into_owned())
}

const PARALLEL: [&str; 8] = [
    "--beam", "parallel", "--pitch", "1,1", "--rows", "5", "--cols", "5",
];

/// One 10 mm voxel of μ = 0.02 mm⁻¹: every central parallel ray crosses 10 mm (0.2,
/// exact to f32 rounding).
#[test]
fn a_one_voxel_volume() {
    let d = tempfile::tempdir().unwrap();
    let v = d.path().join("one.nii");
    nifti_f32(&v, [1, 1, 1], [10.0; 3], &[0.02]);
    let mut a = vec!["--units", "mu"];
    a.extend(PARALLEL);
    let (img, _) = project(&v, &d.path().join("o"), &a);
    for x in img {
        assert!((x - 0.2).abs() < 1e-6, "{x}");
    }
}

/// A 2×2048×2048 slab (0.1 mm voxels, μ = 0.5 mm⁻¹, 0.2 mm thick along x) seen
/// laterally: every ray crosses the 0.2 mm, so every pixel is 0.1.
#[test]
fn a_thin_wide_slab() {
    let d = tempfile::tempdir().unwrap();
    let v = d.path().join("slab.nii");
    nifti_f32(
        &v,
        [2, 2048, 2048],
        [0.1; 3],
        &vec![0.5f32; 2 * 2048 * 2048],
    );
    let mut a = vec!["--units", "mu", "--view", "lateral"];
    a.extend(PARALLEL);
    let (img, _) = project(&v, &d.path().join("o"), &a);
    for x in img {
        assert!((x - 0.1).abs() < 1e-6, "{x}");
    }
}

/// One voxel of μ = 10⁶ mm⁻¹ in air: its pixel's line integral is 10⁶ (f32 holds it
/// exactly), its transmission exactly 0 (exp underflows to 0, never NaN), and every
/// other pixel's transmission exactly 1.
#[test]
fn an_enormous_attenuation() {
    let d = tempfile::tempdir().unwrap();
    let v = d.path().join("dense.nii");
    let mut data = vec![0.0f32; 5 * 5 * 5];
    data[2 + 5 * (2 + 5 * 2)] = 1e6;
    nifti_f32(&v, [5, 5, 5], [1.0; 3], &data);
    let mut a = vec!["--units", "mu"];
    a.extend(PARALLEL);
    let (img, _) = project(&v, &d.path().join("li"), &a);
    let centre = img[2 * 5 + 2];
    assert!((f64::from(centre) - 1e6).abs() < 1e-6 * 1e6, "{centre}");
    assert_eq!(img.iter().filter(|&&x| x != 0.0).count(), 1, "{img:?}");
    a.extend(["--quantity", "transmission"]);
    let (t, _) = project(&v, &d.path().join("t"), &a);
    assert_eq!(t[2 * 5 + 2], 0.0);
    assert!(
        t.iter().enumerate().all(|(i, &x)| i == 12 || x == 1.0),
        "{t:?}"
    );
}

/// A 1-keV-wide beam (two 0.5 keV bins about 60 keV) through 10 mm of water with the
/// perfect absorber: its −log equals the ideal DRR's μ_water(60 keV)·10 mm to 1 %
/// (water's μ changes by ~0.5 % over ±0.5 keV at 60 keV).
#[test]
fn a_one_kev_wide_spectrum() {
    let d = tempfile::tempdir().unwrap();
    let v = d.path().join("water.nii");
    nifti_f32(&v, [1, 1, 1], [10.0; 3], &[0.0]);
    let spectrum = d.path().join("narrow.txt");
    std::fs::write(&spectrum, "59.75 1000\n60.25 1000\n").unwrap();
    let scene = d.path().join("narrow.toml");
    std::fs::write(
        &scene,
        format!(
            "[spectrum]\nfile = \"{}\"\nmas = 1000.0\n[materials]\nmodel = \"water\"\n[detector]\nmodel = \"perfect-absorber\"\n",
            spectrum.display()
        ),
    )
    .unwrap();
    let mut a = vec!["--scene", scene.to_str().unwrap()];
    a.extend(PARALLEL);
    let (poly, _) = project(&v, &d.path().join("poly"), &a);
    let mut m = vec!["--energy-kev", "60"];
    m.extend(PARALLEL);
    let (mono, _) = project(&v, &d.path().join("mono"), &m);
    for (p, q) in poly.iter().zip(&mono) {
        assert!(*q > 0.1, "{q}");
        assert!(((p - q) / q).abs() < 0.01, "poly {p} vs mono {q}");
    }
}

/// The source 10 mm from the isocentre, inside the volume: a finite image and a warning.
#[test]
fn a_source_inside_the_volume() {
    let d = tempfile::tempdir().unwrap();
    let v = d.path().join("cube.nii");
    nifti_f32(&v, [10, 10, 10], [10.0; 3], &vec![0.0f32; 1000]);
    let (img, err) = project(
        &v,
        &d.path().join("o"),
        &[
            "--sad", "10", "--sid", "1500", "--rows", "16", "--cols", "16", "--pitch", "2,2",
        ],
    );
    assert!(err.contains("the source lies inside the volume"), "{err}");
    assert!(img.iter().any(|&x| x > 0.0));
}
