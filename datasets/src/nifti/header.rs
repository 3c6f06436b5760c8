//! Binary layout of the NIfTI-1 (348-byte) and NIfTI-2 (540-byte) headers: parsing in
//! either byte order, encoding in little-endian.
//!
//! Only the fields tomograf uses are kept; both versions are widened to the same
//! [`Header`] (`i64` dimensions, `f64` reals).

use crate::error::{DatasetError, Result};
use std::io::{self, Read};
use std::path::Path;

/// Size of a NIfTI-1 header in bytes.
pub(crate) const NIFTI1_SIZE: usize = 348;
/// Size of a NIfTI-2 header in bytes.
pub(crate) const NIFTI2_SIZE: usize = 540;
/// Magic of a single-file NIfTI-1 (`.nii`).
const MAGIC1: &[u8; 4] = b"n+1\0";
/// Magic of a NIfTI-1 header/image pair (`.hdr` + `.img`).
const MAGIC1_PAIR: &[u8; 4] = b"ni1\0";
/// Magic of a single-file NIfTI-2.
const MAGIC2: &[u8; 8] = b"n+2\0\r\n\x1a\n";
/// Magic of a NIfTI-2 header/image pair.
const MAGIC2_PAIR: &[u8; 8] = b"ni2\0\r\n\x1a\n";
/// NIFTI_UNITS_MM in `xyzt_units`.
pub(crate) const UNITS_MM: i32 = 2;

/// The header fields tomograf reads or writes, widened to NIfTI-2 precision.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Header {
    /// 1 or 2.
    pub version: u8,
    /// Byte order of the file (headers we write are little-endian).
    pub big_endian: bool,
    /// `dim[0]` = number of dimensions, `dim[1..=dim[0]]` = sizes.
    pub dim: [i64; 8],
    /// NIFTI_TYPE_* code of the voxels.
    pub datatype: i16,
    /// Bits per voxel.
    pub bitpix: i16,
    /// `pixdim[0]` = qfac, `pixdim[1..=3]` = voxel size (mm).
    pub pixdim: [f64; 8],
    /// Byte offset of the voxel data in the file.
    pub vox_offset: f64,
    /// Value scaling: `value = stored · scl_slope + scl_inter` (slope 0 = no scaling).
    pub scl_slope: f64,
    /// See `scl_slope`.
    pub scl_inter: f64,
    /// Units of `pixdim`.
    pub xyzt_units: i32,
    /// NIFTI_XFORM_* code of the quaternion transform (0 = absent).
    pub qform_code: i32,
    /// NIFTI_XFORM_* code of the general affine (0 = absent).
    pub sform_code: i32,
    /// Quaternion `(b, c, d)`; `a` is implied.
    pub quatern: [f64; 3],
    /// Quaternion transform translation (mm, RAS).
    pub qoffset: [f64; 3],
    /// Rows of the 3×4 affine mapping `(i, j, k, 1)` to RAS mm.
    pub srow: [[f64; 4]; 3],
}

impl Header {
    /// Header size in bytes for this version.
    pub fn size(&self) -> usize {
        if self.version == 2 {
            NIFTI2_SIZE
        } else {
            NIFTI1_SIZE
        }
    }
}

/// Reads up to `buf.len()` bytes, stopping early only at end of file.
pub(crate) fn read_up_to(r: &mut (impl Read + ?Sized), buf: &mut [u8]) -> io::Result<usize> {
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
pub(crate) fn read_error(path: &Path, e: io::Error) -> DatasetError {
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

/// Little/big-endian field access into a header buffer.
struct Fields<'a> {
    buf: &'a [u8],
    be: bool,
}

macro_rules! getter {
    ($name:ident, $ty:ty) => {
        fn $name(&self, off: usize) -> $ty {
            const N: usize = std::mem::size_of::<$ty>();
            let mut a = [0u8; N];
            a.copy_from_slice(&self.buf[off..off + N]);
            if self.be {
                <$ty>::from_be_bytes(a)
            } else {
                <$ty>::from_le_bytes(a)
            }
        }
    };
}

impl Fields<'_> {
    getter!(i16, i16);
    getter!(i32, i32);
    getter!(i64, i64);
    getter!(f32, f32);
    getter!(f64, f64);
    fn f32s<const N: usize>(&self, off: usize) -> [f64; N] {
        std::array::from_fn(|i| f64::from(self.f32(off + 4 * i)))
    }
    fn f64s<const N: usize>(&self, off: usize) -> [f64; N] {
        std::array::from_fn(|i| self.f64(off + 8 * i))
    }
}

/// Reads and parses a NIfTI-1 or NIfTI-2 header from the start of `r`, detecting the
/// version and byte order from the `sizeof_hdr` field.
pub(crate) fn read_header(r: &mut (impl Read + ?Sized), path: &Path) -> Result<Header> {
    let mut buf = [0u8; NIFTI2_SIZE];
    let n = read_up_to(r, &mut buf[..4]).map_err(|e| read_error(path, e))?;
    if n == 0 {
        return Err(DatasetError::corrupt(
            path,
            "not a NIfTI file: the file is empty",
        ));
    }
    if n < 4 {
        return Err(DatasetError::truncated(
            path,
            format!("the NIfTI header needs at least 348 bytes but the file holds only {n}"),
        ));
    }
    let first = [buf[0], buf[1], buf[2], buf[3]];
    let (version, be) = match (i32::from_le_bytes(first), i32::from_be_bytes(first)) {
        (348, _) => (1u8, false),
        (_, 348) => (1, true),
        (540, _) => (2, false),
        (_, 540) => (2, true),
        (le, _) => {
            return Err(DatasetError::corrupt(
                path,
                format!(
                    "not a NIfTI file: the header-size field reads {le} \
                     (expected 348 for NIfTI-1 or 540 for NIfTI-2)"
                ),
            ));
        }
    };
    let size = if version == 1 {
        NIFTI1_SIZE
    } else {
        NIFTI2_SIZE
    };
    let got = 4 + read_up_to(r, &mut buf[4..size]).map_err(|e| read_error(path, e))?;
    if got < size {
        return Err(DatasetError::truncated(
            path,
            format!("the NIfTI-{version} header needs {size} bytes but the file holds only {got}"),
        ));
    }
    let f = Fields { buf: &buf, be };
    if version == 1 {
        check_magic(path, &buf[344..348], MAGIC1, MAGIC1_PAIR, 1)?;
        Ok(parse1(&f, be))
    } else {
        check_magic(path, &buf[4..12], MAGIC2, MAGIC2_PAIR, 2)?;
        Ok(parse2(&f, be))
    }
}

fn check_magic(path: &Path, got: &[u8], single: &[u8], pair: &[u8], v: u8) -> Result<()> {
    if got == single {
        Ok(())
    } else if got == pair {
        Err(DatasetError::unsupported(
            path,
            "this is the header of a NIfTI .hdr/.img pair; only single-file .nii / .nii.gz \
             is supported (convert it, e.g. with nibabel or fslchfiletype)",
        ))
    } else {
        Err(DatasetError::corrupt(
            path,
            format!(
                "not a valid NIfTI-{v} file: magic is {:?}, expected {:?}",
                String::from_utf8_lossy(got),
                String::from_utf8_lossy(single)
            ),
        ))
    }
}

fn parse1(f: &Fields, be: bool) -> Header {
    Header {
        version: 1,
        big_endian: be,
        dim: std::array::from_fn(|i| i64::from(f.i16(40 + 2 * i))),
        datatype: f.i16(70),
        bitpix: f.i16(72),
        pixdim: f.f32s(76),
        vox_offset: f64::from(f.f32(108)),
        scl_slope: f64::from(f.f32(112)),
        scl_inter: f64::from(f.f32(116)),
        xyzt_units: i32::from(f.buf[123]),
        qform_code: i32::from(f.i16(252)),
        sform_code: i32::from(f.i16(254)),
        quatern: f.f32s(256),
        qoffset: f.f32s(268),
        srow: [f.f32s(280), f.f32s(296), f.f32s(312)],
    }
}

fn parse2(f: &Fields, be: bool) -> Header {
    Header {
        version: 2,
        big_endian: be,
        dim: std::array::from_fn(|i| f.i64(16 + 8 * i)),
        datatype: f.i16(12),
        bitpix: f.i16(14),
        pixdim: f.f64s(104),
        vox_offset: f.i64(168) as f64,
        scl_slope: f.f64(176),
        scl_inter: f.f64(184),
        xyzt_units: f.i32(500),
        qform_code: f.i32(344),
        sform_code: f.i32(348),
        quatern: f.f64s(352),
        qoffset: f.f64s(376),
        srow: [f.f64s(400), f.f64s(432), f.f64s(464)],
    }
}

/// Little-endian byte writer at fixed offsets.
struct Out(Vec<u8>);

impl Out {
    fn put(&mut self, off: usize, bytes: &[u8]) {
        self.0[off..off + bytes.len()].copy_from_slice(bytes);
    }
}

/// Encodes `h` as a little-endian single-file header of its version (348 bytes for
/// NIfTI-1, 540 for NIfTI-2). NIfTI-1 fields are narrowed to `i16`/`f32`; the caller
/// checks that dimensions fit.
pub(crate) fn encode(h: &Header, description: &str) -> Vec<u8> {
    let mut o = Out(vec![0u8; h.size()]);
    let descrip = &description.as_bytes()[..description.len().min(79)];
    if h.version == 2 {
        o.put(0, &(NIFTI2_SIZE as i32).to_le_bytes());
        o.put(4, MAGIC2);
        o.put(12, &h.datatype.to_le_bytes());
        o.put(14, &h.bitpix.to_le_bytes());
        for (i, d) in h.dim.iter().enumerate() {
            o.put(16 + 8 * i, &d.to_le_bytes());
        }
        for (i, p) in h.pixdim.iter().enumerate() {
            o.put(104 + 8 * i, &p.to_le_bytes());
        }
        o.put(168, &(h.vox_offset as i64).to_le_bytes());
        o.put(176, &h.scl_slope.to_le_bytes());
        o.put(184, &h.scl_inter.to_le_bytes());
        o.put(240, descrip);
        o.put(344, &h.qform_code.to_le_bytes());
        o.put(348, &h.sform_code.to_le_bytes());
        for (i, v) in h.quatern.iter().chain(&h.qoffset).enumerate() {
            o.put(352 + 8 * i, &v.to_le_bytes());
        }
        for (r, row) in h.srow.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                o.put(400 + 32 * r + 8 * c, &v.to_le_bytes());
            }
        }
        o.put(500, &h.xyzt_units.to_le_bytes());
    } else {
        let f = |v: f64| (v as f32).to_le_bytes();
        o.put(0, &(NIFTI1_SIZE as i32).to_le_bytes());
        o.put(38, b"r");
        for (i, d) in h.dim.iter().enumerate() {
            o.put(40 + 2 * i, &(*d as i16).to_le_bytes());
        }
        o.put(70, &h.datatype.to_le_bytes());
        o.put(72, &h.bitpix.to_le_bytes());
        for (i, p) in h.pixdim.iter().enumerate() {
            o.put(76 + 4 * i, &f(*p));
        }
        o.put(108, &f(h.vox_offset));
        o.put(112, &f(h.scl_slope));
        o.put(116, &f(h.scl_inter));
        o.put(123, &[h.xyzt_units as u8]);
        o.put(148, descrip);
        o.put(252, &(h.qform_code as i16).to_le_bytes());
        o.put(254, &(h.sform_code as i16).to_le_bytes());
        for (i, v) in h.quatern.iter().chain(&h.qoffset).enumerate() {
            o.put(256 + 4 * i, &f(*v));
        }
        for (r, row) in h.srow.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                o.put(280 + 16 * r + 4 * c, &f(*v));
            }
        }
        o.put(344, MAGIC1);
    }
    o.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(version: u8) -> Header {
        Header {
            version,
            big_endian: false,
            dim: [3, 4, 5, 6, 1, 1, 1, 1],
            datatype: 16,
            bitpix: 32,
            pixdim: [-1.0, 0.5, 0.75, 2.0, 1.0, 1.0, 1.0, 1.0],
            vox_offset: if version == 2 { 544.0 } else { 352.0 },
            scl_slope: 2.0,
            scl_inter: -1.0,
            xyzt_units: UNITS_MM,
            qform_code: 1,
            sform_code: 2,
            quatern: [0.0, 0.5, -0.5],
            qoffset: [1.5, -2.5, 3.0],
            srow: [
                [1.0, 2.0, 3.0, 4.0],
                [5.0, 6.0, 7.0, 8.0],
                [9.0, 10.0, 11.0, 12.0],
            ],
        }
    }

    #[test]
    fn encode_parse_round_trip_both_versions() {
        for v in [1, 2] {
            let h = sample(v);
            let bytes = encode(&h, "test");
            assert_eq!(bytes.len(), h.size());
            let back = read_header(&mut bytes.as_slice(), Path::new("x.nii")).unwrap();
            assert_eq!(back, h);
        }
    }

    #[test]
    fn pair_magic_is_unsupported() {
        let mut bytes = encode(&sample(1), "");
        bytes[344..348].copy_from_slice(MAGIC1_PAIR);
        let e = read_header(&mut bytes.as_slice(), Path::new("a.hdr")).unwrap_err();
        assert!(e.to_string().contains(".hdr/.img pair"), "{e}");
        bytes[344..348].copy_from_slice(b"abcd");
        let e = read_header(&mut bytes.as_slice(), Path::new("a.nii")).unwrap_err();
        assert!(e.to_string().contains("magic"), "{e}");
    }
}
