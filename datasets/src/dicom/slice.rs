//! One slice file: header parsing (tags, transfer syntax) and pixel decoding.

use crate::error::{DatasetError, Result};
use dicom_core::Tag;
use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry};
use dicom_core::value::{PrimitiveValue, Value};
use dicom_dictionary_std::{StandardDataDictionary, tags, uids};
use dicom_object::mem::InMemElement;
use dicom_object::{DefaultDicomObject, InMemDicomObject, OpenFileOptions, ReadError};
use dicom_transfer_syntax_registry::{TransferSyntaxIndex, TransferSyntaxRegistry};
use glam::DVec3;
use std::borrow::Cow;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Explicit VR Big Endian (retired from the standard, still found in old archives).
const EXPLICIT_VR_BIG_ENDIAN: &str = "1.2.840.10008.1.2.2";

/// What the reader needs from one slice's header (everything before the pixel data).
pub(super) struct Slice {
    pub(super) path: PathBuf,
    /// `ImagePositionPatient`, mm (LPS): centre of the first pixel.
    pub(super) position: DVec3,
    /// `ImageOrientationPatient`: row cosine, then column cosine.
    pub(super) orientation: [f64; 6],
    /// `PixelSpacing` (row spacing, column spacing), mm.
    pub(super) pixel_spacing: [f64; 2],
    pub(super) rows: u32,
    pub(super) cols: u32,
    format: PixelFormat,
}

/// How to turn one slice's pixel bytes into values.
#[derive(Clone, Copy)]
struct PixelFormat {
    bits_allocated: u32,
    bits_stored: u32,
    signed: bool,
    big_endian: bool,
    slope: f64,
    intercept: f64,
}

/// Parses the header (everything before the pixel data) of a DICOM Part-10 file; `None`
/// for files without the `DICM` marker and for DICOMDIR files.
pub(super) fn open_header(path: &Path) -> Result<Option<DefaultDicomObject>> {
    let mut head = Vec::with_capacity(132);
    File::open(path)
        .and_then(|f| f.take(132).read_to_end(&mut head))
        .map_err(|e| DatasetError::io(path, "reading", e))?;
    if head.len() < 132 || &head[128..] != b"DICM" {
        return Ok(None);
    }
    // Declared lengths against the file's size before the parser allocates them.
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, "reading", e))?;
    super::lengths::check(path, &bytes)?;
    let obj = OpenFileOptions::new()
        .read_until(tags::PIXEL_DATA)
        .open_file(path)
        .map_err(|e| open_error(path, e))?;
    Ok(
        (obj.meta().media_storage_sop_class_uid() != uids::MEDIA_STORAGE_DIRECTORY_STORAGE)
            .then_some(obj),
    )
}

/// A [`DatasetError`] for a file `dicom-object` could not read: its transfer syntax is
/// unsupported, it ends early, or it is malformed (the whole error chain is quoted).
fn open_error(path: &Path, e: ReadError) -> DatasetError {
    match &e {
        ReadError::ReadUnrecognizedTransferSyntax { uid, .. } => {
            return unsupported_syntax(path, uid);
        }
        ReadError::ReadUnsupportedTransferSyntax { uid, .. }
        | ReadError::ReadUnsupportedTransferSyntaxWithSuggestion { uid, .. } => {
            return unsupported_syntax(path, uid);
        }
        _ => {}
    }
    let (mut message, mut eof) = (e.to_string(), false);
    let mut source = std::error::Error::source(&e);
    while let Some(s) = source {
        eof |= s
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::UnexpectedEof);
        message = format!("{message}: {s}");
        source = s.source();
    }
    if eof {
        DatasetError::truncated(
            path,
            format!(
                "the DICOM data ends early, or does not match the transfer syntax its header \
                 names (implicit/explicit VR, byte order) ({message})"
            ),
        )
    } else {
        DatasetError::corrupt(path, format!("cannot parse the DICOM file: {message}"))
    }
}

/// Whether the transfer syntax `uid` is big-endian; an error unless it is uncompressed.
fn byte_order(path: &Path, uid: &str) -> Result<bool> {
    match uid {
        uids::IMPLICIT_VR_LITTLE_ENDIAN | uids::EXPLICIT_VR_LITTLE_ENDIAN => Ok(false),
        EXPLICIT_VR_BIG_ENDIAN => Ok(true),
        _ => Err(unsupported_syntax(path, uid)),
    }
}

fn unsupported_syntax(path: &Path, uid: &str) -> DatasetError {
    let name = TransferSyntaxRegistry
        .get(uid)
        .map_or("unknown transfer syntax", |ts| ts.name());
    DatasetError::unsupported(
        path,
        format!(
            "compressed transfer syntax {uid} ({name}); decompress the series first \
             (e.g. `gdcmconv --raw`)"
        ),
    )
}

/// Reads the geometry and pixel format of one slice, checking every value.
pub(super) fn parse_slice(path: &Path, obj: &DefaultDicomObject) -> Result<Slice> {
    let big_endian = byte_order(path, obj.meta().transfer_syntax())?;
    let frames = optional_uint(path, obj, tags::NUMBER_OF_FRAMES)?.unwrap_or(1);
    if frames != 1 {
        return Err(DatasetError::unsupported(
            path,
            format!("{frames} frames in one file: only single-frame slices can be read"),
        ));
    }
    let samples = optional_uint(path, obj, tags::SAMPLES_PER_PIXEL)?.unwrap_or(1);
    if samples != 1 {
        return Err(DatasetError::unsupported(
            path,
            format!(
                "{} is {samples}: only grey-level images (1) can be read",
                tag_name(tags::SAMPLES_PER_PIXEL)
            ),
        ));
    }
    let rows = required_uint(path, obj, tags::ROWS)?;
    let cols = required_uint(path, obj, tags::COLUMNS)?;
    if rows == 0 || cols == 0 {
        return Err(DatasetError::corrupt(
            path,
            format!("the image is {rows}×{cols} pixels"),
        ));
    }
    let bits_allocated = required_uint(path, obj, tags::BITS_ALLOCATED)?;
    if ![8, 16, 32].contains(&bits_allocated) {
        return Err(DatasetError::unsupported(
            path,
            format!(
                "{} is {bits_allocated}: only 8, 16 or 32 can be read",
                tag_name(tags::BITS_ALLOCATED)
            ),
        ));
    }
    let bits_stored = optional_uint(path, obj, tags::BITS_STORED)?.unwrap_or(bits_allocated);
    if !(1..=bits_allocated).contains(&bits_stored) {
        return Err(invalid(
            path,
            tags::BITS_STORED,
            format!("{bits_stored} (BitsAllocated is {bits_allocated})"),
        ));
    }
    let signed = match required_uint(path, obj, tags::PIXEL_REPRESENTATION)? {
        0 => false,
        1 => true,
        other => {
            return Err(invalid(
                path,
                tags::PIXEL_REPRESENTATION,
                format!("{other}, not 0 or 1"),
            ));
        }
    };
    let slope = optional_float(path, obj, tags::RESCALE_SLOPE)?.unwrap_or(1.0);
    let intercept = optional_float(path, obj, tags::RESCALE_INTERCEPT)?.unwrap_or(0.0);
    if !(slope.is_finite() && slope > 0.0) {
        return Err(invalid(
            path,
            tags::RESCALE_SLOPE,
            format!("{slope}: it must be finite and positive (0 makes every voxel the intercept)"),
        ));
    }
    if !intercept.is_finite() {
        return Err(invalid(
            path,
            tags::RESCALE_INTERCEPT,
            format!("{intercept}, not finite"),
        ));
    }
    let position = required_floats::<3>(path, obj, tags::IMAGE_POSITION_PATIENT)?;
    let orientation = required_floats::<6>(path, obj, tags::IMAGE_ORIENTATION_PATIENT)?;
    let pixel_spacing = required_floats::<2>(path, obj, tags::PIXEL_SPACING)?;
    if pixel_spacing.iter().any(|&s| s <= 0.0) {
        return Err(invalid(
            path,
            tags::PIXEL_SPACING,
            format!("{pixel_spacing:?} mm, not positive"),
        ));
    }
    Ok(Slice {
        path: path.to_owned(),
        position: DVec3::from_array(position),
        orientation,
        pixel_spacing,
        rows,
        cols,
        format: PixelFormat {
            bits_allocated,
            bits_stored,
            signed,
            big_endian,
            slope,
            intercept,
        },
    })
}

impl Slice {
    /// Errors when the slice's file is smaller than its pixels (rows × columns × bits
    /// allocated, native encoding), before anything is allocated for them.
    pub(super) fn check_file_holds_pixels(&self) -> Result<()> {
        let need =
            u64::from(self.rows) * u64::from(self.cols) * u64::from(self.format.bits_allocated) / 8;
        let len = std::fs::metadata(&self.path)
            .map_err(|e| DatasetError::io(&self.path, "reading the size of", e))?
            .len();
        if len < need {
            return Err(DatasetError::truncated(
                &self.path,
                format!(
                    "{} × {} pixels of {} bits need {need} bytes, but the file holds {len}",
                    self.rows, self.cols, self.format.bits_allocated
                ),
            ));
        }
        Ok(())
    }
}

/// Reads the whole file of `slice` and writes its rescaled pixel values into `out`
/// (`rows × cols`, column index fastest).
pub(super) fn read_pixels(slice: &Slice, out: &mut [f32]) -> Result<()> {
    let path = &slice.path;
    let obj = OpenFileOptions::new()
        .open_file(path)
        .map_err(|e| open_error(path, e))?;
    let f = slice.format;
    let element = element(&obj, tags::PIXEL_DATA).ok_or_else(|| missing(path, tags::PIXEL_DATA))?;
    // The bytes in file order: OB values are kept as read, OW words were decoded to native.
    let bytes: Cow<[u8]> = match element.value() {
        Value::Primitive(PrimitiveValue::U8(b)) => Cow::Borrowed(&b[..]),
        Value::Primitive(PrimitiveValue::U16(w)) => Cow::Owned(
            w.iter()
                .flat_map(|w| {
                    if f.big_endian {
                        w.to_be_bytes()
                    } else {
                        w.to_le_bytes()
                    }
                })
                .collect(),
        ),
        Value::PixelSequence(_) => {
            return Err(DatasetError::unsupported(
                path,
                "encapsulated (compressed) pixel data",
            ));
        }
        _ => {
            return Err(invalid(
                path,
                tags::PIXEL_DATA,
                format!("of type {:?}", element.vr()),
            ));
        }
    };
    let size = (f.bits_allocated / 8) as usize;
    let need = out.len() * size;
    // One pad byte makes an odd length even (PS3.5 §8.1.1); anything more means the header
    // does not describe the data (Rows, Columns or BitsAllocated wrong, or several frames).
    if bytes.len() > need + need % 2 {
        return Err(DatasetError::corrupt(
            path,
            format!(
                "PixelData holds {} bytes but {} rows × {} columns of {} bits need {need}: the \
                 header's Rows, Columns or BitsAllocated do not describe the pixel data (or it \
                 holds several frames, which is not supported)",
                bytes.len(),
                slice.rows,
                slice.cols,
                f.bits_allocated
            ),
        ));
    }
    if bytes.len() < need {
        return Err(DatasetError::truncated(
            path,
            format!(
                "PixelData holds {} bytes but {} rows × {} columns of {} bits need {need}",
                bytes.len(),
                slice.rows,
                slice.cols,
                f.bits_allocated
            ),
        ));
    }
    let shift = 32 - f.bits_stored;
    for (value, b) in out.iter_mut().zip(bytes.chunks_exact(size)) {
        let raw = match (size, f.big_endian) {
            (1, _) => b[0] as u32,
            (2, false) => u16::from_le_bytes([b[0], b[1]]) as u32,
            (2, true) => u16::from_be_bytes([b[0], b[1]]) as u32,
            (_, false) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            (_, true) => u32::from_be_bytes([b[0], b[1], b[2], b[3]]),
        };
        // Keep the low `bits_stored` bits; sign-extend them for signed data.
        let stored = if f.signed {
            ((raw << shift) as i32 >> shift) as f64
        } else {
            ((raw << shift) >> shift) as f64
        };
        *value = (stored * f.slope + f.intercept) as f32;
    }
    Ok(())
}

/// The element `tag` of `obj`, unless it is absent or empty.
pub(super) fn element(obj: &InMemDicomObject, tag: Tag) -> Option<&InMemElement> {
    obj.element_opt(tag)
        .ok()
        .flatten()
        .filter(|e| !matches!(e.value(), Value::Primitive(PrimitiveValue::Empty)))
}

/// "Alias (gggg,eeee)", e.g. "PixelSpacing (0028,0030)".
pub(super) fn tag_name(tag: Tag) -> String {
    let alias = StandardDataDictionary
        .by_tag(tag)
        .map_or("tag", |e| e.alias());
    format!("{alias} ({:04X},{:04X})", tag.group(), tag.element())
}

fn missing(path: &Path, tag: Tag) -> DatasetError {
    DatasetError::corrupt(path, format!("missing required tag {}", tag_name(tag)))
}

pub(super) fn invalid(path: &Path, tag: Tag, what: impl std::fmt::Display) -> DatasetError {
    DatasetError::corrupt(path, format!("invalid {}: {what}", tag_name(tag)))
}

/// A text value, trimmed; empty if absent.
pub(super) fn optional_str(obj: &InMemDicomObject, tag: Tag) -> String {
    element(obj, tag)
        .and_then(|e| e.to_str().ok())
        .map_or_else(String::new, |s| s.trim().trim_end_matches('\0').to_owned())
}

pub(super) fn required_str(path: &Path, obj: &InMemDicomObject, tag: Tag) -> Result<String> {
    Some(optional_str(obj, tag))
        .filter(|s| !s.is_empty())
        .ok_or_else(|| missing(path, tag))
}

pub(super) fn optional_uint(path: &Path, obj: &InMemDicomObject, tag: Tag) -> Result<Option<u32>> {
    element(obj, tag)
        .map(|e| e.to_int::<u32>().map_err(|e| invalid(path, tag, e)))
        .transpose()
}

fn required_uint(path: &Path, obj: &InMemDicomObject, tag: Tag) -> Result<u32> {
    optional_uint(path, obj, tag)?.ok_or_else(|| missing(path, tag))
}

fn optional_float(path: &Path, obj: &InMemDicomObject, tag: Tag) -> Result<Option<f64>> {
    let Some(e) = element(obj, tag) else {
        return Ok(None);
    };
    match e.to_float64() {
        Ok(v) if v.is_finite() => Ok(Some(v)),
        Ok(v) => Err(invalid(path, tag, format!("{v} is not finite"))),
        Err(err) => Err(invalid(path, tag, err)),
    }
}

/// Exactly `N` finite numbers (a multi-valued decimal string).
fn required_floats<const N: usize>(
    path: &Path,
    obj: &InMemDicomObject,
    tag: Tag,
) -> Result<[f64; N]> {
    let e = element(obj, tag).ok_or_else(|| missing(path, tag))?;
    let values = e
        .to_multi_float64()
        .map_err(|err| invalid(path, tag, err))?;
    match <[f64; N]>::try_from(values.as_slice()) {
        Ok(v) if v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => Err(invalid(
            path,
            tag,
            format!("{values:?}: expected {N} finite numbers"),
        )),
    }
}
