//! DICOM CT series → [`Volume`]: a folder of single-frame slices (one file per slice), as
//! scanners export them and TCIA distributes them (LIDC-IDRI…), parsed with `dicom-object`.
//!
//! # Conventions
//! DICOM's patient frame is LPS in millimetres, which is tomograf's world frame: nothing is
//! flipped. For a series of `n` slices of `Rows × Columns` pixels:
//! * dims are `(Columns, Rows, n)`: voxel `(i, j, k)` is column `i` of row `j` of the
//!   `k`-th slice in sorted order; `i` runs along the row direction cosine
//!   (`ImageOrientationPatient[0..3]`), `j` along the column direction cosine (`[3..6]`);
//! * slices are sorted by the projection of `ImagePositionPatient` onto the slice normal
//!   `n = row cosine × column cosine`, ascending, so `k` runs along `+n` (the direction
//!   matrix's third column), whatever the file names or instance numbers;
//! * spacing (mm) = (`PixelSpacing[1]`, `PixelSpacing[0]`, mean distance between consecutive
//!   slices): `PixelSpacing` is (distance between rows, distance between columns);
//! * origin = `ImagePositionPatient` of the first sorted slice, which DICOM defines as the
//!   centre of its first pixel, i.e. of voxel `(0, 0, 0)`;
//! * values = stored · `RescaleSlope` + `RescaleIntercept` (defaults 1 and 0; HU for CT),
//!   per slice, as `f32`. Stored values keep their low `BitsStored` bits (sign-extended when
//!   `PixelRepresentation` is 1); `HighBit` is assumed to be `BitsStored − 1`.
//!
//! # What is read
//! Only DICOM Part-10 files (128-byte preamble, then `DICM`) are considered; any other file
//! in a folder (LIDC's XML annotations, notes…) and DICOMDIR files are skipped. Pixel data
//! must be uncompressed: Implicit or Explicit VR Little Endian, or Explicit VR Big Endian;
//! one sample per pixel; 8, 16 or 32 bits allocated; one frame per file. Compressed series
//! can be converted with `gdcmconv --raw` or `dcmdjpeg`. Stacks that are tilted (gantry
//! tilt), sheared, unevenly spaced or missing slices are refused rather than resampled.

mod lengths;
mod slice;
mod write;

pub use write::write_dicom_series;

use crate::error::{DatasetError, Result};
use dicom_dictionary_std::tags;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use slice::{
    Slice, element, invalid, open_header, optional_str, optional_uint, parse_slice, read_pixels,
    required_str, tag_name,
};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tomograf_sim::Volume;
use tomograf_sim::volume::checked_voxel_count;

/// Checks the value lengths a DICOM Part-10 file declares against its size, as every read
/// here does before the parser sees the file (a declared length the file cannot hold is
/// refused before anything is allocated for it); `Ok` for a file that is not Part 10.
pub fn check_value_lengths(path: &Path) -> Result<()> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, "reading", e))?;
    lengths::check(path, &bytes)
}

/// Largest difference between the orientation cosines of two slices of a series.
const ORIENTATION_TOL: f64 = 1e-4;
/// Largest angle (rad) between the slice normal and the line through the slice positions.
const TILT_TOL: f64 = 1e-3;
/// Largest relative difference between a slice gap and the series' typical gap…
const GAP_REL_TOL: f64 = 0.01;
/// …or absolute difference (mm): positions are decimal strings, often rounded to 0.01 mm.
const GAP_ABS_TOL: f64 = 0.01;
/// Two slices closer than this (mm) along the normal are duplicates.
const DUPLICATE_TOL: f64 = 1e-3;

/// A CT slice must hold RescaleIntercept and RescaleSlope: the CT Image module requires both
/// (type 1), and without them the stored values are not HU (most scanners store HU + 1024),
/// which no later check would see.
fn check_rescale_tags(path: &Path, obj: &dicom_object::InMemDicomObject) -> Result<()> {
    let missing: Vec<String> = [tags::RESCALE_INTERCEPT, tags::RESCALE_SLOPE]
        .into_iter()
        .filter(|&t| element(obj, t).is_none())
        .map(tag_name)
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    Err(DatasetError::unsupported(
        path,
        format!(
            "a CT slice without {}: its stored values cannot be read as HU (most scanners \
             store HU + 1024). Add the tags, or read the stored values as they are with \
             --allow-non-ct (allow_non_ct = true in a scene's [volume])",
            missing.join(" and ")
        ),
    ))
}

/// One series found under a folder tree by [`scan_dicom_tree`]: the DICOM files of one
/// folder that share a `SeriesInstanceUID` (a series split over several folders gives
/// one entry per folder).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SeriesInfo {
    /// `SeriesInstanceUID` (0020,000E).
    pub series_uid: String,
    /// The folder holding the files, to pass to [`read_dicom_series`].
    pub folder: PathBuf,
    /// Number of files (slices) of the series in that folder.
    pub files: usize,
    /// `Modality` (0008,0060), e.g. "CT", "DX"; empty if absent.
    pub modality: String,
    /// `SeriesDescription` (0008,103E); empty if absent.
    pub description: String,
    /// `Rows` (0028,0010) of the first file read; 0 if absent.
    pub rows: u32,
    /// `Columns` (0028,0011) of the first file read; 0 if absent.
    pub cols: u32,
}

/// Reads the CT series stored in `dir` (not its sub-folders) into a [`Volume`] in the LPS
/// world frame; see the [module docs](self) for the geometry and value conventions.
///
/// Every DICOM file in the folder must be a slice of the same series (other files are
/// skipped). `allow_non_ct` accepts modalities other than CT (the values are then whatever
/// the rescale gives, not necessarily HU).
///
/// Errors name the folder or file and the problem: no DICOM files, several series (with
/// their UIDs; see [`scan_dicom_tree`]), a non-CT modality, a missing or invalid tag, a
/// compressed transfer syntax, slices that disagree in size, pixel spacing or orientation,
/// duplicate or missing slices (gaps that differ from the typical one by more than 1 %,
/// or 0.01 mm), a single slice, a tilted or sheared stack (slice positions more than
/// 1 mrad off the slice normal), truncated files, or a volume above
/// [`tomograf_sim::volume::MAX_VOXELS`] (checked before the voxels are allocated).
pub fn read_dicom_series(dir: &Path, allow_non_ct: bool) -> Result<Volume> {
    let (files, subdirs) = list_dir(dir)?;
    // Files are parsed in parallel; the first error in file order is the one reported,
    // whatever the thread count.
    let parsed: Vec<_> = files.par_iter().map(|path| open_header(path)).collect();
    let mut headers = Vec::new();
    for (path, obj) in files.iter().zip(parsed) {
        if let Some(obj) = obj? {
            headers.push((path, obj));
        }
    }
    if headers.is_empty() {
        let hint = if subdirs.is_empty() {
            String::new()
        } else {
            format!(
                "; it has {} sub-folder(s), which are not searched: list the series of a \
                 folder tree with `tomograf scan` (scan_dicom_tree in Rust)",
                subdirs.len()
            )
        };
        return Err(DatasetError::series(
            dir,
            format!(
                "no DICOM files (Part-10 files with the DICM marker) in this folder \
                 ({} other file(s)){hint}",
                files.len()
            ),
        ));
    }

    let mut series: BTreeMap<String, usize> = BTreeMap::new();
    for (path, obj) in &headers {
        *series
            .entry(required_str(path, obj, tags::SERIES_INSTANCE_UID)?)
            .or_default() += 1;
    }
    if series.len() > 1 {
        let list: Vec<String> = series
            .iter()
            .map(|(uid, n)| format!("{uid} ({n} files)"))
            .collect();
        return Err(DatasetError::series(
            dir,
            format!(
                "the folder holds {} series, expected one: {}; put each series in its own \
                 folder (`tomograf scan`, or scan_dicom_tree in Rust, lists the series of a folder tree)",
                series.len(),
                list.join(", ")
            ),
        ));
    }
    if !allow_non_ct {
        for (path, obj) in &headers {
            let modality = optional_str(obj, tags::MODALITY);
            if modality != "CT" {
                return Err(DatasetError::unsupported(
                    path,
                    format!(
                        "modality is {modality:?}, not CT (--allow-non-ct, or \
                         allow_non_ct = true in a scene's [volume], reads other modalities \
                         anyway)"
                    ),
                ));
            }
        }
    }
    let mut slices = headers
        .iter()
        .map(|(path, obj)| {
            let slice = parse_slice(path, obj)?;
            if !allow_non_ct {
                check_rescale_tags(path, obj)?;
            }
            Ok(slice)
        })
        .collect::<Result<Vec<_>>>()?;
    drop(headers);

    let (spacing, origin, direction) = stack_geometry(dir, &mut slices)?;
    let dims = [
        slices[0].cols as usize,
        slices[0].rows as usize,
        slices.len(),
    ];
    let count = checked_voxel_count(dims).map_err(|e| DatasetError::TooLarge {
        path: dir.to_owned(),
        detail: e.to_string(),
    })?;
    // Every slice's file must be able to hold its pixels before the volume is allocated
    // (a header can claim 8000 × 8000 pixels in a 1 kB file).
    for slice in &slices {
        slice.check_file_holds_pixels()?;
    }
    let mut data = vec![0.0f32; count];
    // Slices decoded in parallel, each into its own plane; first error in slice order.
    let decoded: Vec<Result<()>> = slices
        .par_iter()
        .zip(data.par_chunks_exact_mut(dims[0] * dims[1]))
        .map(|(slice, out)| read_pixels(slice, out))
        .collect();
    decoded.into_iter().collect::<Result<()>>()?;
    Volume::new(dims, spacing, origin, direction, data).map_err(|source| DatasetError::Volume {
        path: dir.to_owned(),
        source,
    })
}

/// Lists the series under `root`, searching every sub-folder (LIDC-IDRI's layout is
/// `patient/study/series/*.dcm`): one [`SeriesInfo`] per folder and series, sorted by
/// folder then series UID. Files that are not DICOM, cannot be parsed or have no
/// `SeriesInstanceUID` are skipped; a folder that cannot be listed is an error.
/// Only headers are read (up to the pixel data), so scanning is fast.
pub fn scan_dicom_tree(root: &Path) -> Result<Vec<SeriesInfo>> {
    Ok(scan_dicom_tree_reporting(root)?.0)
}

/// Files a scan skipped: each path with the reason it could not be read.
pub type Skipped = Vec<(PathBuf, String)>;

/// [`scan_dicom_tree`], also returning the files that are DICOM (they carry the `DICM`
/// marker) but could not be read, each with the reason, so that a scan can say what it
/// skipped.
pub fn scan_dicom_tree_reporting(root: &Path) -> Result<(Vec<SeriesInfo>, Skipped)> {
    let mut skipped = Vec::new();
    let mut found = Vec::new();
    let mut pending = vec![root.to_owned()];
    while let Some(dir) = pending.pop() {
        let (files, subdirs) = list_dir(&dir)?;
        let mut in_dir: BTreeMap<String, SeriesInfo> = BTreeMap::new();
        for path in &files {
            let obj = match open_header(path) {
                Ok(Some(obj)) => obj,
                Ok(None) => continue,
                Err(e) => {
                    skipped.push((path.clone(), e.to_string()));
                    continue;
                }
            };
            let uid = match required_str(path, &obj, tags::SERIES_INSTANCE_UID) {
                Ok(uid) => uid,
                Err(e) => {
                    skipped.push((path.clone(), e.to_string()));
                    continue;
                }
            };
            let info = in_dir.entry(uid.clone()).or_insert_with(|| SeriesInfo {
                series_uid: uid,
                folder: dir.clone(),
                files: 0,
                modality: optional_str(&obj, tags::MODALITY),
                description: optional_str(&obj, tags::SERIES_DESCRIPTION),
                rows: optional_uint(path, &obj, tags::ROWS)
                    .ok()
                    .flatten()
                    .unwrap_or(0),
                cols: optional_uint(path, &obj, tags::COLUMNS)
                    .ok()
                    .flatten()
                    .unwrap_or(0),
            });
            info.files += 1;
        }
        found.extend(in_dir.into_values());
        pending.extend(subdirs);
    }
    found.sort_by(|a, b| (&a.folder, &a.series_uid).cmp(&(&b.folder, &b.series_uid)));
    skipped.sort();
    Ok((found, skipped))
}

/// The regular files and the sub-folders of `dir`, each sorted by name. Symbolic links to
/// folders are not followed (no cycles).
fn list_dir(dir: &Path) -> Result<(Vec<PathBuf>, Vec<PathBuf>)> {
    let io = |e| DatasetError::io(dir, "listing the folder", e);
    let (mut files, mut subdirs) = (Vec::new(), Vec::new());
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let entry = entry.map_err(io)?;
        let path = entry.path();
        if entry.file_type().map_err(io)?.is_dir() {
            subdirs.push(path);
        } else if path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    subdirs.sort();
    Ok((files, subdirs))
}

/// Checks that the slices make one regular stack, sorts them along the slice normal and
/// returns (spacing, origin, direction) as described in the module docs.
fn stack_geometry(dir: &Path, slices: &mut [Slice]) -> Result<(DVec3, DVec3, DMat3)> {
    let first = &slices[0];
    for s in &slices[1..] {
        let differs = |what: &str, a: String, b: String| {
            DatasetError::series(
                dir,
                format!(
                    "the slices differ in {what}: {} has {a}, {} has {b}",
                    name(&first.path),
                    name(&s.path)
                ),
            )
        };
        if (s.rows, s.cols) != (first.rows, first.cols) {
            let size = |s: &Slice| format!("{} rows × {} columns", s.rows, s.cols);
            return Err(differs("size", size(first), size(s)));
        }
        if (0..2).any(|a| {
            (s.pixel_spacing[a] - first.pixel_spacing[a]).abs() > 1e-4 * first.pixel_spacing[a]
        }) {
            let ps = |s: &Slice| format!("PixelSpacing {:?} mm", s.pixel_spacing);
            return Err(differs("pixel spacing", ps(first), ps(s)));
        }
        if (0..6).any(|a| (s.orientation[a] - first.orientation[a]).abs() > ORIENTATION_TOL) {
            let iop = |s: &Slice| format!("ImageOrientationPatient {:?}", s.orientation);
            return Err(differs("orientation", iop(first), iop(s)));
        }
    }
    let o = first.orientation;
    let (row, col) = (DVec3::new(o[0], o[1], o[2]), DVec3::new(o[3], o[4], o[5]));
    if (row.length() - 1.0).abs() > 1e-3
        || (col.length() - 1.0).abs() > 1e-3
        || row.dot(col).abs() > 1e-3
    {
        return Err(invalid(
            &first.path,
            tags::IMAGE_ORIENTATION_PATIENT,
            format!("{o:?}: not two orthogonal unit vectors"),
        ));
    }
    let row = row.normalize();
    let col = (col - row * row.dot(col)).normalize();
    let normal = row.cross(col);
    if slices.len() < 2 {
        return Err(DatasetError::series(
            dir,
            format!(
                "only one slice ({}): a volume needs at least 2",
                name(&first.path)
            ),
        ));
    }

    slices.sort_by(|a, b| a.position.dot(normal).total_cmp(&b.position.dot(normal)));
    let z: Vec<f64> = slices.iter().map(|s| s.position.dot(normal)).collect();
    let gaps: Vec<f64> = z.windows(2).map(|w| w[1] - w[0]).collect();
    let label = |k: usize| format!("{} ({})", k, name(&slices[k].path));
    if let Some(k) = gaps.iter().position(|&g| g < DUPLICATE_TOL) {
        return Err(DatasetError::series(
            dir,
            format!(
                "slices {} and {} are at the same position ({:.4} mm along the slice normal): \
                 duplicate slices",
                label(k),
                label(k + 1),
                z[k]
            ),
        ));
    }
    let mut sorted_gaps = gaps.clone();
    sorted_gaps.sort_by(f64::total_cmp);
    let typical = sorted_gaps[(sorted_gaps.len() - 1) / 2];
    let tol = (GAP_REL_TOL * typical).max(GAP_ABS_TOL);
    if let Some(k) = gaps.iter().position(|&g| (g - typical).abs() > tol) {
        return Err(DatasetError::series(
            dir,
            format!(
                "uneven slice spacing: sorted slices {} and {} are {:.4} mm apart but the \
                 typical spacing is {typical:.4} mm (a slice may be missing, or two \
                 acquisitions are mixed)",
                label(k),
                label(k + 1),
                gaps[k]
            ),
        ));
    }
    let p0 = slices[0].position;
    for (k, s) in slices.iter().enumerate().skip(1) {
        let d = s.position - p0;
        let along = d.dot(normal);
        let across = (d - normal * along).length();
        if across > TILT_TOL * along + GAP_ABS_TOL {
            return Err(DatasetError::unsupported(
                dir,
                format!(
                    "gantry tilt or sheared stack: slice {} is {across:.3} mm off the line \
                     through the first slice along the slice normal ({:.3}° from it); \
                     resample the series first",
                    label(k),
                    across.atan2(along).to_degrees()
                ),
            ));
        }
    }
    let mean_gap = (z[z.len() - 1] - z[0]) / (z.len() - 1) as f64;
    let [row_spacing, col_spacing] = slices[0].pixel_spacing;
    let spacing = DVec3::new(col_spacing, row_spacing, mean_gap);
    Ok((spacing, p0, DMat3::from_cols(row, col, normal)))
}

/// The file name of `path`, for messages that already name its folder.
fn name(path: &Path) -> Cow<'_, str> {
    path.file_name()
        .unwrap_or(path.as_os_str())
        .to_string_lossy()
}
