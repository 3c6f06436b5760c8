//! The bad-input catalogue (issue 23): one table of inputs a user may give — files
//! tomograf did not write, impossible geometry, sizes beyond memory, corrupt checkpoints —
//! each with the words its error must contain. Every row must end with a non-zero exit,
//! no panic, no abort, within a time limit (a hang fails), and the named words on stderr.
//! `TOMOGRAF_MEMORY_LIMIT_GB=8` makes the "beyond memory" rows independent of the machine.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs the binary with `args` under a memory limit of 8 GiB, killing it after `limit`.
/// Returns (exit code, stderr), or `None` on a timeout.
fn run(args: &[String], limit: Duration) -> Option<(Option<i32>, String)> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tomograf"))
        .args(args)
        .env("TOMOGRAF_MEMORY_LIMIT_GB", "8")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("waits") {
            let mut err = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            return Some((status.code(), err));
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// Writes `mean_volume.npy` of shape `dims` (z, y, x) holding `data`, f32 little-endian.
fn npy(path: &Path, shape: [u64; 3], data: &[f32]) {
    use npyz::WriterBuilder;
    let mut out = Vec::new();
    {
        let mut w = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&shape)
            .writer(&mut out)
            .begin_nd()
            .unwrap();
        w.extend(data.iter().copied()).unwrap();
        w.finish().unwrap();
    }
    std::fs::write(path, out).unwrap();
}

/// Copies the files of `from` into `to` (sub-folders are left out).
fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            continue;
        }
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
}

/// Overwrites the 16-bit value of the first explicit-VR little-endian US element `tag`
/// (group, element) in a DICOM file.
fn patch_us(path: &Path, tag: (u16, u16), value: u16) {
    let mut b = std::fs::read(path).unwrap();
    let mut pat = Vec::new();
    pat.extend_from_slice(&tag.0.to_le_bytes());
    pat.extend_from_slice(&tag.1.to_le_bytes());
    pat.extend_from_slice(b"US\x02\x00");
    let at = b
        .windows(pat.len())
        .position(|w| w == pat.as_slice())
        .expect("tag present")
        + pat.len();
    b[at..at + 2].copy_from_slice(&value.to_le_bytes());
    std::fs::write(path, b).unwrap();
}

/// Overwrites the tag, or the value, of the first explicit-VR little-endian DS element
/// `tag` in a DICOM file: `value` (same length as the old one) and/or `new_tag`.
fn patch_ds(path: &Path, tag: (u16, u16), new_tag: Option<(u16, u16)>, value: Option<&str>) {
    let mut b = std::fs::read(path).unwrap();
    let mut pat = Vec::new();
    pat.extend_from_slice(&tag.0.to_le_bytes());
    pat.extend_from_slice(&tag.1.to_le_bytes());
    pat.extend_from_slice(b"DS");
    let at = b
        .windows(pat.len())
        .position(|w| w == pat.as_slice())
        .expect("tag present");
    if let Some(t) = new_tag {
        b[at..at + 2].copy_from_slice(&t.0.to_le_bytes());
        b[at + 2..at + 4].copy_from_slice(&t.1.to_le_bytes());
    }
    if let Some(v) = value {
        let len = u16::from_le_bytes([b[at + 6], b[at + 7]]) as usize;
        assert_eq!(v.len(), len, "same length as the old value");
        b[at + 8..at + 8 + len].copy_from_slice(v.as_bytes());
    }
    std::fs::write(path, b).unwrap();
}

#[test]
fn every_bad_input_ends_in_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |name: &str| d.join(name);
    let out = |name: &str| s(&p(name));

    // Fixtures: small valid files, then broken copies.
    let small = ["--phantom-dims", "16,16,8", "--phantom-spacing", "20,20,40"];
    let proj = p("proj");
    let mut a = vec!["project".to_string()];
    a.extend(small.iter().map(|x| x.to_string()));
    a.extend(["--rows", "16", "--cols", "16", "--arc", "0:30:12", "-o"].map(String::from));
    a.push(s(&proj));
    common::ok(&common::tomograf(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
    ));
    common::ok(&common::tomograf(&[
        "dataset",
        "-o",
        &out("data"),
        "--phantoms",
        "1",
        "--size",
        "16",
        "--views",
        "10",
    ]));
    let item = s(&p("data").join("00000"));
    common::ok(&common::tomograf(&[
        "phantom",
        "-o",
        &out("ct.nii"),
        "--dims",
        "16,16,8",
        "--spacing",
        "20,20,40",
    ]));
    common::ok(&common::tomograf(&[
        "phantom",
        "--dicom",
        "-o",
        &out("dicom"),
        "--dims",
        "16,16,4",
        "--spacing",
        "20,20,40",
    ]));
    // Truncated and garbage volumes.
    let ct = std::fs::read(p("ct.nii")).unwrap();
    std::fs::write(p("truncated.nii"), &ct[..ct.len() / 2]).unwrap();
    std::fs::write(p("garbage.nii"), vec![0x5au8; 600]).unwrap();
    std::fs::write(p("empty.nii"), b"").unwrap();
    let mut nan = vec![-1000.0f32; 8 * 8 * 8];
    nan[100] = f32::NAN;
    common::nifti_f32(&p("nan.nii"), [8, 8, 8], [1.0; 3], &nan);
    let mut inf = vec![0.0f32; 8 * 8 * 8];
    inf[7] = f32::INFINITY;
    common::nifti_f32(&p("inf.nii"), [8, 8, 8], [1.0; 3], &inf);
    std::fs::create_dir_all(p("no-dicom")).unwrap();
    std::fs::write(p("no-dicom").join("readme.txt"), "not DICOM").unwrap();
    // A DICOM series whose headers claim half the rows of the pixel data.
    copy_dir(&p("dicom"), &p("dicom-rows"));
    for e in std::fs::read_dir(p("dicom-rows")).unwrap() {
        patch_us(&e.unwrap().path(), (0x0028, 0x0010), 8);
    }
    // DICOM rescale: slope 0 (every voxel the intercept), slope −1, no slope at all
    // (the tag renumbered to RescaleType, which the writer does not use).
    for (name, value) in [("dicom-slope0", "0 "), ("dicom-slope-neg", "-1")] {
        copy_dir(&p("dicom"), &p(name));
        for e in std::fs::read_dir(p(name)).unwrap() {
            patch_ds(&e.unwrap().path(), (0x0028, 0x1053), None, Some(value));
        }
    }
    copy_dir(&p("dicom"), &p("dicom-no-slope"));
    for e in std::fs::read_dir(p("dicom-no-slope")).unwrap() {
        patch_ds(
            &e.unwrap().path(),
            (0x0028, 0x1053),
            Some((0x0028, 0x1054)),
            None,
        );
    }
    // A NIfTI sform that puts the first voxel 10³⁰ mm away.
    common::nifti_f32(&p("far.nii"), [8, 8, 8], [1.0; 3], &vec![0.0f32; 8 * 8 * 8]);
    let mut far = std::fs::read(p("far.nii")).unwrap();
    far[254..256].copy_from_slice(&1i16.to_le_bytes()); // sform_code
    for (row, values) in [
        [1.0f32, 0.0, 0.0, 1e30],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]
    .iter()
    .enumerate()
    {
        for (c, v) in values.iter().enumerate() {
            let at = 280 + 16 * row + 4 * c;
            far[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(p("far.nii"), far).unwrap();
    // Meshes.
    // A binary STL header announcing 10 triangles, then half of one.
    let mut stl = vec![0u8; 80];
    stl.extend_from_slice(&10u32.to_le_bytes());
    stl.extend_from_slice(&[0u8; 25]);
    std::fs::write(p("cut.stl"), stl).unwrap();
    std::fs::write(p("bad.obj"), "v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap();
    // Spectra.
    std::fs::write(p("negative.txt"), "20 1.0\n30 -2.0\n40 1.0\n").unwrap();
    std::fs::write(p("words.txt"), "kev fluence\nabc def\n").unwrap();
    // A regular file where a folder must go.
    std::fs::write(p("file"), "x").unwrap();
    let under_file = s(&p("file").join("sub"));
    // Checkpoints: the shipped demo model, then corrupt copies.
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("model/checkpoints/demo");
    let broken = |name: &str, f: &dyn Fn(&Path)| -> String {
        let c = p(name);
        copy_dir(&demo, &c);
        f(&c);
        s(&c)
    };
    let empty_bpk = broken("ck-empty-bpk", &|c| {
        std::fs::write(c.join("generator.bpk"), b"").unwrap()
    });
    let zero_scale = broken("ck-zero-scale", &|c| {
        let t = std::fs::read_to_string(c.join("state.json")).unwrap();
        let mut j: serde_json::Value = serde_json::from_str(&t).unwrap();
        j["proj_scale"] = serde_json::json!(0.0);
        std::fs::write(c.join("state.json"), j.to_string()).unwrap();
    });
    let huge_scale = broken("ck-huge-scale", &|c| {
        let t = std::fs::read_to_string(c.join("state.json")).unwrap();
        let mut j: serde_json::Value = serde_json::from_str(&t).unwrap();
        j["proj_scale"] = serde_json::json!(1e308);
        std::fs::write(c.join("state.json"), j.to_string()).unwrap();
    });
    let nan_mean = broken("ck-nan-mean", &|c| {
        npy(
            &c.join("mean_volume.npy"),
            [2, 2, 2],
            &[0.0, 1.0, f32::NAN, 0.0, 0.0, 0.0, 0.0, 0.0],
        )
    });
    let huge_mean = broken("ck-huge-mean", &|c| {
        npy(&c.join("mean_volume.npy"), [2, 2, 2], &[1e30; 8])
    });
    let cut_mean = broken("ck-cut-mean", &|c| {
        let b = std::fs::read(c.join("mean_volume.npy")).unwrap();
        std::fs::write(c.join("mean_volume.npy"), &b[..b.len() - 100]).unwrap();
    });
    let no_mean = broken("ck-no-mean", &|c| {
        std::fs::remove_file(c.join("mean_volume.npy")).unwrap()
    });
    let other_preset = broken("ck-other-preset", &|c| {
        let t = std::fs::read_to_string(c.join("config.toml")).unwrap();
        std::fs::write(
            c.join("config.toml"),
            t.replace("hidden = 128", "hidden = 64"),
        )
        .unwrap();
    });
    // Scenes.
    let scene = |name: &str, text: &str| -> String {
        let f = p(&format!("{name}.toml"));
        std::fs::write(&f, text).unwrap();
        s(&f)
    };
    let small_scene = "[volume]\nphantom_dims = [16, 16, 8]\nphantom_spacing_mm = [20.0, 20.0, 40.0]\n[detector]\nrows = 16\ncols = 16\n";

    // Data sets: a manifest that lists its item twice; an item whose projections are all 0.
    let data = p("data");
    let dup = p("data-dup");
    copy_dir(&data, &dup);
    copy_dir(&data.join("00000"), &dup.join("00000"));
    let line = std::fs::read_to_string(data.join("manifest.jsonl")).unwrap();
    std::fs::write(dup.join("manifest.jsonl"), format!("{line}{line}")).unwrap();
    let air = p("data-air");
    copy_dir(&data, &air);
    copy_dir(&data.join("00000"), &air.join("00000"));
    npy(
        &air.join("00000").join("projections.npy"),
        [12, 16, 16], // 10 views of the orbit, AP and lateral
        &[0.0; 12 * 16 * 16],
    );

    // A training config whose batch alone needs terabytes (it was an abort after 24 GB).
    let tiny = include_str!("../model/presets/tiny.toml");
    assert!(tiny.contains("\nbatch = 2\n"));
    let big_batch = scene(
        "big-batch",
        &tiny.replace("\nbatch = 2\n", "\nbatch = 100000000\n"),
    );

    let proj_s = s(&proj);
    let cut_proj = p("proj-cut");
    copy_dir(&proj, &cut_proj);
    let b = std::fs::read(cut_proj.join("drr.npy")).unwrap();
    std::fs::write(cut_proj.join("drr.npy"), &b[..b.len() - 100]).unwrap();
    let o = out("o");
    // (arguments, words the error must contain)
    let rows: Vec<(Vec<String>, &str)> = vec![
        // Sizes beyond memory and counts beyond reason.
        (vec!["project", "--arc", "0:5:1000000000", "-o", &o].map_into(), "more than 1000000 in one job"),
        (vec!["project", "--scene", &scene("arc", &format!("{small_scene}[views]\narc = \"0:5:1000000000\"\n")), "-o", &o].map_into(), "more than 1000000"),
        (vec!["project", "--arc", "0:1:500000", "--rows", "256", "--cols", "256", "-o", &o].map_into(), "held as f32 images needs"),
        // 2.5 GiB of images fit the 8 GiB; the render's peak (≈ 3.8 × the images) does not.
        (vec!["project", "--arc", "0:0.03515625:10240", "--rows", "256", "--cols", "256", "-o", &o].map_into(), "rendering 10240 views (671088640 pixels in all) of a"),
        (vec!["project", "--scene", &scene("cyl", &format!("{small_scene}[[mesh]]\nname = \"c\"\nkind = \"cylinder\"\nresolution = 4000000000\nmu_per_mm = 0.1\n")), "-o", &o].map_into(), "segments"),
        (vec!["reconstruct-classical", &proj_s, "--dims", "100000,100000,100000", "-o", &out("r.nii")].map_into(), "exceed the limit"),
        (vec!["reconstruct-classical", &proj_s, "--dims", "2400,2400,2400", "-o", &out("r.nii")].map_into(), "more than the 8.0 GiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        // 1.3 GiB of volume, but SART-TV holds ≈ 7.7 of them (the job's peak, not its output).
        (vec!["reconstruct-classical", &proj_s, "--method", "sart-tv", "--dims", "700,700,700", "-o", &out("r.nii")].map_into(), "SART-TV onto a 700×700×700 grid from 12 views (--dims, --like or --views set both) needs 9.9 GiB, more than the 8.0 GiB"),
        (vec!["project", "--phantom-dims", "2400,2400,2400", "-o", &o].map_into(), "more than the 8.0 GiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        (vec!["phantom", "--dims", "2400,2400,2400", "-o", &out("big.nii")].map_into(), "more than the 8.0 GiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        // Runaway settings.
        (vec!["project", "--projector", "trilinear", "--step", "1e-9", "-o", &o].map_into(), "≥ 0.001"),
        (vec!["--threads", "100000", "project", "-o", &o].map_into(), "give 1 to 1024"),
        (vec!["--threads", "0", "project", "-o", &o].map_into(), "give 1 to 1024"),
        // Impossible or silently wrong geometry.
        (vec!["project", "--sad", "1e300", "-o", &o].map_into(), "at most 100000 mm"),
        (vec!["project", "--sid", "nan", "-o", &o].map_into(), "SID is NaN"),
        (vec!["project", "--sad", "1000", "--sid", "900", "-o", &o].map_into(), "smaller than SAD"),
        (vec!["project", "--isocentre", "5000,0,0", "--pitch", "1.5,1.5", "-o", &o].map_into(), "no ray of any view meets the volume"),
        (vec!["project", "--offset", "1e9,0", "-o", &o].map_into(), "no ray of any view meets the volume"),
        (vec!["project", "--view", "sideways", "-o", &o].map_into(), "neither a named view"),
        (vec!["project", "--arc", "0:5:0", "-o", &o].map_into(), "at least one view"),
        (vec!["project", "--rows", "0", "-o", &o].map_into(), "0"),
        (vec!["project", "--rows", "1", "--cols", "1", "-o", &o].map_into(), "a 1 × 1 detector"),
        (vec!["project", &out("ct.nii"), "--phantom-dims", "16,16,16", "-o", &o].map_into(), "are for the built-in phantom"),
        (vec!["project", "--beam", "parallel", "--sad", "1000", "-o", &o].map_into(), "do not apply to a parallel beam"),
        // Volumes tomograf did not write.
        (vec!["project", &out("truncated.nii"), "-o", &o].map_into(), "truncated.nii"),
        (vec!["project", &out("garbage.nii"), "-o", &o].map_into(), "garbage.nii"),
        (vec!["project", &out("empty.nii"), "-o", &o].map_into(), "empty.nii"),
        (vec!["project", &out("nan.nii"), "-o", &o].map_into(), "NaN"),
        (vec!["project", &out("inf.nii"), "-o", &o].map_into(), "inf"),
        (vec!["project", &out("missing.nii"), "-o", &o].map_into(), "missing.nii"),
        (vec!["project", &out("no-dicom"), "-o", &o].map_into(), "no-dicom"),
        (vec!["project", &out("dicom-rows"), "-o", &o].map_into(), "do not describe the pixel data"),
        (vec!["project", &out("dicom-slope0"), "-o", &o].map_into(), "RescaleSlope (0028,1053): 0: it must be finite and positive"),
        (vec!["project", &out("dicom-slope-neg"), "-o", &o].map_into(), "RescaleSlope (0028,1053): -1: it must be finite and positive"),
        (vec!["project", &out("dicom-no-slope"), "-o", &o].map_into(), "a CT slice without RescaleSlope (0028,1053)"),
        (vec!["project", &out("far.nii"), "-o", &o].map_into(), "beyond ±1e6 mm (1 km) of the world origin"),
        (vec!["project", &out("ct.nii"), "--units", "furlongs", "-o", &o].map_into(), "furlongs"),
        // Meshes and scenes typed by hand.
        (vec!["project", "--scene", &scene("stl", &format!("{small_scene}[[mesh]]\nname = \"m\"\npath = \"{}\"\nmu_per_mm = 0.1\n", out("cut.stl"))), "-o", &o].map_into(), "ends early"),
        (vec!["project", "--scene", &scene("obj", &format!("{small_scene}[[mesh]]\nname = \"m\"\npath = \"{}\"\nmu_per_mm = 0.1\n", out("bad.obj"))), "-o", &o].map_into(), "bad.obj"),
        (vec!["project", "--scene", &scene("unknown-key", "[volume]\ncolour = 1\n"), "-o", &o].map_into(), "unknown field `colour`"),
        // The top of the detector's range, once blamed on too few photons ("raise the exposure").
        (vec!["project", "--scene", &scene("adc8", &format!("{small_scene}[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[detector.response]\nquantum_noise = true\n[detector.response.mode]\nkind = \"energy-integrating\"\nconversion_gain_adu_per_kev = 0.3125\nswank_factor = 0.9\n[detector.response.scintillator]\nmaterial = \"CsI\"\nthickness_mm = 0.6\n[detector.response.readout]\noffset_adu = 1000.0\nelectronic_noise_adu = 23.4\nbits = 8\n")), "-o", &o].map_into(), "the dark field is already at the detector's ceiling (255 of 255 ADU"),
        (vec!["project", "--phantom-dims", "16,16,8", "--phantom-spacing", "20,20,40", "--rows", "16", "--cols", "16", "--preset", "kv-flat-panel-120kvp", "--mas", "1e30", "--detector-model", "noiseless-csi", "-o", &o].map_into(), "the open beam's signal is inf: it overflows float32; lower the exposure (mas)"),
        (vec!["project", "--scene", &scene("not-toml", "[volume\n"), "-o", &o].map_into(), "not valid"),
        (vec!["project", "--scene", &out("no-such-scene.toml"), "-o", &o].map_into(), "no-such-scene.toml"),
        (vec!["project", "--scene", &scene("mat", &format!("{small_scene}[[mesh]]\nname = \"m\"\nkind = \"sphere\"\nmaterial = \"unobtainium\"\n")), "-o", &o].map_into(), "unknown material: 'unobtainium'"),
        (vec!["project", "--scene", &scene("exact", &format!("{small_scene}[[mesh]]\nname = \"m\"\nkind = \"cylinder\"\nexact = true\nresolution = 8\nmu_per_mm = 0.1\n")), "-o", &o].map_into(), "drop one of them"),
        (vec!["project", "--scene", &scene("blend", &format!("{small_scene}[spectrum]\nkvp = 100\n[materials]\nblend_hu = 500\n")), "-o", &o].map_into(), "not narrower than 'adipose'"),
        (vec!["project", "--scene", &scene("dose-drr", &format!("{small_scene}[dose]\nphotons = 1000\n")), "-o", &o].map_into(), "[dose] needs real detector physics"),
        (vec!["project", "--scene", &scene("dose-zero", &format!("{small_scene}[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[dose]\nphotons = 0\n")), "-o", &o].map_into(), "[dose] photons = 0"),
        // Physics out of range.
        (vec!["project", "--preset", "kv-flat-panel-1000kvp", "-o", &o].map_into(), "kv-flat-panel-1000kvp"),
        (vec!["project", "--kvp", "1000", "-o", &o].map_into(), "1000"),
        (vec!["project", "--kvp", "100", "--mas=-1", "-o", &o].map_into(), "mas = -1; it must be finite and > 0"),
        (vec!["project", "--preset", "kv-flat-panel-120kvp", "--mas", "1e30", "--noise-seed", "1", "-o", &o].map_into(), "lower the mAs"),
        (vec!["project", "--kvp", "100", "--detector-model", "superconducting", "-o", &o].map_into(), "superconducting"),
        (vec!["project", "--energy-kev", "0", "-o", &o].map_into(), "keV"),
        (vec!["project", "--projector", "montecarlo", "-o", &o].map_into(), "unknown projector 'montecarlo'"),
        (vec!["project", "--scene", &scene("spec-neg", &format!("{small_scene}[spectrum]\nfile = \"{}\"\n", out("negative.txt"))), "-o", &o].map_into(), "negative.txt"),
        (vec!["project", "--scene", &scene("spec-words", &format!("{small_scene}[spectrum]\nfile = \"{}\"\n", out("words.txt"))), "-o", &o].map_into(), "words.txt"),
        // Outputs where a file is.
        (vec!["project", "-o", &under_file].map_into(), "file"),
        (vec!["reconstruct-classical", &proj_s, "--dims", "8,8,8", "-o", &s(&p("file").join("sub").join("r.nii"))].map_into(), "cannot create the output folder"),
        (vec!["train", &out("data"), "-o", &under_file, "--config", "tiny", "--iterations", "1"].map_into(), "cannot create the output folder"),
        // Evaluation and inference.
        (vec!["evaluate", &out("data"), "--items", "0", "-o", &out("ev")].map_into(), "--items 0 scores nothing"),
        (vec!["train", &out("data"), "-o", &out("tr-big"), "--config", &big_batch, "--iterations", "1"].map_into(), "training 'tiny' (batch 100000000, patch 8², samples 8, hidden 32, depth 2: lower these in the config) on 1 item(s) of 0.0 MiB (estimated peak 52.2 TiB), beyond what is already held, needs"),
        (vec!["train", &out("data-dup"), "-o", &out("tr-dup"), "--config", "tiny", "--iterations", "1"].map_into(), "line 2: item '00000' is listed twice (also on line 1)"),
        (vec!["train", &out("data-air"), "-o", &out("tr-air"), "--config", "tiny", "--iterations", "1"].map_into(), "every projection value is 0"),
        (vec!["evaluate", &out("data"), "--scatter-correction", "prior", "-o", &out("ev-sc")].map_into(), "give --checkpoint or --train-data"),
        (vec!["evaluate", &out("data"), "--scatter-correction", "sideways", "-o", &out("ev-sc2")].map_into(), "expected 'none', 'prior' or 'oracle'"),
        (vec!["reconstruct", &item, "--checkpoint", &s(&demo), "--scatter-correction", "prior", "-o", &out("rec.nii")].map_into(), "has no scatter to correct"),
        (vec!["reconstruct", &item, "--checkpoint", &s(&demo), "--iterations", "0", "-o", &out("rec.nii")].map_into(), "at least 1"),
        (vec!["reconstruct", &item, "--checkpoint", &empty_bpk, "-o", &out("rec.nii")].map_into(), "empty, truncated or corrupt"),
        (vec!["reconstruct", &item, "--checkpoint", &zero_scale, "-o", &out("rec.nii")].map_into(), "proj_scale = 0"),
        (vec!["reconstruct", &item, "--checkpoint", &huge_scale, "-o", &out("rec.nii")].map_into(), "must be finite and in (0, 1e6]"),
        (vec!["reconstruct", &item, "--checkpoint", &nan_mean, "-o", &out("rec.nii")].map_into(), "mean_volume.npy"),
        (vec!["reconstruct", &item, "--checkpoint", &huge_mean, "-o", &out("rec.nii")].map_into(), "mean_volume.npy: value 0 is 1e30, outside [0, 1]"),
        (vec!["reconstruct", &item, "--checkpoint", &cut_mean, "-o", &out("rec.nii")].map_into(), "truncated or corrupt NPY"),
        (vec!["reconstruct", &item, "--checkpoint", &no_mean, "-o", &out("rec.nii")].map_into(), "missing"),
        (vec!["reconstruct", &item, "--checkpoint", &other_preset, "-o", &out("rec.nii")].map_into(), "generator.bpk"),
        (vec!["reconstruct", &item, "--checkpoint", &out("no-checkpoint"), "-o", &out("rec.nii")].map_into(), "no-checkpoint"),
        (vec!["reconstruct-classical", &out("no-proj"), "--dims", "8,8,8", "-o", &out("r.nii")].map_into(), "no-proj"),
        // Issue 51: counts and sizes that would overflow, abort or never end.
        (vec!["dataset", "-o", &out("ds-big"), "--phantoms", "18446744073709551615"].map_into(), "at most 1000000 per data set"),
        (vec!["dataset", "-o", &out("ds-seed"), "--phantoms", "3", "--seed", "18446744073709551615"].map_into(), "would pass 2^64 − 1"),
        (vec!["dataset", "-o", &out("ds-views"), "--phantoms", "1", "--size", "256", "--views", "200000"].map_into(), "an item of 200002 views"),
        (vec!["demo", "--phantoms", "1000000000000000", "-o", &out("demo-big")].map_into(), "--phantoms"),
        (vec!["demo", "--train-phantoms", "1000000000000000", "-o", &out("demo-big2")].map_into(), "--train-phantoms"),
        (vec!["dataset", "-o", &out("ds-kev"), "--phantoms", "1", "--size", "8", "--views", "2", "--energy-kev", "-60"].map_into(), "-60 keV"),
        (vec!["project", "--scene", &scene("blur-huge", &format!("{small_scene}[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[detector.response.blur]\nsigma_mm = 1e9\n")), "-o", &o].map_into(), "blur sigma is 1000000000 mm"),
        (vec!["project", "--scene", &scene("frames-huge", &format!("{small_scene}[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[detector.response.calibration]\nflat_frames = 1000000000\n")), "-o", &o].map_into(), "flat_frames = 1000000000"),
        (vec!["reconstruct-classical", &proj_s, "--dims", "8,8,8", "-o", &format!("{}/", out("recdir"))].map_into(), "that is a folder"),
        (vec!["reconstruct-classical", &proj_s, "--dims", "8,8,8", "-o", &s(d)].map_into(), "that is a folder"),
        (vec!["reconstruct-classical", &proj_s, "--method", "fdk", "--views", "3,3,3", "--dims", "8,8,8", "-o", &out("dup.nii")].map_into(), "view 3 is listed more than once"),
        // Refused before the reconstruction, not after it (it once ran the whole job first).
        (vec!["reconstruct-classical", &proj_s, "--dims", "3000,3000,3000", "--energy-kev=-60", "-o", &out("kev.nii")].map_into(), "--energy-kev: out of range: effective energy -60 keV is outside the water attenuation table"),
        (vec!["reconstruct-classical", &proj_s, "--dims", "8,8,8", "--spacing", "1e300", "-o", &out("sp.nii")].map_into(), "--spacing 1e300"),
        (vec!["project", "--phantom-dims", "16,16,8", "--rows", "8", "--cols", "8", "--quantity", "intensity", "--i0", "1e39", "-o", &o].map_into(), "images are float32"),
        (vec!["reconstruct-classical", &s(&cut_proj), "--dims", "8,8,8", "-o", &out("cut.nii")].map_into(), "the file ends before them"),
        (vec!["project", "--scene", &scene("mu-huge", &format!("{small_scene}[[mesh]]\nname = \"s\"\nkind = \"sphere\"\nradius_mm = 50\nmu_per_mm = 1e38\n")), "-o", &out("mu-huge")].map_into(), "overflows float32"),
        (vec!["tradeoff", "--phantom-dims", "16,16,8", "--rows", "8", "--cols", "8", "--repeats", "0", "--report", &out("t0")].map_into(), "--repeats 0"),
        (vec!["tradeoff", "--phantom-dims", "16,16,8", "--rows", "8", "--cols", "8", "--kvp", "100", "--bins", "8,0", "--report", &out("t1")].map_into(), "--bins 0"),
        (vec!["tradeoff", "--phantom-dims", "16,16,8", "--rows", "8", "--cols", "8", "--scatter-fractions", "5,-1", "--report", &out("t2")].map_into(), "--scatter-fractions 5"),
        (vec!["tradeoff", "--phantom-dims", "16,16,8", "--rows", "8", "--cols", "8", "-o", &out("t3")].map_into(), "tradeoff writes no images, only its report: give the report's folder with --report"),
    ];
    assert!(rows.len() >= 40, "{} rows", rows.len());
    let mut failures = Vec::new();
    for (args, words) in &rows {
        let line = args.join(" ");
        match run(args, Duration::from_secs(60)) {
            None => failures.push(format!("HANG (over 60 s): {line}")),
            Some((code, err)) => {
                if code == Some(0) {
                    failures.push(format!("SUCCEEDED: {line}\n{err}"));
                } else if err.contains("panicked")
                    || code.is_none()
                    || code == Some(101)
                    || code == Some(134)
                {
                    failures.push(format!("PANIC/ABORT (exit {code:?}): {line}\n{err}"));
                } else if !err.contains(words) {
                    failures.push(format!("no '{words}' in the error of: {line}\n{err}"));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} rows failed:\n\n{}",
        failures.len(),
        rows.len(),
        failures.join("\n\n")
    );
    // No row left a half-written image behind.
    assert!(!p("o").join("drr.npy").exists());
}

/// `vec![..].map_into()`: the row's arguments as owned strings.
trait MapInto {
    fn map_into(self) -> Vec<String>;
}

impl MapInto for Vec<&str> {
    fn map_into(self) -> Vec<String> {
        self.into_iter().map(String::from).collect()
    }
}

/// A line detector (1 × N or N × 1) without a pitch is fitted along its long axis and
/// renders the volume; it was refused with "no ray of any view meets the volume" (issue 51:
/// its square pitch had been fitted to put the whole volume into one row).
/// A CT file's item holds about three copies of the full-resolution CT while it is brought
/// into the patient frame and its body found (`scene::peak::item_peak_bytes`): a CT that
/// can be read but not worked on is refused after reading, naming the item and its
/// estimate, and leaves no item behind; with room, the job reports its estimate.
#[test]
fn a_ct_item_beyond_memory_is_refused_before_its_copies() {
    let dir = tempfile::tempdir().unwrap();
    let ct = dir.path().join("ct.nii.gz");
    let bin = env!("CARGO_BIN_EXE_tomograf");
    let ok = Command::new(bin)
        .args(["phantom", "--dims", "64,64,64", "-o", &s(&ct)])
        .output()
        .unwrap();
    assert!(ok.status.success());
    let dataset = |limit_gb: &str, out: &Path| {
        Command::new(bin)
            .args([
                "dataset",
                &s(&ct),
                "-o",
                &s(out),
                "--size",
                "16",
                "--views",
                "4",
            ])
            .env("TOMOGRAF_MEMORY_LIMIT_GB", limit_gb)
            .output()
            .unwrap()
    };
    // 4.3 MB: room to read the 1 MiB CT (and its file), not for the item's ~90 MiB peak.
    let out = dir.path().join("tight");
    let r = dataset("0.004", &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "item 00000: bringing into the patient frame and finding the body of a 64×64×64 CT"
        ) && err.contains("estimated peak")
            && err.contains("MiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        "{err}"
    );
    assert!(!out.join("00000").join("item.json").exists());
    let out = dir.path().join("roomy");
    let r = dataset("8", &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(
        err.contains("estimated peak memory") && err.contains("1 item(s) made, 0 already finished"),
        "{err}"
    );
}

/// Inference holds the field's activations for a patch of rays and the grid
/// (`model::config::TrainConfig::inference_peak_bytes`): refused before the fit where that
/// cannot fit, naming the field's sizes; with room, `reconstruct` reports its estimate.
/// `evaluate` likewise, with the baselines' data.
#[test]
fn an_inference_evaluation_or_training_beyond_memory_is_refused_before_its_work() {
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_tomograf");
    let data = dir.path().join("data");
    let ok = Command::new(bin)
        .args([
            "dataset",
            "--phantoms",
            "2",
            "--size",
            "64",
            "--views",
            "2",
            "-o",
            &s(&data),
        ])
        .output()
        .unwrap();
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("model/checkpoints/demo");
    let reconstruct = |limit_gb: &str, out: &Path| {
        Command::new(bin)
            .args([
                "reconstruct",
                &s(&data.join("00000")),
                "--checkpoint",
                &s(&demo),
            ])
            .args(["--iterations", "2", "-o", &s(out)])
            .env("TOMOGRAF_MEMORY_LIMIT_GB", limit_gb)
            .output()
            .unwrap()
    };
    // 102 MiB: the checkpoint and the item load; the fit's ~270 MiB does not fit.
    let out = dir.path().join("tight.nii.gz");
    let r = reconstruct("0.1", &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("inference onto a 64×64×64 grid with the checkpoint's field (hidden 128")
            && err.contains("MiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        "{err}"
    );
    assert!(!out.exists());
    let out = dir.path().join("roomy.nii.gz");
    let r = reconstruct("8", &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("(estimated peak memory"), "{err}");
    assert!(out.exists());
    // `evaluate` adds PCA-MAP's training set (`eval::peak`): refused before it is loaded
    // and before the output folder is made.
    let evaluate = |limit_gb: &str, out: &Path| {
        Command::new(bin)
            .args([
                "evaluate",
                &s(&data),
                "--train-data",
                &s(&data),
                "--views",
                "1",
            ])
            .args(["--items", "1"])
            .args(["-o", &s(out)])
            .env("TOMOGRAF_MEMORY_LIMIT_GB", limit_gb)
            .output()
            .unwrap()
    };
    let out = dir.path().join("tight-evaluation");
    let r = evaluate("0.01", &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("evaluating 1 test item(s) with a PCA prior of 2 training items")
            && err.contains("MiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        "{err}"
    );
    assert!(!out.exists());
    let out = dir.path().join("roomy-evaluation");
    let r = evaluate("8", &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("estimated peak memory"), "{err}");
    // `train` (`eval::peak::check_training`): `small`'s step (~230 MiB with its items) is
    // refused under 184 MiB before the items are loaded, although the floor checked when
    // the networks are made (160 MiB) fits; nothing is written.
    let train = |limit_gb: &str, out: &Path| {
        Command::new(bin)
            .args(["train", &s(&data), "--config", "small", "--iterations", "1"])
            .args(["-o", &s(out)])
            .env("TOMOGRAF_MEMORY_LIMIT_GB", limit_gb)
            .output()
            .unwrap()
    };
    let out = dir.path().join("tight-training");
    let r = train("0.18", &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("training 'small' (batch 4, patch 16², samples 32, hidden 128, depth 4")
            && err.contains("MiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        "{err}"
    );
    assert!(!out.exists());
    let out = dir.path().join("roomy-training");
    let r = train("8", &out);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("estimated peak memory"), "{err}");
    assert!(out.join("checkpoint").is_dir());
}

/// `validate tg195` holds its case's voxel medium (`eval::validation::tg195::medium`, Case 3's
/// 310×312×387 voxels about 470 MiB): refused before it is filled where that cannot fit;
/// `tradeoff` likewise before its ladder.
#[test]
fn a_validation_case_or_tradeoff_beyond_memory_is_refused_before_its_work() {
    let dir = tempfile::tempdir().unwrap();
    let r = Command::new(env!("CARGO_BIN_EXE_tomograf"))
        .args([
            "validate",
            "tg195",
            "--cases",
            "3",
            "--photons-case3",
            "1000",
        ])
        .args(["-o", &s(dir.path())])
        .env("TOMOGRAF_MEMORY_LIMIT_GB", "0.2")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("the TG-195 case's voxel medium of 310×312×387 voxels needs")
            && err.contains("MiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        "{err}"
    );
    assert!(!dir.path().join("tg195.csv").exists());
    // `tradeoff`: the built-in phantom's 33 MiB volume is read under 51 MiB, but detector
    // physics (~104 MiB beyond it) is refused before the ladder runs — by the scene's own
    // render check in `prepare`, which the ladder now goes through, before its larger
    // estimate (`eval::tradeoff::peak_bytes`) is reached.
    let out = dir.path().join("tradeoff");
    let r = Command::new(env!("CARGO_BIN_EXE_tomograf"))
        .args([
            "tradeoff",
            "--preset",
            "kv-flat-panel-120kvp",
            "--report",
            &s(&out),
        ])
        .env("TOMOGRAF_MEMORY_LIMIT_GB", "0.05")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("256×256×133 volume (detector physics")
            && err.contains("MiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn line_detectors_render_without_a_pitch() {
    let dir = tempfile::tempdir().unwrap();
    for (rows, cols) in [("1", "8"), ("8", "1")] {
        let o = dir.path().join(format!("line{rows}x{cols}"));
        let out = common::tomograf(&[
            "project",
            "--phantom-dims",
            "16,16,8",
            "--rows",
            rows,
            "--cols",
            cols,
            "--format",
            "npy",
            "-o",
            &s(&o),
        ]);
        common::ok(&out);
        let npy = std::fs::read_dir(&o)
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.extension().is_some_and(|e| e == "npy"))
            .expect("an .npy image");
        let bytes = std::fs::read(npy).unwrap();
        // The last 8 float32 values are the image (after the .npy header).
        let image: Vec<f32> = bytes[bytes.len() - 32..]
            .chunks(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert!(image.iter().any(|&v| v > 0.0), "{rows}×{cols}: {image:?}");
    }
}

/// Geometry that is legal but almost certainly not meant renders with a warning: the
/// detector through the patient (SID = SAD), the source inside it (SAD 10 mm); a
/// sensible set-up warns about nothing.
#[test]
fn suspicious_geometry_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let o = s(&dir.path().join("o"));
    let small = [
        "--phantom-dims",
        "16,16,8",
        "--phantom-spacing",
        "20,20,40",
        "--rows",
        "16",
        "--cols",
        "16",
    ];
    for (extra, words) in [
        (
            &["--sad", "1000", "--sid", "1000"][..],
            Some("the detector cuts through the volume"),
        ),
        (
            &["--sad", "10", "--sid", "1500"][..],
            Some("the source lies inside the volume"),
        ),
        (&["--sad", "1000", "--sid", "1500"][..], None),
    ] {
        let mut args = vec!["project"];
        args.extend(small);
        args.extend(extra);
        args.extend(["-o", &o]);
        let out = common::tomograf(&args);
        common::ok(&out);
        let err = String::from_utf8_lossy(&out.stderr);
        match words {
            Some(w) => assert!(err.contains(w), "{extra:?}: {err}"),
            None => assert!(!err.contains("warning"), "{extra:?}: {err}"),
        }
    }
    // An image that holds one value everywhere says nothing: named (it was silent).
    let out = common::tomograf(&[
        "project",
        "--phantom-dims",
        "16,16,8",
        "--rows",
        "8",
        "--cols",
        "8",
        "--empty-below",
        "1e30",
        "-o",
        &o,
    ]);
    common::ok(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("every pixel of every view is 0: nothing in the beam"),
        "{err}"
    );
    // `dataset` says so too (it said nothing).
    for (sid, warned) in [("1000", true), ("1500", false)] {
        let out = common::tomograf(&[
            "dataset",
            "-o",
            &s(&dir.path().join(format!("ds{sid}"))),
            "--phantoms",
            "1",
            "--size",
            "8",
            "--views",
            "2",
            "--sad",
            "1000",
            "--sid",
            sid,
        ]);
        common::ok(&out);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            err.contains("the detector cuts through every CT"),
            warned,
            "{err}"
        );
    }
}

/// `scan` lists the readable series and names each DICOM file it had to skip (a
/// truncated slice), instead of passing over it in silence.
#[test]
fn scan_names_the_files_it_skips() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("tree");
    common::ok(&common::tomograf(&[
        "phantom",
        "--dicom",
        "-o",
        &s(&d),
        "--dims",
        "16,16,4",
        "--spacing",
        "20,20,40",
    ]));
    let mut files: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let b = std::fs::read(&files[0]).unwrap();
    std::fs::write(&files[0], &b[..200]).unwrap();
    let out = common::tomograf(&["scan", &s(dir.path())]);
    common::ok(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("skipped 1 DICOM file")
            && err.contains(files[0].file_name().unwrap().to_str().unwrap()),
        "{err}"
    );
    let listed = String::from_utf8_lossy(&out.stdout);
    assert!(
        listed.contains(&format!("\t{}\t", files.len() - 1)),
        "{listed}"
    );
}

/// A checkpoint whose prior (the mean training volume) is on another grid than the item is
/// named: it was silently resampled (issue 51: a 4³ `mean_volume.npy` for a 64³ model).
#[test]
fn a_prior_on_another_grid_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = d.join("data");
    common::ok(&common::tomograf(&[
        "dataset",
        "-o",
        &s(&data),
        "--phantoms",
        "1",
        "--size",
        "64",
        "--views",
        "4",
    ]));
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("model/checkpoints/demo");
    let reconstruct = |ck: &Path| {
        common::tomograf(&[
            "reconstruct",
            &s(&data.join("00000")),
            "--checkpoint",
            &s(ck),
            "--views",
            "1",
            "--iterations",
            "1",
            "-o",
            &s(&d.join("rec")),
        ])
    };
    let words = "the checkpoint's prior (mean_volume.npy, the grid it was trained on) is 4×4×4";
    let same = reconstruct(&demo);
    common::ok(&same);
    assert!(!String::from_utf8_lossy(&same.stderr).contains("prior (mean_volume.npy"));
    let small = d.join("ck-small-prior");
    copy_dir(&demo, &small);
    npy(&small.join("mean_volume.npy"), [4, 4, 4], &[0.2; 64]);
    let out = reconstruct(&small);
    common::ok(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(words) && err.contains("64×64×64 CT grid"),
        "{err}"
    );
}

/// Runs tomograf with `args` (and `TOMOGRAF_MEMORY_LIMIT_GB` when given): exit code, stderr.
fn tomograf_with(args: &[&str], limit_gb: Option<&str>) -> (Option<i32>, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tomograf"));
    c.args(args);
    if let Some(l) = limit_gb {
        c.env("TOMOGRAF_MEMORY_LIMIT_GB", l);
    }
    let r = c.output().unwrap();
    (
        r.status.code(),
        String::from_utf8_lossy(&r.stderr).into_owned(),
    )
}

/// A study too large for the memory available is refused before its first stage, naming
/// each stage's estimate and the largest (issue 51: each stage used to be checked only when
/// it began, after the earlier ones had run).
#[test]
fn a_study_beyond_memory_is_refused_before_its_first_stage() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    // 50 MB: less than any stage of a `tiny` study needs beside what the process holds.
    let (code, err) = tomograf_with(
        &["study", "realism-gap", "--scale", "tiny", "-o", &s(&out)],
        Some("0.05"),
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("the study (--scale tiny: 16³ grids")
            && err.contains("in its report stage")
            && err.contains("data 69 MiB, training 28 MiB, evaluation 34 MiB, report 89 MiB")
            && err.contains("more than the 51.2 MiB that TOMOGRAF_MEMORY_LIMIT_GB allows"),
        "{err}"
    );
    assert!(!out.join("data").exists(), "a stage ran before the refusal");
}

/// `validate tg195` with a photon or a hundred per run (issue 51: it once hung in the
/// deviations plot) finishes, and says that figures without a finite standard error tell
/// nothing, instead of printing ± inf deviations without a word.
#[test]
fn a_validation_with_too_few_photons_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let (code, err) = tomograf_with(
        &[
            "validate",
            "tg195",
            "--cases",
            "1",
            "--photons-case1",
            "1",
            "-o",
            &s(dir.path()),
        ],
        None,
    );
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("have no finite, non-zero standard error: too few photons"),
        "{err}"
    );
    assert!(dir.path().join("tg195.csv").exists());
}

/// `demo --phantoms` beyond the limit is refused before the demo remakes its training set
/// (it once spent seconds and wrote `train-set/` first).
#[test]
fn a_demo_with_too_many_phantoms_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let (code, err) = tomograf_with(
        &["demo", "--phantoms", "1000000000000000", "-o", &s(&out)],
        None,
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("--phantoms: 1000000000000000 phantoms: at most 1000000"),
        "{err}"
    );
    assert!(
        !out.join("train-set").exists(),
        "the training set was remade first"
    );
}

/// A data set larger than the free disk is refused before its first item, naming what it
/// would write and what is free (issue 51: `dataset` used to run until the disk filled).
/// 1 000 000 items of 256³ voxels and 38 views are about 74 TiB, beyond any disk CI runs on.
#[test]
fn a_data_set_beyond_the_free_disk_is_refused_before_its_first_item() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("set");
    let (code, err) = tomograf_with(
        &[
            "dataset",
            "-o",
            &s(&out),
            "--phantoms",
            "1000000",
            "--size",
            "256",
            "--views",
            "36",
        ],
        None,
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("1000000 item(s) of 256³ voxels and 38 views of 256² pixels")
            && err.contains("would write about 74.0 TiB but")
            && err.contains("is free there"),
        "{err}"
    );
    assert!(!out.exists(), "the refused run made its folder");
}
