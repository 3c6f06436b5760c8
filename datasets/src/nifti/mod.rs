//! NIfTI volumes (`.nii`, `.nii.gz`; NIfTI-1 and NIfTI-2) ↔ [`Volume`].
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
//! Compression is detected from the gzip magic bytes, not from the file name.

mod affine;
mod header;

use crate::atomic::write_atomic;
use crate::error::{DatasetError, Result};
use flate2::Compression;
use flate2::read::MultiGzDecoder;
use flate2::write::GzEncoder;
use glam::{DMat3, DVec3};
use header::{Header, NIFTI1_SIZE, NIFTI2_SIZE, read_error, read_up_to};
use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Write};
use std::path::Path;
use tomograf_sim::Volume;
use tomograf_sim::volume::MAX_VOXELS;

/// Voxel types that can be read, with their NIFTI_TYPE_* code and size in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum DataType {
    U8,
    I8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl DataType {
    fn from_code(code: i16) -> std::result::Result<Self, String> {
        Ok(match code {
            2 => Self::U8,
            256 => Self::I8,
            4 => Self::I16,
            512 => Self::U16,
            8 => Self::I32,
            768 => Self::U32,
            1024 => Self::I64,
            1280 => Self::U64,
            16 => Self::F32,
            64 => Self::F64,
            1 => return Err("1-bit (binary) voxels".into()),
            32 | 1792 | 2048 => return Err(format!("complex voxels (datatype {code})")),
            128 | 2304 => return Err(format!("RGB/RGBA voxels (datatype {code})")),
            1536 => return Err("128-bit float voxels (datatype 1536)".into()),
            _ => return Err(format!("unknown datatype code {code}")),
        })
    }
    fn name(self) -> &'static str {
        match self {
            Self::U8 => "uint8",
            Self::I8 => "int8",
            Self::I16 => "int16",
            Self::U16 => "uint16",
            Self::I32 => "int32",
            Self::U32 => "uint32",
            Self::I64 => "int64",
            Self::U64 => "uint64",
            Self::F32 => "float32",
            Self::F64 => "float64",
        }
    }
    fn size(self) -> usize {
        match self {
            Self::U8 | Self::I8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::I64 | Self::U64 | Self::F64 => 8,
        }
    }
}

/// Reads a NIfTI-1 or NIfTI-2 file (`.nii`, or gzip-compressed `.nii.gz`) into a
/// [`Volume`] in the LPS world frame.
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
/// file and the problem (truncated, not NIfTI, unsupported type or 4-D data, too large,
/// sheared…).
pub fn read_nifti(path: &Path) -> Result<Volume> {
    let file = File::open(path).map_err(|e| DatasetError::io(path, "opening", e))?;
    let file_len = file.metadata().ok().map(|m| m.len());
    let mut buffered = BufReader::with_capacity(1 << 20, file);
    let head = buffered
        .fill_buf()
        .map_err(|e| DatasetError::io(path, "reading", e))?;
    let gz = head.starts_with(&[0x1f, 0x8b]);
    let mut reader: Box<dyn Read> = if gz {
        Box::new(MultiGzDecoder::new(buffered))
    } else {
        Box::new(buffered)
    };

    let h = header::read_header(&mut reader, path)?;
    let dims = volume_dims(&h, path)?;
    let dtype = DataType::from_code(h.datatype)
        .map_err(|why| DatasetError::unsupported(path, format!("voxel type: {why}")))?;
    let (spacing, direction, origin) = geometry(&h).map_err(|e| DatasetError::corrupt(path, e))?;

    let count = dims[0] * dims[1] * dims[2];
    let offset = data_offset(&h, path)?;
    let nbytes = (count as u64) * dtype.size() as u64;
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
                dtype.name()
            ),
        ));
    }
    let skip = offset - h.size() as u64;
    let skipped = io::copy(&mut reader.by_ref().take(skip), &mut io::sink())
        .map_err(|e| read_error(path, e))?;
    if skipped < skip {
        return Err(DatasetError::truncated(
            path,
            format!(
                "the header puts the voxel data at byte {offset}, but the data ends at byte {}",
                h.size() as u64 + skipped
            ),
        ));
    }
    let data = read_voxels(&mut reader, path, &h, dtype, count)?;
    if gz {
        // Decode to the end so that the gzip trailer (CRC-32 and length) is verified.
        io::copy(&mut reader, &mut io::sink()).map_err(|e| read_error(path, e))?;
    }
    Volume::new(dims, spacing, origin, direction, data).map_err(|source| DatasetError::Volume {
        path: path.to_owned(),
        source,
    })
}

/// The three spatial dimensions, refusing zero/negative sizes, several volumes and sizes
/// beyond [`MAX_VOXELS`], before any allocation.
fn volume_dims(h: &Header, path: &Path) -> Result<[usize; 3]> {
    let nd = h.dim[0];
    if !(1..=7).contains(&nd) {
        return Err(DatasetError::corrupt(
            path,
            format!("dim[0] = {nd}: the number of dimensions must be between 1 and 7"),
        ));
    }
    let mut dims = [1u64; 3];
    for a in 1..=nd as usize {
        let n = h.dim[a];
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
    let count = dims.iter().try_fold(1u64, |acc, &n| acc.checked_mul(n));
    match count {
        Some(c) if c <= MAX_VOXELS as u64 => Ok(dims.map(|n| n as usize)),
        _ => Err(DatasetError::TooLarge {
            path: path.to_owned(),
            detail: format!(
                "{}×{}×{} voxels exceed the limit of {MAX_VOXELS} voxels",
                dims[0], dims[1], dims[2]
            ),
        }),
    }
}

/// Byte offset of the voxel data (`vox_offset`, or just past the header and the 4-byte
/// extension flag when it is 0).
fn data_offset(h: &Header, path: &Path) -> Result<u64> {
    let v = h.vox_offset;
    if v == 0.0 {
        return Ok(h.size() as u64 + 4);
    }
    if !(v.is_finite() && v.fract() == 0.0 && v >= h.size() as f64 && v < 1e15) {
        return Err(DatasetError::corrupt(
            path,
            format!(
                "vox_offset = {v}: the voxel data must start at a whole byte at or after the \
                 {}-byte header",
                h.size()
            ),
        ));
    }
    Ok(v as u64)
}

/// Spacing (mm), direction and origin in LPS from the header's affine.
fn geometry(h: &Header) -> std::result::Result<(DVec3, DMat3, DVec3), String> {
    let (ras, method) = affine::ras_affine(h)?;
    let lps = ras.flip_xy();
    let (spacing, direction) = affine::decompose(lps.linear, method)?;
    Ok((spacing, direction, lps.translation))
}

/// Reads `count` voxels of type `dtype`, scaled, as `f32`.
fn read_voxels(
    r: &mut dyn Read,
    path: &Path,
    h: &Header,
    dtype: DataType,
    count: usize,
) -> Result<Vec<f32>> {
    let (slope, inter) = if h.scl_slope != 0.0 && h.scl_slope.is_finite() {
        let inter = if h.scl_inter.is_finite() {
            h.scl_inter
        } else {
            0.0
        };
        (h.scl_slope, inter)
    } else {
        (1.0, 0.0)
    };
    let scale = |v: f64| (v * slope + inter) as f32;
    let mut out = Vec::new();
    out.try_reserve_exact(count)
        .map_err(|_| DatasetError::TooLarge {
            path: path.to_owned(),
            detail: format!("cannot allocate {count} voxels ({} MiB)", (count * 4) >> 20),
        })?;
    let be = h.big_endian;
    let size = dtype.size();
    let total = count * size;
    let mut chunk = vec![0u8; (1 << 20).min(total)];
    let mut done = 0;
    while done < total {
        let want = chunk.len().min(total - done);
        let got = read_up_to(r, &mut chunk[..want]).map_err(|e| read_error(path, e))?;
        if got < want {
            return Err(DatasetError::truncated(
                path,
                format!("the voxel data ends after {} of {total} bytes", done + got),
            ));
        }
        let bytes = &chunk[..want];
        macro_rules! decode {
            ($ty:ty) => {{
                const N: usize = std::mem::size_of::<$ty>();
                out.extend(bytes.chunks_exact(N).map(|c| {
                    let mut a = [0u8; N];
                    a.copy_from_slice(c);
                    let v = if be {
                        <$ty>::from_be_bytes(a)
                    } else {
                        <$ty>::from_le_bytes(a)
                    };
                    scale(v as f64)
                }))
            }};
        }
        match dtype {
            DataType::U8 => decode!(u8),
            DataType::I8 => decode!(i8),
            DataType::I16 => decode!(i16),
            DataType::U16 => decode!(u16),
            DataType::I32 => decode!(i32),
            DataType::U32 => decode!(u32),
            DataType::I64 => decode!(i64),
            DataType::U64 => decode!(u64),
            DataType::F32 => decode!(f32),
            DataType::F64 => decode!(f64),
        }
        done += want;
    }
    Ok(out)
}

/// Writes `volume` as a single-file NIfTI, gzip-compressed when the file name ends with
/// `.gz` (any case), atomically (see [`write_atomic`]).
///
/// The file is little-endian float32 with no scaling (`scl_slope` 1, `scl_inter` 0),
/// `xyzt_units` = mm, NIfTI-1 (NIfTI-2 only if a dimension exceeds 32767). The LPS
/// geometry is converted to a RAS affine stored twice, consistently: as the sform
/// (`sform_code` 1, scanner) and as the qform (`qform_code` 1; `pixdim[1..=3]` = spacing,
/// quaternion of the rotation, `pixdim[0]` = qfac = −1 when the grid is a reflection).
pub fn write_nifti(path: &Path, volume: &Volume) -> Result<()> {
    let header = header_for(volume);
    let bytes = header::encode(&header, "tomograf");
    let gz = path
        .file_name()
        .is_some_and(|n| n.to_string_lossy().to_ascii_lowercase().ends_with(".gz"));
    write_atomic(path, |w| {
        if gz {
            let mut enc = GzEncoder::new(w, Compression::fast());
            write_body(&mut enc, &bytes, volume.data())?;
            enc.finish()?;
            Ok(())
        } else {
            write_body(w, &bytes, volume.data())
        }
    })
}

/// Header, 4-byte zero extension flag, then the voxels as little-endian f32.
fn write_body(w: &mut impl Write, header: &[u8], data: &[f32]) -> io::Result<()> {
    w.write_all(header)?;
    w.write_all(&[0u8; 4])?;
    let mut buf = Vec::with_capacity(1 << 18);
    for chunk in data.chunks(1 << 16) {
        buf.clear();
        buf.extend(chunk.iter().flat_map(|v| v.to_le_bytes()));
        w.write_all(&buf)?;
    }
    Ok(())
}

/// The header describing `volume` (RAS affine in both sform and qform).
fn header_for(volume: &Volume) -> Header {
    let [nx, ny, nz] = volume.dims();
    let version = if [nx, ny, nz].iter().all(|&n| n <= i16::MAX as usize) {
        1
    } else {
        2
    };
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
    let (quatern, qfac) = affine::quaternion_of(direction_ras);
    let row = |r: usize| {
        let m = ras.linear;
        [m.x_axis[r], m.y_axis[r], m.z_axis[r], ras.translation[r]]
    };
    Header {
        version,
        big_endian: false,
        dim: [3, nx as i64, ny as i64, nz as i64, 1, 1, 1, 1],
        datatype: 16,
        bitpix: 32,
        pixdim: [qfac, spacing.x, spacing.y, spacing.z, 1.0, 1.0, 1.0, 1.0],
        vox_offset: (if version == 1 {
            NIFTI1_SIZE
        } else {
            NIFTI2_SIZE
        } + 4) as f64,
        scl_slope: 1.0,
        scl_inter: 0.0,
        xyzt_units: header::UNITS_MM,
        qform_code: 1,
        sform_code: 1,
        quatern,
        qoffset: ras.translation.to_array(),
        srow: [row(0), row(1), row(2)],
    }
}
