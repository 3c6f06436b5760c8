//! NRRD volumes (`.nrrd`, attached data; `.nhdr`, a header whose data lie in another file),
//! the format of 3D Slicer and pyradiomics, read into a [`Volume`] in the world frame
//! (LPS, mm).
//!
//! The format (teem's NRRD0001–NRRD0005, <https://teem.sourceforge.net/nrrd/format.html>):
//! a magic line, `field: value` lines, a blank line, then the samples — raw or gzip, the
//! first axis fastest (as [`Volume`] stores them). Read here: 3-D scalar volumes of
//! (u)int8/16/32 or float/double, little or big endian, `raw` or `gzip` encoding, with
//! `space` (LPS, RAS or LAS, by name or in full, e.g. `left-posterior-superior`), `space
//! directions` (the world step of each index axis, in the space's frame) and `space
//! origin` (the world position of voxel (0, 0, 0)); without a space, `spacings` along the
//! world axes from the origin. Values are taken as they are stored (a CT's NRRD holds HU).
//! Anything else — other encodings, more axes, a space other than the three above, space
//! units other than mm — is refused, naming the field.

use crate::error::{DatasetError, Result};
use glam::{DMat3, DVec3};
use std::borrow::Cow;
use std::io::Read;
use std::path::{Path, PathBuf};
use tomograf_sim::Volume;

/// Reads the NRRD volume at `path` (`.nrrd`, or `.nhdr` with its data file).
pub fn read_nrrd(path: &Path) -> Result<Volume> {
    let bytes = std::fs::read(path).map_err(|source| DatasetError::Io {
        path: path.to_path_buf(),
        action: "reading",
        source,
    })?;
    let corrupt = |reason: String| DatasetError::Corrupt {
        path: path.to_path_buf(),
        reason,
    };
    let unsupported = |reason: String| DatasetError::Unsupported {
        path: path.to_path_buf(),
        reason,
    };
    if !bytes.starts_with(b"NRRD000") {
        return Err(corrupt(
            "not an NRRD file (it does not start with the magic NRRD000x)".into(),
        ));
    }
    // The header ends at the first empty line; attached data follow it.
    let (header_end, data_start) = find_blank_line(&bytes)
        .ok_or_else(|| corrupt("the header has no end (no empty line after it)".into()))?;
    let header = std::str::from_utf8(&bytes[..header_end])
        .map_err(|_| corrupt("the header is not text".into()))?;
    let h = Header::parse(header).map_err(corrupt)?;
    let dims = h.sizes;
    let count =
        tomograf_sim::volume::checked_voxel_count(dims).map_err(|e| DatasetError::TooLarge {
            path: path.to_path_buf(),
            detail: e.to_string(),
        })?;
    let sample = h.sample.bytes();
    let payload_bytes = count
        .checked_mul(sample)
        .ok_or_else(|| unsupported(format!("{count} samples of {sample} bytes overflow")))?;
    // The samples and their f32 copy must fit in memory.
    crate::error::check_read_memory(path, dims, payload_bytes as u128)?;
    let (stored, source): (Cow<[u8]>, PathBuf) = match &h.data_file {
        None => (Cow::Borrowed(&bytes[data_start..]), path.to_path_buf()),
        Some(name) => {
            let p = path.parent().unwrap_or(Path::new(".")).join(name);
            // A regular file only: a device or a pipe named here would never end.
            if !p.is_file() {
                return Err(corrupt(format!(
                    "its data file {} is not a regular file",
                    p.display()
                )));
            }
            let b = std::fs::read(&p).map_err(|source| DatasetError::Io {
                path: p.clone(),
                action: "reading (the data file its header names)",
                source,
            })?;
            (Cow::Owned(b), p)
        }
    };
    let stored = &stored[h.byte_skip.min(stored.len())..];
    let payload: Cow<[u8]> = match h.encoding {
        Encoding::Raw => Cow::Borrowed(stored),
        Encoding::Gzip => {
            // Deflate expands at most 1032-fold: a file too small for what its header asks
            // is truncated, told before anything is allocated.
            if (stored.len() as u128) * 1032 < payload_bytes as u128 {
                return Err(DatasetError::Truncated {
                    path: source,
                    detail: format!(
                        "{} bytes of gzip data cannot hold the {payload_bytes} bytes of \
                         samples its header asks for (deflate expands at most 1032-fold)",
                        stored.len()
                    ),
                });
            }
            let mut out = Vec::with_capacity(payload_bytes);
            flate2::read::MultiGzDecoder::new(stored)
                .take(payload_bytes as u64 + 1)
                .read_to_end(&mut out)
                .map_err(|e| DatasetError::Corrupt {
                    path: source.clone(),
                    reason: format!("its gzip data do not decompress: {e}"),
                })?;
            Cow::Owned(out)
        }
    };
    if payload.len() < payload_bytes {
        return Err(DatasetError::Truncated {
            path: source,
            detail: format!(
                "{} × {} × {} samples of {sample} bytes need {payload_bytes} bytes of data; \
                 found {}",
                dims[0],
                dims[1],
                dims[2],
                payload.len()
            ),
        });
    }
    let data: Vec<f32> = payload[..payload_bytes]
        .chunks_exact(sample)
        .map(|c| h.sample.decode(c, h.little_endian))
        .collect();
    Volume::new(dims, h.spacing, h.origin, h.direction, data).map_err(|source| {
        DatasetError::Volume {
            path: path.to_path_buf(),
            source,
        }
    })
}

/// Where the header's text ends and the data begin: the first empty line (`\n\n`, or with
/// carriage returns).
fn find_blank_line(b: &[u8]) -> Option<(usize, usize)> {
    let mut line_start = 0;
    for (i, &c) in b.iter().enumerate() {
        if c == b'\n' {
            let line = &b[line_start..i];
            if line.is_empty() || line == b"\r" {
                return Some((line_start, i + 1));
            }
            line_start = i + 1;
        }
    }
    None
}

/// A sample type and its size.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Sample {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Sample {
    fn parse(t: &str) -> std::result::Result<Self, String> {
        Ok(match t {
            "signed char" | "int8" | "int8_t" => Self::I8,
            "uchar" | "unsigned char" | "uint8" | "uint8_t" => Self::U8,
            "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
                Self::I16
            }
            "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => Self::U16,
            "int" | "signed int" | "int32" | "int32_t" => Self::I32,
            "uint" | "unsigned int" | "uint32" | "uint32_t" => Self::U32,
            "float" => Self::F32,
            "double" => Self::F64,
            other => {
                return Err(format!(
                    "type '{other}' is not supported (8-, 16- or 32-bit integers, float or \
                     double)"
                ));
            }
        })
    }

    fn bytes(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn decode(self, c: &[u8], le: bool) -> f32 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = c.try_into().expect("a sample");
                (if le {
                    <$t>::from_le_bytes(a)
                } else {
                    <$t>::from_be_bytes(a)
                }) as f32
            }};
        }
        match self {
            Self::I8 => c[0] as i8 as f32,
            Self::U8 => c[0] as f32,
            Self::I16 => num!(i16, 2),
            Self::U16 => num!(u16, 2),
            Self::I32 => num!(i32, 4),
            Self::U32 => num!(u32, 4),
            Self::F32 => num!(f32, 4),
            Self::F64 => num!(f64, 8),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Raw,
    Gzip,
}

/// What the header says, in the world frame (LPS, mm).
struct Header {
    sizes: [usize; 3],
    sample: Sample,
    little_endian: bool,
    encoding: Encoding,
    spacing: DVec3,
    origin: DVec3,
    /// Columns: the world (LPS) directions of the index axes.
    direction: DMat3,
    data_file: Option<String>,
    byte_skip: usize,
}

impl Header {
    fn parse(text: &str) -> std::result::Result<Self, String> {
        let mut fields = std::collections::BTreeMap::new();
        for line in text.lines().skip(1) {
            let line = line.trim_end_matches('\r');
            if line.starts_with('#') || line.trim().is_empty() {
                continue;
            }
            // Key/value pairs (`key:=value`) are free text; fields are `name: value`.
            if line.contains(":=") {
                continue;
            }
            let Some((k, v)) = line.split_once(": ") else {
                return Err(format!("header line '{line}' is not 'field: value'"));
            };
            fields.insert(k.trim().to_ascii_lowercase(), v.trim().to_string());
        }
        let field = |k: &str| fields.get(k).map(String::as_str);
        let need = |k: &str| field(k).ok_or_else(|| format!("the header has no '{k}' field"));

        let dimension: usize = need("dimension")?
            .parse()
            .map_err(|_| "'dimension' is not a whole number".to_string())?;
        if dimension != 3 {
            return Err(format!(
                "dimension {dimension}: only 3-D volumes are read (one scalar per voxel)"
            ));
        }
        let sizes: [usize; 3] = three("sizes", need("sizes")?, "sizes")?;
        let sample = Sample::parse(need("type")?)?;
        let little_endian = match field("endian") {
            None if sample.bytes() == 1 => true,
            None => return Err("the header has no 'endian' field".into()),
            Some("little") => true,
            Some("big") => false,
            Some(e) => return Err(format!("endian '{e}': give little or big")),
        };
        let encoding = match need("encoding")? {
            "raw" => Encoding::Raw,
            "gzip" | "gz" => Encoding::Gzip,
            e => {
                return Err(format!(
                    "encoding '{e}' is not supported (raw or gzip; convert the file, e.g. \
                     with unu or SimpleITK)"
                ));
            }
        };
        if let Some(u) = field("space units") {
            let units: Vec<&str> = u.split_whitespace().map(|s| s.trim_matches('"')).collect();
            if units.iter().any(|u| *u != "mm") {
                return Err(format!("space units {u}: only mm are read"));
            }
        }
        // Signs that turn the space's axes into LPS.
        let flip = match field("space").map(str::to_ascii_lowercase).as_deref() {
            Some("left-posterior-superior" | "lps") => Some(DVec3::new(1.0, 1.0, 1.0)),
            Some("right-anterior-superior" | "ras") => Some(DVec3::new(-1.0, -1.0, 1.0)),
            Some("left-anterior-superior" | "las") => Some(DVec3::new(1.0, -1.0, 1.0)),
            Some(other) => {
                return Err(format!(
                    "space '{other}' is not supported (left-posterior-superior, \
                     right-anterior-superior or left-anterior-superior)"
                ));
            }
            None => None,
        };
        let (spacing, origin, direction) = match flip {
            Some(flip) => {
                let dirs = vectors(need("space directions")?)?;
                let [a, b, c]: [DVec3; 3] = dirs
                    .try_into()
                    .map_err(|_| "'space directions' must give 3 vectors".to_string())?;
                let (a, b, c) = (a * flip, b * flip, c * flip);
                let spacing = DVec3::new(a.length(), b.length(), c.length());
                if !(spacing.is_finite() && spacing.min_element() > 0.0) {
                    return Err(format!(
                        "'space directions' give a zero or non-finite step ({spacing} mm)"
                    ));
                }
                let direction = DMat3::from_cols(a / spacing.x, b / spacing.y, c / spacing.z);
                let origin = match field("space origin") {
                    None => DVec3::ZERO,
                    Some(o) => {
                        let v = vectors(o)?;
                        let [o]: [DVec3; 1] = v
                            .try_into()
                            .map_err(|_| "'space origin' must be one vector".to_string())?;
                        o * flip
                    }
                };
                (spacing, origin, direction)
            }
            None => {
                let s = need("spacings").map_err(|_| {
                    "the header gives neither 'space' with 'space directions' nor \
                         'spacings': the voxel size is unknown"
                        .to_string()
                })?;
                let s: [f64; 3] = three("spacings", s, "values")?;
                (DVec3::from(s), DVec3::ZERO, DMat3::IDENTITY)
            }
        };
        let byte_skip = match field("byte skip") {
            None => 0,
            Some(s) => s
                .parse()
                .map_err(|_| format!("byte skip '{s}' is not supported (a byte count ≥ 0)"))?,
        };
        if byte_skip > 0 && encoding == Encoding::Gzip {
            return Err(
                "'byte skip' with gzip encoding is not supported (the skip would apply to the \
                 decompressed data)"
                    .into(),
            );
        }
        if field("line skip").is_some_and(|s| s != "0") {
            return Err("'line skip' is not supported".into());
        }
        let data_file = field("data file").or(field("datafile")).map(str::to_string);
        if data_file
            .as_deref()
            .is_some_and(|d| d.starts_with("LIST") || d.contains('%'))
        {
            return Err("a data file list or pattern is not supported (one data file)".into());
        }
        Ok(Self {
            sizes,
            sample,
            little_endian,
            encoding,
            spacing,
            origin,
            direction,
            data_file,
            byte_skip,
        })
    }
}

/// The vectors `(x,y,z) (x,y,z) …` of a field; `none` is refused (every axis must be a
/// spatial one).
fn vectors(text: &str) -> std::result::Result<Vec<DVec3>, String> {
    let mut out = Vec::new();
    for part in text.split(')') {
        let part = part.trim();
        if part.is_empty() {
            continue;
        }
        if part.starts_with("none") {
            return Err(format!(
                "'{text}': an axis without a direction (none) is not a 3-D volume's"
            ));
        }
        let inner = part
            .strip_prefix('(')
            .ok_or_else(|| format!("'{text}' is not a list of (x,y,z) vectors"))?;
        let v: Vec<f64> = inner
            .split(',')
            .map(|s| {
                s.trim()
                    .parse::<f64>()
                    .map_err(|_| format!("'{text}' holds '{}'", s.trim()))
            })
            .collect::<std::result::Result<_, _>>()?;
        let v: [f64; 3] = v
            .try_into()
            .map_err(|_| format!("'{text}': each vector needs 3 components"))?;
        out.push(DVec3::from(v));
    }
    Ok(out)
}

/// The three whitespace-separated numbers of header field `name` (`what` they are, for the
/// error when there are not three).
fn three<T: std::str::FromStr>(
    name: &str,
    text: &str,
    what: &str,
) -> std::result::Result<[T; 3], String> {
    let v: Vec<T> = text
        .split_whitespace()
        .map(|s| s.parse().map_err(|_| format!("'{name}' holds '{s}'")))
        .collect::<std::result::Result<_, _>>()?;
    v.try_into()
        .map_err(|_| format!("'{name}' must give 3 {what}"))
}
