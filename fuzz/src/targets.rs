//! The fuzz targets' bodies, shared by the cargo-fuzz binaries (`fuzz/fuzz_targets/`) and the
//! corpus replay on stable (`tests/fuzz_corpus.rs`, which includes this file by path).
//! Every input must end in a value or an error: never a panic, an abort for memory or a hang.
//!
//! What they share: the parsers read paths, so each input is written to a
//! file in a scratch folder of this process (under /dev/shm when it exists), and a memory
//! limit small enough that a header asking for more is refused before any allocation.

use std::path::{Path, PathBuf};
use std::sync::Once;

static INIT: Once = Once::new();

/// The scratch folder of this process (created once), with the memory limit set.
pub fn scratch() -> PathBuf {
    let shm = Path::new("/dev/shm");
    let base = if shm.is_dir() {
        shm.to_path_buf()
    } else {
        std::env::temp_dir()
    };
    let dir = base.join(format!("tomograf-fuzz-{}", std::process::id()));
    INIT.call_once(|| {
        // 1 GiB: libFuzzer's default -rss_limit_mb is 2048, so a header that passes this
        // check cannot make an input abort for memory.
        // SAFETY: set once, before any other thread of this process reads the environment.
        unsafe { std::env::set_var("TOMOGRAF_MEMORY_LIMIT_GB", "1") };
        std::fs::create_dir_all(&dir).expect("scratch folder");
    });
    dir
}

/// Writes `bytes` to `name` in the scratch folder and returns its path.
pub fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let p = scratch().join(name);
    std::fs::write(&p, bytes).expect("scratch file");
    p
}

/// NIfTI-1, plain or gzip (the reader tells them by the gzip magic).
pub fn nifti(data: &[u8]) {
    let p = file("input.nii", data);
    let _ = tomograf_datasets::nifti::read_nifti(&p);
}

/// NRRD, attached data (raw or gzip), or a detached header whose data file is the
/// input's second part (after [`SLICE_MARKER`]), written beside it as `input.raw`.
pub fn nrrd(data: &[u8]) {
    let (header, rest) = match data
        .windows(SLICE_MARKER.len())
        .position(|w| w == SLICE_MARKER)
    {
        Some(k) => (&data[..k], Some(&data[k + SLICE_MARKER.len()..])),
        None => (data, None),
    };
    match rest {
        None => {
            let p = file("input.nrrd", header);
            let _ = tomograf_datasets::nrrd::read_nrrd(&p);
        }
        Some(raw) => {
            file("input.raw", raw);
            let p = file("input.nhdr", header);
            let _ = tomograf_datasets::nrrd::read_nrrd(&p);
        }
    }
}

/// The marker that cuts a `dicom_series` input into slice files.
pub const SLICE_MARKER: &[u8] = b"--slice--";

/// DICOM slices and series assembly: the input is cut at each [`SLICE_MARKER`] into files
/// (at most 4) of one folder, read as a series and scanned as a tree.
pub fn dicom_series(data: &[u8]) {
    let dir = scratch().join("series");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("series folder");
    let mut rest = data;
    for i in 0..4 {
        let cut = if i == 3 {
            None
        } else {
            rest.windows(SLICE_MARKER.len())
                .position(|w| w == SLICE_MARKER)
        };
        let (part, next) = match cut {
            Some(k) => (&rest[..k], &rest[k + SLICE_MARKER.len()..]),
            None => (rest, &[][..]),
        };
        std::fs::write(dir.join(format!("slice{i}.dcm")), part).expect("slice file");
        if cut.is_none() {
            break;
        }
        rest = next;
    }
    let _ = tomograf_datasets::dicom::read_dicom_series(&dir, false);
    let _ = tomograf_datasets::dicom::scan_dicom_tree_reporting(&dir);
}

/// A mesh file with extension `ext` (`obj`, `ply`, `stl`).
pub fn mesh(ext: &str, data: &[u8]) {
    let p = file(&format!("input.{ext}"), data);
    let _ = tomograf_sim::mesh::io::load(&p);
}

/// A user spectrum file (energy, fluence rows).
pub fn spectrum(data: &[u8]) {
    let p = file("input.txt", data);
    let _ = tomograf_physics::spectrum::Spectrum::from_file(&p);
}

/// The marker that cuts an `item` input into the files of a data-set item.
pub const FILE_MARKER: &[u8] = b"--file--";

/// A data-set item and its manifest (`tomograf_datasets::item`): the input is cut at each
/// [`FILE_MARKER`] into `manifest.jsonl`, `00000/item.json`, `00000/views.json` and
/// `00000/projections.npy` (in that order; missing parts are missing files); the manifest
/// and the item are read. (The item's CT is NIfTI: its own target.)
pub fn item(data: &[u8]) {
    let dir = scratch().join("dataset");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("00000")).expect("item folder");
    let names = [
        "manifest.jsonl",
        "00000/item.json",
        "00000/views.json",
        "00000/projections.npy",
    ];
    let mut rest = data;
    for name in names {
        let cut = rest
            .windows(FILE_MARKER.len())
            .position(|w| w == FILE_MARKER);
        let part = &rest[..cut.unwrap_or(rest.len())];
        std::fs::write(dir.join(name), part).expect("item file");
        match cut {
            Some(k) => rest = &rest[k + FILE_MARKER.len()..],
            None => break,
        }
    }
    let _ = tomograf_datasets::item::read_manifest(&dir, None);
    let _ = tomograf_datasets::item::read_manifest(&dir, Some("test"));
    let _ = tomograf_datasets::item::read_item(&dir.join("00000"));
}

/// A target's body: parse one input.
pub type Target = fn(&[u8]);

/// The largest phantom grid (voxels) and detector (pixels) a `scene` input may ask for:
/// larger ones are replaced (the voxel count) or not rendered (the pixels), so that one
/// input stays well under a second; the memory limit still sees every size asked for.
const SCENE_VOXELS: usize = 32 * 32 * 32;
const SCENE_PIXELS: usize = 64 * 64;

/// Scene TOML (`tomograf project --scene`): parsed, its physics chosen, its volume (the
/// built-in phantom on a small grid: inputs name no files — the volume, spectrum and mesh
/// readers have targets of their own), views and geometry resolved, primitive meshes
/// built; an ideal DRR whose views are small is rendered (the first view).
pub fn scene(data: &[u8]) {
    let dir = scratch();
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(mut scene) = tomograf_scene::Scene::from_toml(text, Some(&dir)) else {
        return;
    };
    scene.volume.path = None;
    if let Some(s) = scene.spectrum.as_mut() {
        s.file = None;
    }
    scene.mesh.retain(|m| m.path.is_none());
    let small = scene.volume.phantom_dims.is_some_and(|d| {
        d.iter()
            .try_fold(1usize, |a, &n| a.checked_mul(n))
            .is_some_and(|n| n <= SCENE_VOXELS)
    });
    if !small {
        scene.volume.phantom_dims = Some([8, 8, 8]);
        scene.volume.phantom_spacing_mm = Some([40.0, 40.0, 40.0]);
    }
    let Ok(prepared) = tomograf_scene::prepare(&scene) else {
        return;
    };
    let Some(view) = prepared.job.views.first() else {
        return;
    };
    let Ok(renderer) = prepared.renderer() else {
        return;
    };
    if prepared.acquisition.is_none() && view.rows.saturating_mul(view.cols) <= SCENE_PIXELS {
        let _ = renderer.render(0, view);
    }
}

/// The files of a checkpoint a `checkpoint` input is cut into at each [`FILE_MARKER`], in
/// this order (those left out are missing).
pub const CHECKPOINT_FILES: [&str; 5] = [
    "config.toml",
    "state.json",
    "codes.json",
    "mean_volume.npy",
    "generator.bpk",
];

/// A checkpoint as inference loads it (`tomograf reconstruct`, `evaluate`):
/// `tomograf_model::checkpoint::load_generator` on a folder of the files in
/// [`CHECKPOINT_FILES`], cut from the input at each [`FILE_MARKER`].
pub fn checkpoint(data: &[u8]) {
    let dir = scratch().join("checkpoint");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("checkpoint folder");
    let mut rest = data;
    for name in CHECKPOINT_FILES {
        let cut = rest
            .windows(FILE_MARKER.len())
            .position(|w| w == FILE_MARKER);
        let (part, next) = match cut {
            Some(i) => (&rest[..i], &rest[i + FILE_MARKER.len()..]),
            None => (rest, &[][..]),
        };
        std::fs::write(dir.join(name), part).expect("checkpoint file");
        rest = next;
        if cut.is_none() {
            break;
        }
    }
    let device = tomograf_model::backend::device("flex").expect("the CPU backend");
    let _ = tomograf_model::checkpoint::load_generator(&dir, &device);
}

/// Every target by name (the folder names under `fuzz/corpus/` and `fuzz/seeds/`).
pub const TARGETS: &[(&str, Target)] = &[
    ("nifti", nifti),
    ("nrrd", nrrd),
    ("dicom_series", dicom_series),
    ("mesh_obj", |d| mesh("obj", d)),
    ("mesh_ply", |d| mesh("ply", d)),
    ("mesh_stl", |d| mesh("stl", d)),
    ("spectrum", spectrum),
    ("item", item),
    ("scene", scene),
    ("checkpoint", checkpoint),
];
