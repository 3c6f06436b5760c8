//! DICOM series reader: synthetic CT series are written with `dicom-object`'s own writer
//! (CT Image Storage, one slice per file, files named and written out of order) and read
//! back; expected geometry and values are computed here from what was written.

use dicom_core::value::{PixelFragmentSequence, PrimitiveValue, Value};
use dicom_core::{DataElement, Tag, VR};
use dicom_dictionary_std::{tags, uids};
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};
use glam::{DMat3, DVec3};
use std::path::Path;
use tomograf_datasets::DatasetError;
use tomograf_datasets::dicom::{read_dicom_series, scan_dicom_tree};

const SERIES: &str = "1.2.826.0.1.3680043.8.498.1";
const BIG_ENDIAN: &str = "1.2.840.10008.1.2.2";

/// One slice to write. `stored` holds `rows × cols` int16 values, column index fastest.
#[derive(Clone)]
struct Spec {
    position: DVec3,
    row: DVec3,
    col: DVec3,
    rows: u16,
    cols: u16,
    pixel_spacing: [f64; 2],
    series: String,
    modality: &'static str,
    instance: u32,
    stored: Vec<i16>,
    transfer_syntax: &'static str,
    /// Tags to leave out.
    omit: Vec<Tag>,
}

fn ds(values: &[f64]) -> PrimitiveValue {
    let s: Vec<String> = values.iter().map(|v| format!("{v:.10}")).collect();
    PrimitiveValue::from(s.join("\\"))
}

fn write_slice(path: &Path, s: &Spec) {
    let sop = format!("{}.{}", s.series, s.instance + 1000);
    let mut obj = InMemDicomObject::new_empty();
    let mut put = |tag: Tag, vr: VR, v: PrimitiveValue| {
        if !s.omit.contains(&tag) {
            obj.put(DataElement::new(tag, vr, v));
        }
    };
    put(tags::SOP_CLASS_UID, VR::UI, uids::CT_IMAGE_STORAGE.into());
    put(tags::SOP_INSTANCE_UID, VR::UI, sop.as_str().into());
    put(tags::MODALITY, VR::CS, s.modality.into());
    put(tags::SERIES_DESCRIPTION, VR::LO, "synthetic".into());
    put(tags::SERIES_INSTANCE_UID, VR::UI, s.series.as_str().into());
    put(tags::INSTANCE_NUMBER, VR::IS, s.instance.to_string().into());
    put(
        tags::IMAGE_POSITION_PATIENT,
        VR::DS,
        ds(&s.position.to_array()),
    );
    let iop = [s.row.to_array(), s.col.to_array()].concat();
    put(tags::IMAGE_ORIENTATION_PATIENT, VR::DS, ds(&iop));
    put(tags::SAMPLES_PER_PIXEL, VR::US, 1u16.into());
    put(
        tags::PHOTOMETRIC_INTERPRETATION,
        VR::CS,
        "MONOCHROME2".into(),
    );
    put(tags::ROWS, VR::US, s.rows.into());
    put(tags::COLUMNS, VR::US, s.cols.into());
    put(tags::PIXEL_SPACING, VR::DS, ds(&s.pixel_spacing));
    put(tags::BITS_ALLOCATED, VR::US, 16u16.into());
    put(tags::BITS_STORED, VR::US, 16u16.into());
    put(tags::HIGH_BIT, VR::US, 15u16.into());
    put(tags::PIXEL_REPRESENTATION, VR::US, 1u16.into());
    put(tags::RESCALE_INTERCEPT, VR::DS, "-1024".into());
    put(tags::RESCALE_SLOPE, VR::DS, "2".into());
    let words: Vec<u16> = s.stored.iter().map(|&v| v as u16).collect();
    put(tags::PIXEL_DATA, VR::OW, PrimitiveValue::U16(words.into()));
    let file = obj
        .with_meta(FileMetaTableBuilder::new().transfer_syntax(s.transfer_syntax))
        .unwrap();
    file.write_to_file(path).unwrap();
}

/// Slice-to-file-name permutation: files are named (and written) out of order.
const NAMES: [usize; 6] = [3, 0, 5, 1, 4, 2];

/// An oblique but orthonormal orientation: x and y rotated by 0.4 rad about (1, 2, 3).
fn oblique() -> DMat3 {
    DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.4)
}

/// Stored value of pixel (i, j) of slice `k` (k in writing order).
fn stored(i: usize, j: usize, k: usize) -> i16 {
    (i as i16) + 10 * (j as i16) + 100 * (k as i16) - 300
}

/// The 5 columns × 4 rows × 6 slices series of the tests: PixelSpacing [0.8, 0.6], slices
/// 2.5 mm apart along ±normal (`sign`) from `base`.
fn series_specs(sign: f64, transfer_syntax: &'static str) -> Vec<Spec> {
    let r = oblique();
    let base = DVec3::new(-12.5, 30.25, 101.0);
    (0..6)
        .map(|k| Spec {
            position: base + r.z_axis * (sign * 2.5 * k as f64),
            row: r.x_axis,
            col: r.y_axis,
            rows: 4,
            cols: 5,
            pixel_spacing: [0.8, 0.6],
            series: SERIES.into(),
            modality: "CT",
            instance: k as u32 + 1,
            stored: (0..20).map(|p| stored(p % 5, p / 5, k)).collect(),
            transfer_syntax,
            omit: vec![],
        })
        .collect()
}

fn write_series(dir: &Path, specs: &[Spec]) {
    for (k, s) in specs.iter().enumerate().rev() {
        write_slice(
            &dir.join(format!("IM{:03}.dcm", NAMES[k % 6] + 6 * (k / 6))),
            s,
        );
    }
}

fn file_of(k: usize) -> String {
    format!("IM{:03}.dcm", NAMES[k])
}

fn error_of(dir: &Path) -> (DatasetError, String) {
    let e = read_dicom_series(dir, false).expect_err("the series must be refused");
    let msg = e.to_string();
    (e, msg)
}

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).abs().max_element() < tol
}

fn check_ascending(transfer_syntax: &'static str) {
    let dir = tempfile::tempdir().unwrap();
    let specs = series_specs(1.0, transfer_syntax);
    write_series(dir.path(), &specs);
    let v = read_dicom_series(dir.path(), false).unwrap();
    let r = oblique();
    assert_eq!(v.dims(), [5, 4, 6]);
    assert!(
        close(v.spacing(), DVec3::new(0.6, 0.8, 2.5), 1e-9),
        "{}",
        v.spacing()
    );
    assert!(close(v.origin(), specs[0].position, 1e-9));
    for (got, want) in [
        (v.direction().x_axis, r.x_axis),
        (v.direction().y_axis, r.y_axis),
    ] {
        assert!(close(got, want, 1e-9), "{got} vs {want}");
    }
    assert!(close(v.direction().z_axis, r.z_axis, 1e-9));
    for (i, j, k) in [
        (0, 0, 0),
        (4, 0, 0),
        (0, 3, 0),
        (2, 1, 3),
        (4, 3, 5),
        (1, 2, 5),
    ] {
        let hu = 2.0 * stored(i, j, k) as f32 - 1024.0;
        assert_eq!(v.get(i, j, k), hu, "voxel ({i}, {j}, {k})");
        let p = v.index_to_world(DVec3::new(i as f64, j as f64, k as f64));
        let want = specs[k].position + r.x_axis * (i as f64 * 0.6) + r.y_axis * (j as f64 * 0.8);
        assert!(close(p, want, 1e-9), "voxel ({i}, {j}, {k}): {p} vs {want}");
    }
}

#[test]
fn oblique_series_explicit_little_endian() {
    check_ascending(uids::EXPLICIT_VR_LITTLE_ENDIAN);
}

#[test]
fn oblique_series_implicit_little_endian() {
    check_ascending(uids::IMPLICIT_VR_LITTLE_ENDIAN);
}

#[test]
fn oblique_series_explicit_big_endian() {
    check_ascending(BIG_ENDIAN);
}

#[test]
fn descending_positions_are_sorted_along_the_normal() {
    let dir = tempfile::tempdir().unwrap();
    let specs = series_specs(-1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    write_series(dir.path(), &specs);
    let v = read_dicom_series(dir.path(), false).unwrap();
    assert_eq!(v.dims(), [5, 4, 6]);
    assert!(close(v.origin(), specs[5].position, 1e-9));
    assert!(close(v.direction().z_axis, oblique().z_axis, 1e-9));
    assert!((v.spacing().z - 2.5).abs() < 1e-9);
    for k in 0..6 {
        assert_eq!(v.get(3, 2, k), 2.0 * stored(3, 2, 5 - k) as f32 - 1024.0);
    }
}

#[test]
fn other_files_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    write_series(
        dir.path(),
        &series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN),
    );
    std::fs::write(dir.path().join("069.xml"), "<LidcReadMessage/>").unwrap();
    std::fs::write(dir.path().join("tiny"), "x").unwrap();
    assert_eq!(
        read_dicom_series(dir.path(), false).unwrap().dims(),
        [5, 4, 6]
    );
}

#[test]
fn missing_middle_slice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    write_series(dir.path(), &specs);
    std::fs::remove_file(dir.path().join(file_of(3))).unwrap();
    let (e, msg) = error_of(dir.path());
    assert!(matches!(e, DatasetError::Series { .. }), "{msg}");
    assert!(
        msg.contains("uneven slice spacing") && msg.contains("5.0000 mm"),
        "{msg}"
    );
    assert!(
        msg.contains(&file_of(2)) && msg.contains(&file_of(4)),
        "{msg}"
    );

    // Duplicate positions.
    specs.truncate(3);
    specs[2].position = specs[1].position;
    let dir = tempfile::tempdir().unwrap();
    write_series(dir.path(), &specs);
    let (_, msg) = error_of(dir.path());
    assert!(msg.contains("duplicate slices"), "{msg}");
}

#[test]
fn inconsistent_slices_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    specs[2].rows = 5;
    specs[2].stored = vec![0; 25];
    write_series(dir.path(), &specs);
    let (_, msg) = error_of(dir.path());
    assert!(
        msg.contains("differ in size") && msg.contains("5 rows × 5 columns"),
        "{msg}"
    );

    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    specs[4].row = DVec3::X;
    specs[4].col = DVec3::Y;
    write_series(dir.path(), &specs);
    let (_, msg) = error_of(dir.path());
    assert!(msg.contains("differ in orientation"), "{msg}");

    // Gantry tilt: each slice shifted along the column direction (10°).
    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    for (k, s) in specs.iter_mut().enumerate() {
        s.position += s.col * (2.5 * k as f64 * 10f64.to_radians().tan());
    }
    write_series(dir.path(), &specs);
    let (e, msg) = error_of(dir.path());
    assert!(matches!(e, DatasetError::Unsupported { .. }), "{msg}");
    assert!(
        msg.contains("gantry tilt") && msg.contains("10.000°"),
        "{msg}"
    );
}

#[test]
fn non_ct_modality_needs_permission() {
    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    for s in &mut specs {
        s.modality = "MR";
    }
    write_series(dir.path(), &specs);
    let (_, msg) = error_of(dir.path());
    assert!(
        msg.contains("\"MR\", not CT") && msg.contains("allow_non_ct"),
        "{msg}"
    );
    assert_eq!(
        read_dicom_series(dir.path(), true).unwrap().dims(),
        [5, 4, 6]
    );
}

#[test]
fn two_series_in_one_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    for s in &mut specs[..2] {
        s.series = "1.2.3.4".into();
    }
    write_series(dir.path(), &specs);
    let (_, msg) = error_of(dir.path());
    assert!(msg.contains("holds 2 series"), "{msg}");
    assert!(msg.contains("1.2.3.4 (2 files)") && msg.contains(&format!("{SERIES} (4 files)")));
    assert!(msg.contains("scan_dicom_tree"), "{msg}");
}

#[test]
fn compressed_transfer_syntax_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    write_series(
        dir.path(),
        &series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN),
    );
    // Replace one slice with a "JPEG baseline" one holding junk encapsulated data.
    let mut obj = InMemDicomObject::new_empty();
    let spec = &series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN)[1];
    obj.put(DataElement::new(
        tags::SOP_CLASS_UID,
        VR::UI,
        uids::CT_IMAGE_STORAGE,
    ));
    obj.put(DataElement::new(tags::SOP_INSTANCE_UID, VR::UI, "1.2.3.99"));
    obj.put(DataElement::new(tags::MODALITY, VR::CS, "CT"));
    obj.put(DataElement::new(tags::SERIES_INSTANCE_UID, VR::UI, SERIES));
    obj.put(DataElement::new(
        tags::IMAGE_POSITION_PATIENT,
        VR::DS,
        ds(&spec.position.to_array()),
    ));
    let fragments = PixelFragmentSequence::new(vec![], vec![vec![0xFF, 0xD8, 1, 2, 3, 4]]);
    obj.put(DataElement::new(
        tags::PIXEL_DATA,
        VR::OB,
        Value::from(fragments),
    ));
    let file = obj
        .with_meta(FileMetaTableBuilder::new().transfer_syntax(uids::JPEG_BASELINE8_BIT))
        .unwrap();
    file.write_to_file(dir.path().join(file_of(1))).unwrap();
    let (e, msg) = error_of(dir.path());
    assert!(matches!(e, DatasetError::Unsupported { .. }), "{msg}");
    assert!(
        msg.contains(&file_of(1)) && msg.contains("1.2.840.10008.1.2.4.50"),
        "{msg}"
    );
    assert!(
        msg.contains("compressed transfer syntax") && msg.contains("gdcmconv --raw"),
        "{msg}"
    );
}

#[test]
fn truncated_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    write_series(
        dir.path(),
        &series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN),
    );
    let victim = dir.path().join(file_of(4));
    let bytes = std::fs::read(&victim).unwrap();
    std::fs::write(&victim, &bytes[..bytes.len() - 7]).unwrap();
    let (e, msg) = error_of(dir.path());
    assert!(matches!(e, DatasetError::Truncated { .. }), "{msg}");
    assert!(msg.contains(&file_of(4)), "{msg}");

    // Pixel data shorter than Rows × Columns (a well-formed element).
    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    specs[0].stored.truncate(12);
    write_series(dir.path(), &specs);
    let (e, msg) = error_of(dir.path());
    assert!(matches!(e, DatasetError::Truncated { .. }), "{msg}");
    assert!(
        msg.contains(&file_of(0)) && msg.contains("PixelData holds 24 bytes"),
        "{msg}"
    );
}

#[test]
fn missing_tags_and_too_few_slices_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    specs[2].omit = vec![tags::PIXEL_SPACING];
    write_series(dir.path(), &specs);
    let (e, msg) = error_of(dir.path());
    assert!(matches!(e, DatasetError::Corrupt { .. }), "{msg}");
    assert!(
        msg.contains(&file_of(2)) && msg.contains("missing required tag PixelSpacing (0028,0030)"),
        "{msg}"
    );

    let dir = tempfile::tempdir().unwrap();
    write_series(
        dir.path(),
        &series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN)[..1],
    );
    let (_, msg) = error_of(dir.path());
    assert!(
        msg.contains("only one slice") && msg.contains("at least 2"),
        "{msg}"
    );
}

#[test]
fn empty_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    std::fs::write(dir.path().join("notes.txt"), "hello").unwrap();
    let (e, msg) = error_of(dir.path());
    assert!(matches!(e, DatasetError::Series { .. }), "{msg}");
    assert!(
        msg.contains("no DICOM files") && msg.contains("scan_dicom_tree"),
        "{msg}"
    );
    let missing = dir.path().join("absent");
    assert!(matches!(
        read_dicom_series(&missing, false),
        Err(DatasetError::Io { .. })
    ));
}

#[test]
fn scan_finds_nested_series() {
    let root = tempfile::tempdir().unwrap();
    let ct = root.path().join("LIDC-IDRI-0001/study/3000566");
    let dx = root.path().join("LIDC-IDRI-0001/study2/3000923");
    std::fs::create_dir_all(&ct).unwrap();
    std::fs::create_dir_all(&dx).unwrap();
    write_series(&ct, &series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN));
    std::fs::write(ct.join("069.xml"), "<xml/>").unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN)[..2].to_vec();
    for s in &mut specs {
        s.series = "1.2.3.4".into();
        s.modality = "DX";
    }
    write_series(&dx, &specs);
    std::fs::write(root.path().join("README"), "not dicom").unwrap();

    let found = scan_dicom_tree(root.path()).unwrap();
    assert_eq!(found.len(), 2, "{found:?}");
    assert_eq!(
        (found[0].folder.as_path(), found[0].files),
        (ct.as_path(), 6)
    );
    assert_eq!(
        (found[0].series_uid.as_str(), found[0].modality.as_str()),
        (SERIES, "CT")
    );
    assert_eq!((found[0].rows, found[0].cols), (4, 5));
    assert_eq!(found[0].description, "synthetic");
    assert_eq!(
        (found[1].folder.as_path(), found[1].files),
        (dx.as_path(), 2)
    );
    assert_eq!(
        (found[1].series_uid.as_str(), found[1].modality.as_str()),
        ("1.2.3.4", "DX")
    );
    assert_eq!(
        read_dicom_series(&found[0].folder, false).unwrap().dims(),
        [5, 4, 6]
    );
}

#[test]
fn write_then_read_round_trips_geometry_and_whole_hu() {
    use tomograf_datasets::dicom::write_dicom_series;
    use tomograf_sim::Volume;
    // Oblique, left-handed storage (k against i × j), odd sizes, integer HU.
    let r = oblique() * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0));
    let (nx, ny, nz) = (7, 5, 4);
    let data: Vec<f32> = (0..nx * ny * nz)
        .map(|n| (n as f32 * 13.0) % 3000.0 - 1000.0)
        .collect();
    let vol = Volume::new(
        [nx, ny, nz],
        DVec3::new(0.7, 0.9, 2.5),
        DVec3::new(-3.0, 40.0, 12.0),
        r,
        data,
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_dicom_series(dir.path(), &vol, "1.2.826.0.1.3680043.8.498.77").unwrap();
    let back = read_dicom_series(dir.path(), false).unwrap();
    assert_eq!(back.dims(), vol.dims());
    assert!((back.spacing() - vol.spacing()).length() < 1e-5);
    // The reader stacks slices along i × j, so k may come back reversed: compare voxels by
    // world position instead of by index.
    for (i, j, k) in [(0, 0, 0), (6, 4, 3), (3, 2, 1), (1, 4, 2)] {
        let p = vol.index_to_world(DVec3::new(i as f64, j as f64, k as f64));
        let q = back.world_to_index(p);
        let (bi, bj, bk) = (
            q.x.round() as usize,
            q.y.round() as usize,
            q.z.round() as usize,
        );
        assert!(
            (q - DVec3::new(bi as f64, bj as f64, bk as f64)).length() < 1e-4,
            "{q}"
        );
        assert_eq!(back.get(bi, bj, bk), vol.get(i, j, k));
    }
    assert!(write_dicom_series(dir.path(), &vol, "not a uid").is_err());
}

/// Slices are parsed and decoded in parallel; with several bad slices the error names the
/// first in file order (headers) or slice order (pixels), whatever the thread count.
#[test]
fn the_first_bad_slice_is_reported_whatever_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut specs = series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN);
    specs[2].stored.truncate(12);
    specs[4].stored.truncate(8);
    write_series(dir.path(), &specs);
    let message = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| error_of(dir.path()).1)
    };
    let one = message(1);
    assert!(
        one.contains(&file_of(2)) && one.contains("PixelData holds 24 bytes"),
        "{one}"
    );
    for threads in [2, 4, 7] {
        assert_eq!(message(threads), one, "{threads} threads");
    }
}

/// A meta header whose TransferSyntaxUID does not match how the data set is encoded (an
/// explicit-VR file labelled implicit, or big endian) is named as such: it was reported as
/// "file is truncated" (issue 51), which sent users looking for a cut-off download.
#[test]
fn a_transfer_syntax_that_does_not_match_the_data_set_is_named() {
    for (label, want) in [
        (&b"1.2.840.10008.1.2\0\0\0"[..], "'1.2.840.10008.1.2'"),
        (&b"1.2.840.10008.1.2.2\0"[..], "'1.2.840.10008.1.2.2'"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        write_series(
            dir.path(),
            &series_specs(1.0, uids::EXPLICIT_VR_LITTLE_ENDIAN),
        );
        let explicit = b"1.2.840.10008.1.2.1\0";
        for entry in std::fs::read_dir(dir.path()).unwrap() {
            let path = entry.unwrap().path();
            let mut bytes = std::fs::read(&path).unwrap();
            let at = bytes
                .windows(explicit.len())
                .position(|w| w == explicit)
                .expect("the meta group's transfer syntax");
            bytes[at..at + explicit.len()].copy_from_slice(label);
            std::fs::write(&path, bytes).unwrap();
        }
        let (_, msg) = error_of(dir.path());
        assert!(
            msg.contains(&format!("its TransferSyntaxUID (0002,0010) is {want}"))
                && msg.contains("encoded as explicit VR little endian")
                && !msg.contains("file is truncated"),
            "{msg}"
        );
    }
}
