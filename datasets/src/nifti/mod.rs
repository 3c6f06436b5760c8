//! NIfTI-1 volumes (`.nii`, `.nii.gz`) ↔ [`Volume`], through the [`nifti`] crate.
//!
//! The crate parses and writes the header, decodes the voxels (any byte order) and applies
//! the value scaling; this module validates the header before anything large is allocated,
//! turns the crate's errors into [`DatasetError`]s that name the file, and converts the
//! geometry (RAS ↔ LPS; see [`read_nifti`]).
//!
//! # Conventions
//! NIfTI stores voxels with `i` fastest, as [`Volume`] does, and maps indices to **RAS**
//! millimetres; tomograf's world frame is **LPS**, so the affine's first two rows are
//! negated on reading and on writing (which affine is used is described on
//! [`read_nifti`]). Voxel `(i, j, k)` of the file is voxel `(i, j, k)` of the volume: no
//! resampling or reordering is done; orientation lives entirely in `direction` and `origin`.
//!
//! Values are converted to `f32` after applying `scl_slope`/`scl_inter`
//! (`value = stored · slope + inter`; slope 0 or non-finite means no scaling).
//! On reading, compression is detected from the gzip magic bytes, not from the file name.
//!
//! NIfTI-2 (540-byte header) is not supported (the crate handles NIfTI-1 only): such files
//! are refused with a clear error, and volumes with an axis longer than 32767 voxels (which
//! would need NIfTI-2) cannot be written.

mod affine;
mod decode;
mod inflate;

use crate::atomic::write_atomic_to_path;
use crate::error::{DatasetError, Result};
use decode::{decode_in_place, decode_parallel, decodes_in_place, scaling, zeroed_words};
use flate2::read::MultiGzDecoder;
use glam::{DMat3, DVec3};
use ndarray::{ArrayD, ArrayView3, ShapeBuilder};
use nifti::writer::WriterOptions;
use nifti::{
    Endianness, InMemNiftiVolume, IntoNdArray, NiftiError, NiftiHeader, NiftiType, Unit, XForm,
};
use rayon::prelude::*;
use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};
use std::path::Path;
use tomograf_sim::Volume;
use tomograf_sim::volume::MAX_VOXELS;

/// Size of a NIfTI-1 header in bytes.
const NIFTI1_SIZE: usize = 348;
/// The `sizeof_hdr` of a NIfTI-2 header.
const NIFTI2_SIZE: i32 = 540;
/// Where the voxels start in the files we write: header + 4-byte (zero) extension flag.
const WRITTEN_DATA_OFFSET: u64 = NIFTI1_SIZE as u64 + 4;
/// The most a deflate stream can expand: 1032 output bytes per input byte (RFC 1951: a
/// 258-byte match in as little as 2 bits, after the first).
const MAX_DEFLATE_RATIO: u64 = 1032;
/// Largest axis length a NIfTI-1 header can hold (`dim` is `int16`).
const NIFTI1_MAX_DIM: usize = i16::MAX as usize;

/// Reads a NIfTI-1 file (`.nii`, or gzip-compressed `.nii.gz`) into a [`Volume`] in the
/// LPS world frame.
///
/// * Dimensions: `dim[1..=3]` (missing ones count as 1). A 4-D or higher file whose
///   extra dimensions are all 1 is accepted; one with several volumes is refused.
/// * Values: stored type (uint8/16/32/64, int8/16/32/64, float32/64) → `f32`, with
///   `scl_slope`/`scl_inter` applied. NaN/Inf voxels are refused by [`Volume::new`].
/// * Geometry: sform if `sform_code > 0`, else qform if `qform_code > 0`, else
///   `pixdim` scaling with zero origin; RAS → LPS by negating x and y; spacing = the
///   affine's column norms (mm), direction = normalised columns, origin = translation.
///   Sheared affines (axes not orthogonal within 1e-4) are refused.
///
/// The header is validated before anything large is allocated; every error names the
/// file and the problem (truncated, not NIfTI, NIfTI-2, unsupported type or 4-D data, too
/// large, sheared…).
pub fn read_nifti(path: &Path) -> Result<Volume> {
    read_nifti_mapped(path, std::convert::identity)
}

/// As [`read_nifti`], with `map` applied to every voxel's value (after the header's
/// scaling) in the pass that decodes it, e.g. HU → mu: the same values as mapping the
/// volume afterwards, one pass over it fewer. The mapped values are the ones checked for
/// NaN and ±Inf, so `map` should keep a non-finite value non-finite.
pub fn read_nifti_mapped(path: &Path, map: impl Fn(f32) -> f32 + Sync + Copy) -> Result<Volume> {
    let file = File::open(path).map_err(|e| DatasetError::io(path, "opening", e))?;
    let file_len = file.metadata().ok().map(|m| m.len());
    let mut buffered = BufReader::with_capacity(1 << 20, file);
    let head = buffered
        .fill_buf()
        .map_err(|e| DatasetError::io(path, "reading", e))?;
    let gz = head.starts_with(&[0x1f, 0x8b]);
    // A .nii.gz is read whole and, where its size is known, inflated in one go (`inflated`:
    // header, extensions and voxels); otherwise streamed.
    let (mut compressed, mut inflated, mut compressed_len) = (Vec::new(), None, 0u64);
    if gz {
        let sizes = expected_size(head, path);
        let read = inflate::read(
            &mut buffered,
            file_len,
            sizes.map(|(n, _)| n),
            sizes.map_or(0, |(_, count)| count as usize),
            MAX_DEFLATE_RATIO,
        )
        .map_err(|e| DatasetError::io(path, "reading", e))?;
        match read {
            inflate::GzFile::Inflated(whole) => {
                compressed_len = file_len.unwrap_or(0);
                inflated = Some(whole);
            }
            inflate::GzFile::Compressed(bytes) => {
                compressed_len = bytes.len() as u64;
                compressed = bytes;
            }
        }
    }
    let mut reader: Box<dyn Read + '_> = match (&inflated, gz) {
        (Some(whole), _) => Box::new(whole.bytes()),
        // Multi-member aware (the crate's own reader decodes only the first gzip member).
        (None, true) => Box::new(MultiGzDecoder::new(&compressed[..])),
        (None, false) => Box::new(buffered),
    };

    let mut h = read_header(&mut reader, path)?;
    let dims = volume_dims(&h, path)?;
    let dtype = voxel_type(&h, path)?;
    let (spacing, direction, origin) = geometry(&h).map_err(|e| DatasetError::corrupt(path, e))?;

    let count = dims[0] * dims[1] * dims[2];
    let offset = data_offset(&h, path)?;
    let nbytes = (count as u64) * dtype.size_of() as u64;
    if let (false, Some(len)) = (gz, file_len)
        && len < offset + nbytes
    {
        return Err(DatasetError::truncated(
            path,
            format!(
                "{}×{}×{} {} voxels need {nbytes} bytes from byte {offset}, \
                 but the file holds only {len} bytes",
                dims[0],
                dims[1],
                dims[2],
                format!("{dtype:?}").to_lowercase()
            ),
        ));
    }
    // Deflate expands at most 1032:1, so a .nii.gz cannot hold more than 1032 bytes per
    // compressed byte: a header asking for more is refused before any allocation.
    if gz && offset + nbytes > MAX_DEFLATE_RATIO * compressed_len {
        return Err(DatasetError::truncated(
            path,
            format!(
                "{}×{}×{} {} voxels need {nbytes} bytes from byte {offset}, more than the {} compressed bytes can hold (deflate expands at most {MAX_DEFLATE_RATIO}:1)",
                dims[0],
                dims[1],
                dims[2],
                format!("{dtype:?}").to_lowercase(),
                compressed_len
            ),
        ));
    }
    // The raw voxels and their f32 copy must fit in memory.
    crate::error::check_read_memory(path, dims, u128::from(nbytes))?;
    // Extensions are not used: skip them up to the voxel data.
    let skip = offset - NIFTI1_SIZE as u64;
    let skipped = io::copy(&mut reader.by_ref().take(skip), &mut io::sink())
        .map_err(|e| read_error(path, e))?;
    if skipped < skip {
        return Err(DatasetError::truncated(
            path,
            format!(
                "the header puts the voxel data at byte {offset}, but the data ends at byte {}",
                NIFTI1_SIZE as u64 + skipped
            ),
        ));
    }

    // The crate sizes the data from `bitpix` and treats slope 0 as "no scaling"; make both
    // follow the documented rules (size from `datatype`; non-finite slope = no scaling).
    h.bitpix = (dtype.size_of() * 8) as i16;
    if !h.scl_slope.is_finite() {
        h.scl_slope = 0.0;
    }
    if !h.scl_inter.is_finite() {
        h.scl_inter = 0.0;
    }
    // Inflated whole: the voxels are decoded where they lie, in the buffer they were
    // inflated into.
    let in_place = decodes_in_place(dtype) && (inflated.is_some() || !gz);
    let data = if in_place {
        // The voxels' bytes at `at` of a buffer of at least `count` words: the inflated
        // file, or the uncompressed file's voxels read into one.
        let (words, at) = if inflated.is_some() {
            drop(reader);
            let whole = inflated.take().expect("inflated");
            (whole.words, offset as usize)
        } else {
            let mut words = zeroed_words(count).ok_or_else(|| DatasetError::TooLarge {
                path: path.to_owned(),
                detail: format!("cannot allocate {count} voxels"),
            })?;
            let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
            reader
                .read_exact(&mut bytes[..nbytes as usize])
                .map_err(|e| match e.kind() {
                    io::ErrorKind::UnexpectedEof => DatasetError::truncated(
                        path,
                        format!("the voxel data ends before its {nbytes} bytes"),
                    ),
                    _ => DatasetError::io(path, "reading", e),
                })?;
            drop(reader);
            (words, 0)
        };
        decode_in_place(
            words,
            at,
            count,
            dtype,
            h.endianness,
            scaling(h.scl_slope, h.scl_inter, map),
        )
    } else {
        // Streamed (or a type the in-place decoder does not take): the crate reads the
        // voxels, from the inflated bytes where there are some.
        let voxels =
            InMemNiftiVolume::from_reader(&mut reader, &h).map_err(|e| voxel_error(path, e))?;
        if gz {
            // Decode to the end so that the gzip trailer (CRC-32 and length) is
            // verified.
            io::copy(&mut reader, &mut io::sink()).map_err(|e| read_error(path, e))?;
        }
        let data = match decode_parallel(
            voxels.raw_data(),
            dtype,
            h.endianness,
            scaling(h.scl_slope, h.scl_inter, map),
        ) {
            Some(data) if data.len() == count => data,
            _ => {
                let array = voxels.into_ndarray::<f32>().map_err(|e| {
                    DatasetError::unsupported(
                        path,
                        format!("voxel type {dtype:?} cannot be decoded: {e}"),
                    )
                })?;
                let mut data =
                    i_fastest(array, dims).map_err(|e| DatasetError::corrupt(path, e))?;
                data.par_iter_mut().for_each(|v| *v = map(*v));
                data
            }
        };
        drop(reader);
        drop(inflated);
        data
    };
    Volume::new(dims, spacing, origin, direction, data).map_err(|source| DatasetError::Volume {
        path: path.to_owned(),
        source,
    })
}

/// The uncompressed size of a `.nii.gz` (header, extensions and voxels) and its number of
/// voxels, as its header states them, inflating only the header from `gz`, the file or its
/// first bytes; `None` where the header is not valid or not among those bytes (the
/// streaming read then reports why).
fn expected_size(gz: &[u8], path: &Path) -> Option<(u64, u64)> {
    let h = read_header(&mut MultiGzDecoder::new(gz), path).ok()?;
    let dims = volume_dims(&h, path).ok()?;
    let dtype = voxel_type(&h, path).ok()?;
    let offset = data_offset(&h, path).ok()?;
    let count = dims
        .iter()
        .try_fold(1u64, |n, &d| n.checked_mul(d as u64))?;
    Some((
        offset.checked_add(count.checked_mul(dtype.size_of() as u64)?)?,
        count,
    ))
}

/// Reads the 348-byte header and parses it with the crate, with precise errors for empty,
/// short, NIfTI-2, header/image-pair and non-NIfTI files.
fn read_header(r: &mut dyn Read, path: &Path) -> Result<NiftiHeader> {
    let mut buf = [0u8; NIFTI1_SIZE];
    let n = read_up_to(r, &mut buf).map_err(|e| read_error(path, e))?;
    if n == 0 {
        return Err(DatasetError::corrupt(
            path,
            "not a NIfTI file: the file is empty",
        ));
    }
    // `sizeof_hdr`, in either byte order: tells NIfTI-2 from NIfTI-1 from anything else.
    let size_field = [buf[0], buf[1], buf[2], buf[3]];
    let (le_size, be_size) = (
        i32::from_le_bytes(size_field),
        i32::from_be_bytes(size_field),
    );
    if n >= 4 && [le_size, be_size].contains(&NIFTI2_SIZE) {
        return Err(DatasetError::unsupported(
            path,
            "NIfTI-2 (540-byte header): only NIfTI-1 files can be read; convert it to \
             NIfTI-1, e.g. with nibabel (nib.Nifti1Image) or `fslchfiletype NIFTI_GZ`",
        ));
    }
    if n < NIFTI1_SIZE {
        return Err(DatasetError::truncated(
            path,
            format!("the NIfTI-1 header needs {NIFTI1_SIZE} bytes but the file holds only {n}"),
        ));
    }
    let h = NiftiHeader::from_reader(&buf[..]).map_err(|e| match e {
        NiftiError::InvalidFormat if ![le_size, be_size].contains(&(NIFTI1_SIZE as i32)) => {
            not_nifti_size(path, le_size)
        }
        NiftiError::InvalidFormat => DatasetError::corrupt(
            path,
            format!(
                "not a NIfTI file: the magic code (bytes 344–347) is {:?}, expected \"n+1\\0\"",
                String::from_utf8_lossy(&buf[344..348])
            ),
        ),
        other => DatasetError::corrupt(path, format!("invalid NIfTI-1 header: {other}")),
    })?;
    if &h.magic == nifti::header::MAGIC_CODE_NI1 {
        return Err(DatasetError::unsupported(
            path,
            "this is the header of a NIfTI .hdr/.img pair; only single-file .nii / .nii.gz \
             is supported (convert it, e.g. with nibabel or fslchfiletype)",
        ));
    }
    if h.sizeof_hdr != NIFTI1_SIZE as i32 {
        // The crate guesses the byte order from dim[0] (valid: 1..=7). A header-size field
        // that reads 348 once swapped means the guess was wrong, i.e. dim[0] is out of range.
        if h.sizeof_hdr.swap_bytes() == NIFTI1_SIZE as i32 {
            return Err(dimensionality_error(path, h.dim[0].swap_bytes() as i16));
        }
        return Err(not_nifti_size(path, le_size));
    }
    Ok(h)
}

fn not_nifti_size(path: &Path, size: i32) -> DatasetError {
    DatasetError::corrupt(
        path,
        format!(
            "not a NIfTI file: the header-size field reads {size} \
             (expected 348 for NIfTI-1 or 540 for NIfTI-2)"
        ),
    )
}

fn dimensionality_error(path: &Path, nd: i16) -> DatasetError {
    DatasetError::corrupt(
        path,
        format!("dim[0] = {nd}: the number of dimensions must be between 1 and 7"),
    )
}

/// The three spatial dimensions, refusing zero/negative sizes, several volumes and sizes
/// beyond [`MAX_VOXELS`], before any allocation. (The crate reads `dim` as `u16`; the
/// standard's field is `int16`, so it is reinterpreted as such.)
fn volume_dims(h: &NiftiHeader, path: &Path) -> Result<[usize; 3]> {
    let nd = h.dim[0] as i16;
    if !(1..=7).contains(&nd) {
        return Err(dimensionality_error(path, nd));
    }
    let mut dims = [1u64; 3];
    for a in 1..=nd as usize {
        let n = h.dim[a] as i16;
        if (a <= 3 && n < 1) || n < 0 {
            return Err(DatasetError::corrupt(
                path,
                format!("dim[{a}] = {n}: every dimension must be at least 1"),
            ));
        }
        if a <= 3 {
            dims[a - 1] = n as u64;
        } else if n > 1 {
            return Err(DatasetError::unsupported(
                path,
                format!(
                    "{nd}-D data: dim[{a}] = {n}, i.e. {n} volumes along axis {a}; only a single \
                     3-D volume can be read (extract one first, e.g. with fslroi)"
                ),
            ));
        }
    }
    let count = dims.iter().product::<u64>(); // ≤ 32767³: no overflow
    if count > MAX_VOXELS as u64 {
        return Err(DatasetError::TooLarge {
            path: path.to_owned(),
            detail: format!(
                "{}×{}×{} voxels exceed the limit of {MAX_VOXELS} voxels",
                dims[0], dims[1], dims[2]
            ),
        });
    }
    Ok(dims.map(|n| n as usize))
}

/// The stored voxel type, if it is one that converts to `f32`.
fn voxel_type(h: &NiftiHeader, path: &Path) -> Result<NiftiType> {
    use NiftiType::*;
    let code = h.datatype;
    let why = match h.data_type() {
        Ok(
            t @ (Uint8 | Int8 | Uint16 | Int16 | Uint32 | Int32 | Uint64 | Int64 | Float32
            | Float64),
        ) => return Ok(t),
        Ok(Complex64 | Complex128 | Complex256) => format!("complex voxels (datatype {code})"),
        Ok(Rgb24 | Rgba32) => format!("RGB/RGBA voxels (datatype {code})"),
        Ok(Float128) => format!("128-bit float voxels (datatype {code})"),
        Err(_) if code == 1 => "1-bit (binary) voxels".into(),
        Err(_) => format!("unknown datatype code {code}"),
    };
    Err(DatasetError::unsupported(
        path,
        format!("voxel type: {why}"),
    ))
}

/// Byte offset of the voxel data (`vox_offset`, or just past the header and the 4-byte
/// extension flag when it is 0).
fn data_offset(h: &NiftiHeader, path: &Path) -> Result<u64> {
    let v = f64::from(h.vox_offset);
    if v == 0.0 {
        return Ok(WRITTEN_DATA_OFFSET);
    }
    if !(v.is_finite() && v.fract() == 0.0 && v >= NIFTI1_SIZE as f64 && v < 1e15) {
        return Err(DatasetError::corrupt(
            path,
            format!(
                "vox_offset = {v}: the voxel data must start at a whole byte at or after the \
                 {NIFTI1_SIZE}-byte header"
            ),
        ));
    }
    Ok(v as u64)
}

/// Spacing (mm), direction and origin in LPS from the header's affine.
fn geometry(h: &NiftiHeader) -> std::result::Result<(DVec3, DMat3, DVec3), String> {
    let (ras, method) = affine::ras_affine(h)?;
    let lps = ras.flip_xy();
    let (spacing, direction) = affine::decompose(lps.linear, method)?;
    Ok((spacing, direction, lps.translation))
}

/// The decoded voxels in tomograf's order (`i` fastest).
///
/// The crate's array is indexed `[i, j, k, …]` (missing axes are absent, extra ones have
/// length 1). With its axes reversed it is indexed `[…, k, j, i]`, whose logical
/// row-major order is ours; when that view is in standard layout (it is for the crate's
/// column-major arrays) its buffer is already in that order and is taken without copying.
fn i_fastest(array: ArrayD<f32>, dims: [usize; 3]) -> std::result::Result<Vec<f32>, String> {
    let shape = array.shape();
    let padded: Vec<usize> = (0..shape.len().max(3))
        .map(|a| shape.get(a).copied().unwrap_or(1))
        .collect();
    if padded[..3] != dims || padded[3..].iter().any(|&n| n != 1) {
        return Err(format!(
            "the decoded voxel array has shape {shape:?}, not the header's {dims:?}"
        ));
    }
    let reversed = array.reversed_axes();
    if !reversed.is_standard_layout() {
        return Ok(reversed.iter().copied().collect());
    }
    let len = reversed.len();
    let (mut data, offset) = reversed.into_raw_vec_and_offset();
    let start = offset.unwrap_or(0);
    data.truncate(start + len);
    data.drain(..start);
    Ok(data)
}

/// Reads up to `buf.len()` bytes, stopping early only at end of file.
fn read_up_to(r: &mut (impl Read + ?Sized), buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Turns a read error into a dataset error: a stream that stops early is truncation, a
/// decoder complaint is corruption, anything else is an I/O failure.
fn read_error(path: &Path, e: io::Error) -> DatasetError {
    match e.kind() {
        io::ErrorKind::UnexpectedEof => {
            DatasetError::truncated(path, format!("the compressed stream ends early ({e})"))
        }
        io::ErrorKind::InvalidInput | io::ErrorKind::InvalidData => {
            DatasetError::corrupt(path, format!("corrupt gzip data: {e}"))
        }
        _ => DatasetError::io(path, "reading", e),
    }
}

/// Maps an error of the crate's voxel reader.
fn voxel_error(path: &Path, e: NiftiError) -> DatasetError {
    match e {
        NiftiError::Io(e) => read_error(path, e),
        NiftiError::IncompatibleLength(got, want) => DatasetError::truncated(
            path,
            format!("the voxel data ends after {got} of {want} bytes"),
        ),
        NiftiError::ReserveVolume(bytes, _) => DatasetError::TooLarge {
            path: path.to_owned(),
            detail: format!(
                "cannot allocate {bytes} bytes ({} MiB) for the voxel data",
                bytes >> 20
            ),
        },
        other => DatasetError::corrupt(path, format!("cannot read the voxel data: {other}")),
    }
}

/// Writes `volume` as a single-file NIfTI-1, gzip-compressed when the file name ends with
/// `.gz` (any case), atomically (a temporary file in the same directory, renamed over
/// `path`; see [`crate::atomic`]).
///
/// The file is written by the `nifti` crate: little-endian float32 with no scaling
/// (`scl_slope` 1, `scl_inter` 0), `xyzt_units` = mm. The LPS geometry is converted to a
/// RAS affine stored twice, consistently: as the sform (`sform_code` 1, scanner) and as the
/// qform (`qform_code` 1; `pixdim[1..=3]` = spacing, quaternion of the rotation,
/// `pixdim[0]` = qfac = −1 when the grid is a reflection).
///
/// An axis longer than 32767 voxels does not fit in NIfTI-1 and NIfTI-2 is not supported:
/// such a volume is refused with [`DatasetError::InvalidOutput`] and nothing is written.
pub fn write_nifti(path: &Path, volume: &Volume) -> Result<()> {
    let [nx, ny, nz] = volume.dims();
    if let Some(n) = [nx, ny, nz].into_iter().find(|&n| n > NIFTI1_MAX_DIM) {
        return Err(DatasetError::invalid_output(
            path,
            format!(
                "the volume is {nx}×{ny}×{nz} voxels; an axis of {n} voxels does not fit in a \
                 NIfTI-1 header (at most {NIFTI1_MAX_DIM} per axis), and NIfTI-2 is not supported"
            ),
        ));
    }
    // Logical [i, j, k] indexing of the i-fastest buffer: a column-major view.
    let data = ArrayView3::from_shape((nx, ny, nz).f(), volume.data()).map_err(|e| {
        DatasetError::invalid_output(path, format!("voxel buffer does not match the dims: {e}"))
    })?;
    let header = header_for(volume);
    let gz = path
        .file_name()
        .is_some_and(|n| n.to_string_lossy().to_ascii_lowercase().ends_with(".gz"));
    // The crate compresses by the name of the file it writes: give the temporary file the
    // extension we want.
    let suffix = if gz { ".nii.gz" } else { ".nii" };
    write_atomic_to_path(path, suffix, |tmp| {
        WriterOptions::new(tmp)
            .reference_header(&header)
            .write_nifti(&data)
            .map_err(|e| match e {
                NiftiError::Io(e) => DatasetError::io(path, "writing", e),
                other => DatasetError::invalid_output(path, format!("NIfTI writer: {other}")),
            })?;
        if !gz {
            // The crate drops its buffered writer without reporting a failed final flush:
            // check that everything reached the file.
            let expected = WRITTEN_DATA_OFFSET + 4 * data.len() as u64;
            let len = std::fs::metadata(tmp)
                .map_err(|e| DatasetError::io(path, "checking the written file", e))?
                .len();
            if len != expected {
                return Err(DatasetError::io(
                    path,
                    "writing",
                    io::Error::other(format!("only {len} of {expected} bytes reached the file")),
                ));
            }
        }
        Ok(())
    })
}

/// The reference header describing `volume`'s geometry (RAS affine in both sform and
/// qform). The crate fills in `dim`, `datatype`, `bitpix`, `vox_offset`, the scaling and
/// the magic from the data it writes.
fn header_for(volume: &Volume) -> NiftiHeader {
    let spacing = volume.spacing();
    let lps = affine::Affine {
        linear: volume.direction() * DMat3::from_diagonal(spacing),
        translation: volume.origin(),
    };
    let ras = lps.flip_xy();
    let direction_ras = affine::Affine {
        linear: volume.direction(),
        translation: DVec3::ZERO,
    }
    .flip_xy()
    .linear;
    let ([b, c, d], qfac) = affine::quaternion_of(direction_ras);
    let row = |r: usize| {
        let m = ras.linear;
        [m.x_axis[r], m.y_axis[r], m.z_axis[r], ras.translation[r]].map(|v| v as f32)
    };
    let t = ras.translation.as_vec3();
    let mut descrip = vec![0u8; 80];
    descrip[..8].copy_from_slice(b"tomograf");
    NiftiHeader {
        pixdim: [qfac, spacing.x, spacing.y, spacing.z, 1.0, 1.0, 1.0, 1.0].map(|v| v as f32),
        xyzt_units: Unit::Mm as u8,
        descrip,
        qform_code: XForm::ScannerAnat as i16,
        sform_code: XForm::ScannerAnat as i16,
        quatern_b: b as f32,
        quatern_c: c as f32,
        quatern_d: d as f32,
        quatern_x: t.x,
        quatern_y: t.y,
        quatern_z: t.z,
        srow_x: row(0),
        srow_y: row(1),
        srow_z: row(2),
        endianness: Endianness::Little,
        ..NiftiHeader::default()
    }
}

#[cfg(test)]
mod tests;
