//! The data-set item format: what `tomograf dataset` writes and the model reads, defined
//! once, in both directions.
//!
//! A data set is a folder with `manifest.jsonl` (one [`ItemRecord`] per line, finished
//! items in item order) and one folder per item (`00000`, `00001`, …) holding:
//! * `item.json` — the [`ItemRecord`]; written last, so it marks the item finished;
//! * `views.json` — the geometry of every projection ([`write_views`]): the set-up, one
//!   pose (θ, φ in degrees) and one detector view per projection, in the DICOM LPS world
//!   frame, mm;
//! * `projections.npy` — float32, views × rows × cols, row-major (line integrals ∫mu ds,
//!   or the detector signal the record's `acquisition` describes);
//! * `ct.nii.gz` — the CT on the training grid, normalised to [0, 1] over the record's HU
//!   window (optional for reading: test items may have none).
//!
//! Every file is written atomically ([`crate::atomic`]). Reading ([`read_item`]) checks that
//! the files agree (view counts, detector sizes, finite values) and names the file at fault.

use crate::atomic::{write_atomic, write_json};
use crate::error::{DatasetError, Result};
use crate::preprocess::HuWindow;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use tomograf_physics::acquisition::Acquisition;
use tomograf_sim::{Geometry, Pose, View, Volume};

/// The name of an item's record file.
pub const ITEM_JSON: &str = "item.json";
/// The name of a data set's list of finished items.
pub const MANIFEST: &str = "manifest.jsonl";

/// What `item.json` holds and `manifest.jsonl` lists. Reading needs only `id`, `hu_window`,
/// `energy_kev` and the three file names; the rest describe the item's provenance and
/// default to empty for items made by hand.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ItemRecord {
    /// Position in the data set (0-based).
    #[serde(default)]
    pub index: usize,
    /// Folder name (`00000`, …).
    pub id: String,
    /// `train` or `test` (any label).
    #[serde(default)]
    pub split: String,
    /// Where the CT came from (a file, or a phantom's specification).
    #[serde(default)]
    pub source: serde_json::Value,
    /// SHA-256 of the source file (or of the phantom's specification), hex.
    #[serde(default)]
    pub source_sha256: String,
    /// HU window of the CT's normalisation to [0, 1].
    pub hu_window: HuWindow,
    /// Effective energy of the line integrals (keV), and of the density scale.
    pub energy_kev: f64,
    /// The CT file, relative to the item folder.
    pub ct: String,
    /// Voxels of the normalised CT.
    #[serde(default)]
    pub ct_dims: [usize; 3],
    /// The projections file, relative to the item folder.
    pub projections: String,
    /// What the projections hold, in words.
    #[serde(default)]
    pub projection_quantity: String,
    /// The acquisition the projections were recorded with (`{"settings": …, "noise_seed":
    /// …}`, [`AcquisitionRecord`]); null for ideal DRRs. Kept as JSON so that the bytes of
    /// `item.json` and `manifest.jsonl` do not depend on field order; read it with
    /// [`ItemRecord::acquisition`].
    #[serde(default)]
    pub acquisition: serde_json::Value,
    /// The geometry file, relative to the item folder.
    pub views: String,
    /// (θ, φ) of each projection, degrees.
    #[serde(default)]
    pub angles_deg: Vec<[f64; 2]>,
    /// The frame the CT's voxel axes run in ([`crate::frame::PATIENT_FRAME`]); empty for
    /// items made before it was recorded (their CTs kept the source's own axes).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub frame: String,
    /// How the source was brought into that frame ([`crate::frame::Reorientation`]; null
    /// for phantoms, which are generated in it).
    #[serde(default, skip_serializing_if = "serde_json::Value::is_null")]
    pub reorientation: serde_json::Value,
    /// What was removed around the body: "couch, padding and stray voxels set to air" or
    /// "kept" (`--keep-table`); empty for phantoms (they hold what their spec asks).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub outside_body: String,
    /// The fraction of the item's CT grid inside the body ([`crate::body`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_fraction: Option<f64>,
    /// The fraction of the body in each tissue class ([`crate::body::TISSUE_CLASSES`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tissue_fractions: Option<crate::body::TissueFractions>,
    /// The shape augmentation applied before the crop ([`crate::augment::Augmentation`]);
    /// null for none.
    #[serde(default, skip_serializing_if = "serde_json::Value::is_null")]
    pub augmentation: serde_json::Value,
    /// The stretch of the body's length kept before the crop
    /// ([`crate::scan_range::ScanRange`]); null for the whole body.
    #[serde(default, skip_serializing_if = "serde_json::Value::is_null")]
    pub scan_range: serde_json::Value,
}

/// An item's acquisition: the settings and the seed of its detector noise.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct AcquisitionRecord {
    /// The physics chain.
    pub settings: Acquisition,
    /// Seed of the detector noise (per item).
    #[serde(default)]
    pub noise_seed: u64,
}

impl AcquisitionRecord {
    /// As the record stores it.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({"settings": self.settings, "noise_seed": self.noise_seed})
    }
}

impl ItemRecord {
    /// The acquisition the projections were recorded with; `None` for ideal DRRs (and for
    /// items written before acquisitions were recorded).
    pub fn acquisition(&self) -> std::result::Result<Option<AcquisitionRecord>, String> {
        if self.acquisition.is_null() {
            return Ok(None);
        }
        serde_json::from_value(self.acquisition.clone())
            .map(Some)
            .map_err(|e| format!("acquisition: {e}"))
    }
}

/// `views.json`: the set-up and one pose and view per projection.
#[derive(Serialize, Deserialize)]
struct ViewsRecord {
    #[serde(default, skip_deserializing)]
    conventions: String,
    geometry: Option<Geometry>,
    poses: Option<Vec<Pose>>,
    views: Option<Vec<View>>,
}

/// How `views.json` states its conventions.
const CONVENTIONS: &str = "World frame DICOM LPS, mm. Pixel (r, c) centre = detector_origin + c*u + r*v; cone rays run from source to pixel centre.";

/// One item as read: its record, geometry, projections and (when present) CT.
#[derive(Debug, Clone)]
pub struct ItemFiles {
    /// The folder.
    pub dir: PathBuf,
    /// `item.json`.
    pub record: ItemRecord,
    /// The set-up the views were made with.
    pub geometry: Geometry,
    /// One pose per projection.
    pub poses: Vec<Pose>,
    /// One view per projection.
    pub views: Vec<View>,
    /// The projections, `views × rows × cols`, row-major.
    pub projections: Vec<f32>,
    /// Detector rows.
    pub rows: usize,
    /// Detector columns.
    pub cols: usize,
    /// The normalised CT; `None` when the item has no CT file.
    pub ct: Option<Volume>,
}

fn corrupt(path: &Path, reason: impl std::fmt::Display) -> DatasetError {
    DatasetError::corrupt(path, reason.to_string())
}

fn read(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| DatasetError::io(path, "reading", e))
}

/// Writes `views.json` into the item folder `dir`.
pub fn write_views(dir: &Path, geometry: &Geometry, poses: &[Pose], views: &[View]) -> Result<()> {
    #[derive(Serialize)]
    struct Out<'a> {
        conventions: &'a str,
        geometry: &'a Geometry,
        poses: &'a [Pose],
        views: &'a [View],
    }
    let path = dir.join("views.json");
    // Through a JSON value: keys in alphabetical order at every level, as views.json has
    // always had them.
    let value = serde_json::to_value(Out {
        conventions: CONVENTIONS,
        geometry,
        poses,
        views,
    })
    .map_err(|e| corrupt(&path, e))?;
    write_json(&path, &value)
}

/// Writes `item.json` into the item folder `dir` (last: it marks the item finished).
pub fn write_record(dir: &Path, record: &ItemRecord) -> Result<()> {
    let path = dir.join(ITEM_JSON);
    // Through a JSON value: keys in alphabetical order, as item.json has always had them.
    let value = serde_json::to_value(record).map_err(|e| corrupt(&path, e))?;
    write_json(&path, &value)
}

/// The record of the item folder `dir`, if it is finished (its `item.json` exists and
/// parses).
pub fn finished_record(dir: &Path) -> Option<ItemRecord> {
    serde_json::from_slice(&std::fs::read(dir.join(ITEM_JSON)).ok()?).ok()
}

/// Rewrites `manifest.jsonl` in the data-set folder `out` from the finished items among
/// the first `items` (folders `00000`, …), in item order; returns their count.
///
/// Shards of one data set call this concurrently, each after its own items. A shard could
/// list the items, then another shard finish its last item and write its manifest, then
/// the first shard's older listing land last, leaving an incomplete manifest for good.
/// So the folder is listed again after each write and the manifest rewritten until the
/// listing is stable: the last write is then always checked against every item finished
/// before it (items only ever get finished, so this ends).
pub fn write_manifest(out: &Path, items: usize) -> Result<usize> {
    write_manifest_checked(out, items, || {})
}

/// [`write_manifest`], calling `between` once between the first listing and its write
/// (the tests finish another shard's item there).
fn write_manifest_checked(out: &Path, items: usize, between: impl FnOnce()) -> Result<usize> {
    let (mut lines, mut n) = list_finished(out, items)?;
    between();
    loop {
        write_atomic(&out.join(MANIFEST), |w| {
            std::io::Write::write_all(w, lines.as_bytes())
        })?;
        let (again, m) = list_finished(out, items)?;
        if again == lines {
            return Ok(n);
        }
        (lines, n) = (again, m);
    }
}

/// The manifest's text for the finished items among the first `items`, and their count.
fn list_finished(out: &Path, items: usize) -> Result<(String, usize)> {
    let mut lines = String::new();
    let mut n = 0;
    for index in 0..items {
        let path = out.join(format!("{index:05}")).join(ITEM_JSON);
        let Ok(bytes) = std::fs::read(&path) else {
            continue;
        };
        let record: ItemRecord = serde_json::from_slice(&bytes).map_err(|e| corrupt(&path, e))?;
        lines += &serde_json::to_string(&record).map_err(|e| corrupt(&path, e))?;
        lines.push('\n');
        n += 1;
    }
    Ok((lines, n))
}

/// The records `manifest.jsonl` of the data-set folder `dir` lists (blank lines skipped),
/// or only those of `split`.
pub fn read_manifest(dir: &Path, split: Option<&str>) -> Result<Vec<ItemRecord>> {
    let mp = dir.join(MANIFEST);
    let text = String::from_utf8(read(&mp)?).map_err(|e| corrupt(&mp, e))?;
    let mut records = Vec::new();
    // Line of each id seen: an item listed twice would be trained on or scored twice.
    let mut seen = std::collections::HashMap::new();
    for (n, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let record: ItemRecord =
            serde_json::from_str(line).map_err(|e| corrupt(&mp, format!("line {}: {e}", n + 1)))?;
        if let Some(first) = seen.insert(record.id.clone(), n + 1) {
            return Err(corrupt(
                &mp,
                format!(
                    "line {}: item '{}' is listed twice (also on line {first}); remove one line",
                    n + 1,
                    record.id
                ),
            ));
        }
        if split.is_none_or(|s| s == record.split) {
            records.push(record);
        }
    }
    Ok(records)
}

/// Reads an item's `views.json` (the file [`write_views`] writes): the set-up, and one
/// pose and one view per projection, the set-up checked. Errors name the file.
pub fn read_views(path: &Path) -> Result<(Geometry, Vec<Pose>, Vec<View>)> {
    let vj: ViewsRecord = serde_json::from_slice(&read(path)?).map_err(|e| corrupt(path, e))?;
    let (Some(geometry), Some(poses), Some(views)) = (vj.geometry, vj.poses, vj.views) else {
        return Err(corrupt(
            path,
            "geometry missing: views.json needs 'geometry', 'poses' and 'views'",
        ));
    };
    geometry.validate().map_err(|e| corrupt(path, e))?;
    Ok((geometry, poses, views))
}

/// Reads the item folder `dir` and checks that its files agree: `views.json` has a geometry,
/// poses and views, one per projection, each valid and of the projections' size; the
/// projections are finite. The CT is read when its file exists.
pub fn read_item(dir: &Path) -> Result<ItemFiles> {
    let ij = dir.join(ITEM_JSON);
    let record: ItemRecord = serde_json::from_slice(&read(&ij)?).map_err(|e| corrupt(&ij, e))?;
    let vp = dir.join(&record.views);
    let (geometry, poses, views) = read_views(&vp)?;
    let invalid = |e: tomograf_sim::SimError| corrupt(&vp, e);
    let pp = dir.join(&record.projections);
    let (projections, shape) = crate::image::read_npy(&pp)?;
    let [nv, rows, cols] = shape[..] else {
        return Err(corrupt(
            &pp,
            format!("expected views × rows × cols, found shape {shape:?}"),
        ));
    };
    if nv == 0 {
        return Err(corrupt(&pp, "no projections (view count 0)"));
    }
    if views.len() != nv || poses.len() != nv {
        return Err(corrupt(
            &pp,
            format!(
                "{nv} projections but {} views and {} poses in {}",
                views.len(),
                poses.len(),
                vp.display()
            ),
        ));
    }
    for v in &views {
        v.validate().map_err(invalid)?;
        if (v.rows, v.cols) != (rows, cols) {
            return Err(corrupt(
                &pp,
                format!(
                    "projections are {rows}×{cols} but a view's detector is {}×{}",
                    v.rows, v.cols
                ),
            ));
        }
    }
    if let Some(i) = projections.iter().position(|x| !x.is_finite()) {
        return Err(corrupt(&pp, format!("value {i} is not finite")));
    }
    record.acquisition().map_err(|e| corrupt(&ij, e))?;
    let cp = dir.join(&record.ct);
    let ct = if cp.exists() {
        Some(crate::nifti::read_nifti(&cp)?)
    } else {
        None
    };
    Ok(ItemFiles {
        dir: dir.to_path_buf(),
        record,
        geometry,
        poses,
        views,
        projections,
        rows,
        cols,
        ct,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A finished item `index` under `out` (only what the manifest needs).
    fn finish(out: &Path, index: usize) {
        let dir = out.join(format!("{index:05}"));
        std::fs::create_dir_all(&dir).unwrap();
        let record = serde_json::json!({
            "id": format!("{index:05}"), "hu_window": {"lo": -1024.0, "hi": 2048.0},
            "energy_kev": 60.0, "ct": "ct.nii.gz", "projections": "projections.npy",
            "views": "views.json",
        });
        std::fs::write(dir.join(ITEM_JSON), record.to_string()).unwrap();
    }

    fn listed(out: &Path) -> Vec<String> {
        read_manifest(out, None)
            .unwrap()
            .into_iter()
            .map(|r| r.id)
            .collect()
    }

    #[test]
    fn a_shard_finishing_between_anothers_listing_and_write_stays_listed() {
        let out = tempfile::tempdir().unwrap();
        let out = out.path();
        // Shard 0 has finished item 0 and lists the folder; meanwhile shard 1 finishes
        // item 1 and writes its manifest (both items); then shard 0 writes its listing.
        finish(out, 0);
        let n = write_manifest_checked(out, 2, || {
            finish(out, 1);
            assert_eq!(write_manifest(out, 2).unwrap(), 2);
        })
        .unwrap();
        assert_eq!(listed(out), ["00000", "00001"], "the older listing won");
        assert_eq!(n, 2);
        // No temporary file is left behind by the rewrites.
        let names: Vec<_> = std::fs::read_dir(out)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
    }
}
