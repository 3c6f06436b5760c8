//! A pre-check of a DICOM Part-10 file's value lengths against its size.
//!
//! `dicom-parser` reserves and fills a buffer of an element's declared value length before
//! it reads the value, so an 809-byte file whose one element claims 3.7 GB made tomograf
//! use 3.7 GB of memory before failing with "truncated" (found by the `dicom_series` fuzz
//! target; docs/reliability.md). GDCM fixed the same class of bug (CVE-2026-3650) by
//! comparing each length with what the stream still holds; this walk does that before the
//! file reaches the parser: the file meta group (explicit VR little endian) and the data
//! set's elements in its transfer syntax (implicit VR little endian, explicit VR little or
//! big endian), recursing into sequences and items of defined length. It stops, unchecked,
//! at the first undefined length (0xFFFFFFFF: a sequence or encapsulated pixel data the
//! parser reads item by item) and in deflated data sets.

use crate::error::{DatasetError, Result};
use std::path::Path;

/// Transfer syntaxes whose data set is implicit VR little endian, and explicit VR big
/// endian; every other one (but deflate) is explicit VR little endian.
const IMPLICIT_LE: &str = "1.2.840.10008.1.2";
const EXPLICIT_BE: &str = "1.2.840.10008.1.2.2";
const DEFLATED: &[&str] = &["1.2.840.10008.1.2.1.99", "1.2.840.10008.1.2.8.1"];
/// Value representations with a 2-byte length in explicit VR; every other one — and an
/// unknown VR, as `dicom-parser` reads it — has 2 reserved bytes and a 4-byte length.
const SHORT_VRS: &[&[u8; 2]] = &[
    b"AE", b"AS", b"AT", b"CS", b"DA", b"DS", b"DT", b"FL", b"FD", b"IS", b"LO", b"LT", b"PN",
    b"SH", b"SL", b"SS", b"ST", b"TM", b"UI", b"UL", b"US",
];
const UNDEFINED: u32 = 0xFFFF_FFFF;
/// Sequences nested deeper than this are not followed (nothing legitimate nests so deep).
const MAX_DEPTH: usize = 32;

#[derive(Clone, Copy)]
struct Syntax {
    explicit: bool,
    big_endian: bool,
}

/// Checks `bytes` (a whole file that starts with the 128-byte preamble and `DICM`); errors
/// name the element whose declared length exceeds what the file holds after it.
pub(super) fn check(path: &Path, bytes: &[u8]) -> Result<()> {
    if bytes.len() < 132 || &bytes[128..132] != b"DICM" {
        return Ok(());
    }
    let le = Syntax {
        explicit: true,
        big_endian: false,
    };
    // The file meta group: explicit VR little endian, elements of group 0002. When it
    // starts with its group length (0002,0000), as the standard requires, the data set
    // starts where that says — as the parser reads it — whatever the elements in between.
    let mut at = 132;
    let mut meta_end = None;
    if at + 12 <= bytes.len()
        && let Some(e) = element(bytes, at, le)
        && e.tag == (0x0002, 0x0000)
        && e.length == 4
        && e.value + 4 <= bytes.len()
    {
        meta_end = Some(e.value + 4 + u32_at(bytes, e.value, false) as usize);
        at = e.value + 4;
    }
    let limit = meta_end.unwrap_or(bytes.len()).min(bytes.len());
    let mut syntax_uid = String::new();
    while at + 8 <= limit && u16_at(bytes, at, false) == 0x0002 {
        let Some(e) = element(bytes, at, le) else {
            break;
        };
        e.fits(path, bytes.len())?;
        if e.length == UNDEFINED {
            return Ok(());
        }
        if e.tag == (0x0002, 0x0010) {
            let v = &bytes[e.value..e.value + e.length as usize];
            syntax_uid = String::from_utf8_lossy(v)
                .trim_end_matches(['\0', ' '])
                .to_string();
        }
        at = e.value + e.length as usize;
    }
    if let Some(end) = meta_end {
        if end > bytes.len() {
            return Ok(()); // the parser reports the meta group as truncated
        }
        at = end;
    }
    if DEFLATED.contains(&syntax_uid.as_str()) {
        return Ok(());
    }
    let syntax = Syntax {
        explicit: syntax_uid != IMPLICIT_LE,
        big_endian: syntax_uid == EXPLICIT_BE,
    };
    walk(path, bytes, at, bytes.len(), syntax, 0).map(|_| ())
}

/// Walks the elements in `bytes[at..end]`; returns false when it stopped at an undefined
/// length (nothing after it is checked).
fn walk(
    path: &Path,
    bytes: &[u8],
    mut at: usize,
    end: usize,
    s: Syntax,
    depth: usize,
) -> Result<bool> {
    while at + 8 <= end {
        let Some(e) = element(bytes, at, s) else {
            return Ok(true);
        };
        e.fits(path, end)?;
        if e.length == UNDEFINED {
            return Ok(false);
        }
        let value_end = e.value + e.length as usize;
        if e.is_sequence
            && depth < MAX_DEPTH
            && !items(path, bytes, e.value, value_end, s, depth + 1)?
        {
            return Ok(false);
        }
        at = value_end;
    }
    Ok(true)
}

/// The items (FFFE,E000) of a sequence value in `bytes[at..end]`, each walked as a data set.
fn items(
    path: &Path,
    bytes: &[u8],
    mut at: usize,
    end: usize,
    s: Syntax,
    depth: usize,
) -> Result<bool> {
    while at + 8 <= end {
        let tag = (
            u16_at(bytes, at, s.big_endian),
            u16_at(bytes, at + 2, s.big_endian),
        );
        let length = u32_at(bytes, at + 4, s.big_endian);
        if tag != (0xFFFE, 0xE000) || length == UNDEFINED {
            return Ok(false);
        }
        let value = at + 8;
        Element {
            tag,
            value,
            length,
            is_sequence: false,
        }
        .fits(path, end)?;
        if !walk(path, bytes, value, value + length as usize, s, depth)? {
            return Ok(false);
        }
        at = value + length as usize;
    }
    Ok(true)
}

struct Element {
    tag: (u16, u16),
    /// Where the value starts.
    value: usize,
    length: u32,
    is_sequence: bool,
}

impl Element {
    /// Errors when the value runs past `end`.
    fn fits(&self, path: &Path, end: usize) -> Result<()> {
        let left = end.saturating_sub(self.value);
        if self.length != UNDEFINED && self.length as usize > left {
            return Err(DatasetError::truncated(
                path,
                format!(
                    "element ({:04X},{:04X}) declares a value of {} bytes, but only {left} \
                     bytes follow it",
                    self.tag.0, self.tag.1, self.length
                ),
            ));
        }
        Ok(())
    }
}

/// The element header at `at`, or `None` when the bytes end inside it.
fn element(bytes: &[u8], at: usize, s: Syntax) -> Option<Element> {
    let tag = (
        u16_at(bytes, at, s.big_endian),
        u16_at(bytes, at + 2, s.big_endian),
    );
    // Item and delimitation tags carry a 4-byte length and no VR in every syntax.
    if !s.explicit || tag.0 == 0xFFFE {
        return Some(Element {
            tag,
            value: at + 8,
            length: u32_at(bytes, at + 4, s.big_endian),
            is_sequence: false,
        });
    }
    let vr: &[u8; 2] = bytes.get(at + 4..at + 6)?.try_into().ok()?;
    if !SHORT_VRS.contains(&vr) {
        if at + 12 > bytes.len() {
            return None;
        }
        Some(Element {
            tag,
            value: at + 12,
            length: u32_at(bytes, at + 8, s.big_endian),
            is_sequence: vr == b"SQ",
        })
    } else {
        Some(Element {
            tag,
            value: at + 8,
            length: u32::from(u16_at(bytes, at + 6, s.big_endian)),
            is_sequence: false,
        })
    }
}

fn u16_at(b: &[u8], at: usize, big: bool) -> u16 {
    let x = [b[at], b[at + 1]];
    if big {
        u16::from_be_bytes(x)
    } else {
        u16::from_le_bytes(x)
    }
}

fn u32_at(b: &[u8], at: usize, big: bool) -> u32 {
    let x = [b[at], b[at + 1], b[at + 2], b[at + 3]];
    if big {
        u32::from_be_bytes(x)
    } else {
        u32::from_le_bytes(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Preamble, DICM, a meta group with the transfer syntax, then `body`.
    fn file(syntax: &str, body: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8; 128];
        b.extend(b"DICM");
        let mut uid = syntax.as_bytes().to_vec();
        if uid.len() % 2 == 1 {
            uid.push(0);
        }
        b.extend([0x02, 0x00, 0x10, 0x00, b'U', b'I']);
        b.extend((uid.len() as u16).to_le_bytes());
        b.extend(uid);
        b.extend(body);
        b
    }

    fn explicit(tag: (u16, u16), vr: &[u8; 2], len: u32, value: &[u8]) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend(tag.0.to_le_bytes());
        b.extend(tag.1.to_le_bytes());
        b.extend(vr);
        if !SHORT_VRS.contains(&vr) {
            b.extend([0, 0]);
            b.extend(len.to_le_bytes());
        } else {
            b.extend((len as u16).to_le_bytes());
        }
        b.extend(value);
        b
    }

    #[test]
    fn lengths_past_the_end_are_named_and_honest_ones_pass() {
        let p = Path::new("x.dcm");
        let ok = explicit((0x0010, 0x0010), b"PN", 4, b"A^B ");
        assert!(check(p, &file("1.2.840.10008.1.2.1", &ok)).is_ok());
        // An OB element claiming 3.7 GB in a small file (what the fuzzer found).
        let bad = explicit((0x2830, 0x5300), b"OB", 3_760_206_080, b"xx");
        let e = check(p, &file("1.2.840.10008.1.2.1", &bad))
            .unwrap_err()
            .to_string();
        assert!(e.contains("(2830,5300)") && e.contains("3760206080"), "{e}");
        // Implicit VR: tag and a 4-byte length.
        let mut imp = vec![0x10, 0x00, 0x10, 0x00];
        imp.extend(1_000_000u32.to_le_bytes());
        imp.extend(b"ABCD");
        assert!(check(p, &file("1.2.840.10008.1.2", &imp)).is_err());
        // Inside a sequence of defined length: the nested element is checked too.
        let inner = explicit((0x0008, 0x0100), b"UT", 500_000, b"ab");
        let mut item = vec![0xFE, 0xFF, 0x00, 0xE0];
        item.extend((inner.len() as u32).to_le_bytes());
        item.extend(&inner);
        let sq = explicit((0x0008, 0x1140), b"SQ", item.len() as u32, &item);
        let e = check(p, &file("1.2.840.10008.1.2.1", &sq))
            .unwrap_err()
            .to_string();
        assert!(e.contains("(0008,0100)"), "{e}");
        // An unknown VR is read with a 4-byte length, as the parser reads it.
        let odd = explicit((0x543E, 0x0008), b"\x10O", 1_869_442_932, b"tomograf");
        assert!(check(p, &file("1.2.840.10008.1.2.1", &odd)).is_err());
        // Undefined length: the walk stops there (the parser reads it item by item).
        let und = explicit((0x7FE0, 0x0010), b"OB", UNDEFINED, b"");
        assert!(check(p, &file("1.2.840.10008.1.2.4.50", &und)).is_ok());
        // Not a Part-10 file: nothing to check here; a file that ends right after the
        // marker or inside the group length ends in Ok or a truncation error, never a panic.
        assert!(check(p, b"not dicom").is_ok());
        let mut short = vec![0u8; 128];
        short.extend(b"DICM");
        for extra in [
            &b""[..],
            b"\x02\x00\x00\x00UL\x04",
            b"\x02\x00\x00\x00UL\x04\x00\xff\xff",
        ] {
            let mut f = short.clone();
            f.extend(extra);
            if let Err(e) = check(p, &f) {
                assert!(e.to_string().contains("truncated"), "{e}");
            }
        }
    }
}
