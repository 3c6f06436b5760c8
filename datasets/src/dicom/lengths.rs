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
use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry};
use dicom_core::{Tag, VR};
use dicom_dictionary_std::StandardDataDictionary;
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
const ITEM: (u16, u16) = (0xFFFE, 0xE000);
const ITEM_END: (u16, u16) = (0xFFFE, 0xE00D);
const SEQUENCE_END: (u16, u16) = (0xFFFE, 0xE0DD);
const PIXEL_DATA: (u16, u16) = (0x7FE0, 0x0010);
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
    // The file meta group, read exactly as `dicom-object` reads it (`FileMetaTable`): it
    // must start with its group length (0002,0000) of 4 bytes (else the parser refuses the
    // file, and there is nothing to check); then whole elements (explicit VR little endian,
    // of any group) are read while the bytes read so far are fewer than that length, so the
    // data set starts after the last element begun inside it — not where the group length
    // alone says. Following the stated length instead put the walk out of step with the
    // parser on a file whose meta group was malformed in its middle, and a 4 GB claim
    // reached the parser (docs/reliability.md).
    if bytes.len() < 132 + 12 {
        return Ok(()); // too short for the group length: the parser reports it
    }
    let Some(first) = element(bytes, 132, le) else {
        return Ok(());
    };
    if first.tag != (0x0002, 0x0000) || first.length != 4 || first.value + 4 > bytes.len() {
        return Ok(());
    }
    let group_length = u64::from(u32_at(bytes, first.value, false));
    let mut at = first.value + 4;
    let mut read = 0u64;
    let mut syntax_uid = String::new();
    while read < group_length {
        if at + 8 > bytes.len() {
            return Ok(()); // the parser reports the meta group as truncated
        }
        let Some(e) = element(bytes, at, le) else {
            return Ok(());
        };
        e.fits(path, bytes.len())?;
        if e.length == UNDEFINED {
            return Ok(()); // the parser refuses an undefined length in the meta group
        }
        if e.tag == (0x0002, 0x0010) {
            let v = &bytes[e.value..e.value + e.length as usize];
            syntax_uid = String::from_utf8_lossy(v)
                .trim_end_matches(['\0', ' '])
                .to_string();
        }
        read += (e.value - at) as u64 + u64::from(e.length);
        at = e.value + e.length as usize;
    }
    if DEFLATED.contains(&syntax_uid.as_str()) {
        return Ok(());
    }
    let syntax = Syntax {
        explicit: syntax_uid != IMPLICIT_LE,
        big_endian: syntax_uid == EXPLICIT_BE,
    };
    let Err(e) = walk(path, bytes, at, bytes.len(), syntax, 0, false) else {
        return Ok(());
    };
    if e.to_string().contains("(7FE0,0010)") {
        return Err(e); // the pixel data cut short: a truncated file
    }
    // A data set that reads whole in another encoding was written in it: the meta group's
    // TransferSyntaxUID is wrong, not the file short (it once read "file is truncated").
    let others = [
        (IMPLICIT_LE, "implicit VR little endian", false, false),
        (
            "1.2.840.10008.1.2.1",
            "explicit VR little endian",
            true,
            false,
        ),
        (EXPLICIT_BE, "explicit VR big endian", true, true),
    ];
    for (uid, name, explicit, big_endian) in others {
        let other = Syntax {
            explicit,
            big_endian,
        };
        let detail = match &e {
            DatasetError::Truncated { detail, .. } => detail.clone(),
            other => other.to_string(),
        };
        if (other.explicit, other.big_endian) != (syntax.explicit, syntax.big_endian)
            && matches!(
                walk(path, bytes, at, bytes.len(), other, 0, false),
                Ok(Some(_))
            )
        {
            return Err(DatasetError::Corrupt {
                path: path.to_path_buf(),
                reason: format!(
                    "its TransferSyntaxUID (0002,0010) is '{syntax_uid}', but its data set is \
                     encoded as {name} ({uid}): read as '{syntax_uid}' it is garbage ({detail}); \
                     the file's meta header is wrong — rewrite it with the right transfer \
                     syntax (e.g. dcmodify or pydicom)"
                ),
            });
        }
    }
    Err(e)
}

/// Walks the elements in `bytes[at..end]` as `dicom-parser` reads them. With `in_item`,
/// the elements are those of an item of undefined length, which end at an item
/// delimitation (FFFE,E00D). Returns where the walk ended (after the delimiter, or `end`),
/// or `None` when it met a structure it does not follow (nothing after it is checked).
fn walk(
    path: &Path,
    bytes: &[u8],
    mut at: usize,
    end: usize,
    s: Syntax,
    depth: usize,
    in_item: bool,
) -> Result<Option<usize>> {
    while at + 8 <= end {
        let Some(e) = element(bytes, at, s) else {
            return Ok(Some(end));
        };
        match e.tag {
            ITEM_END if in_item => return Ok(Some(e.value)),
            // The parser skips an item delimiter outside a sequence.
            ITEM_END => {
                at = e.value;
                continue;
            }
            // Any other (FFFE,xxxx) tag in a data set, item and sequence delimiters
            // included, the parser reads as an element of VR UN with that length: checked
            // below like any element (the fuzzer's (FFFE,FFFF) claiming 4 GB).
            _ => {}
        }
        e.fits(path, end)?;
        e.whole(path)?;
        if e.length == UNDEFINED {
            // The parser reads encapsulated pixel data as fragments, and every other element
            // of undefined length — whatever its VR — as a sequence of items.
            if depth >= MAX_DEPTH {
                return Ok(None);
            }
            let next = if e.tag == PIXEL_DATA {
                fragments(path, bytes, e.value, s)?
            } else {
                items(path, bytes, e.value, bytes.len(), s, depth + 1, true)?
            };
            match next {
                Some(next) => at = next,
                None => return Ok(None),
            }
            continue;
        }
        let value_end = e.value + e.length as usize;
        if e.is_sequence() && depth < MAX_DEPTH {
            items(path, bytes, e.value, value_end, s, depth + 1, false)?;
        }
        at = value_end;
    }
    Ok(Some(end))
}

/// The items (FFFE,E000) of a sequence value starting at `at`: of defined length (ending
/// at `end`) or, with `undefined`, ending at a sequence delimitation (FFFE,E0DD). Each item
/// is walked as a data set, of defined or undefined length. Returns where the sequence
/// ended, or `None` when the walk stopped.
fn items(
    path: &Path,
    bytes: &[u8],
    mut at: usize,
    end: usize,
    s: Syntax,
    depth: usize,
    undefined: bool,
) -> Result<Option<usize>> {
    while at + 8 <= end {
        let (tag, length) = item_header(bytes, at, s);
        let value = at + 8;
        match tag {
            SEQUENCE_END if undefined => return Ok(Some(value)),
            ITEM if length == UNDEFINED => {
                match walk(path, bytes, value, bytes.len(), s, depth, true)? {
                    Some(next) => at = next,
                    None => return Ok(None),
                }
            }
            ITEM => {
                Element::item(tag, value, length).fits(path, end)?;
                if walk(path, bytes, value, value + length as usize, s, depth, false)?.is_none() {
                    return Ok(None);
                }
                at = value + length as usize;
            }
            _ => return Ok(None),
        }
    }
    Ok(if undefined { None } else { Some(end) })
}

/// The fragments of encapsulated pixel data from `at`: items of defined length up to the
/// sequence delimitation, each of which the parser reads whole.
fn fragments(path: &Path, bytes: &[u8], mut at: usize, s: Syntax) -> Result<Option<usize>> {
    while at + 8 <= bytes.len() {
        let (tag, length) = item_header(bytes, at, s);
        match tag {
            SEQUENCE_END => return Ok(Some(at + 8)),
            ITEM if length != UNDEFINED => {
                Element::item(tag, at + 8, length).fits(path, bytes.len())?;
                at += 8 + length as usize;
            }
            _ => return Ok(None),
        }
    }
    Ok(None)
}

/// Tag and length of an item or delimiter header at `at` (`at + 8` must be in bounds).
fn item_header(bytes: &[u8], at: usize, s: Syntax) -> ((u16, u16), u32) {
    let tag = (
        u16_at(bytes, at, s.big_endian),
        u16_at(bytes, at + 2, s.big_endian),
    );
    (tag, u32_at(bytes, at + 4, s.big_endian))
}

struct Element {
    tag: (u16, u16),
    /// Where the value starts.
    value: usize,
    length: u32,
    /// As the parser reads it ([`element`]).
    vr: VR,
}

impl Element {
    fn item(tag: (u16, u16), value: usize, length: u32) -> Self {
        Element {
            tag,
            value,
            length,
            vr: VR::UN,
        }
    }

    fn is_sequence(&self) -> bool {
        self.vr == VR::SQ
    }

    /// Errors when a binary number VR's value is not a whole number of numbers: the
    /// parser reads only the whole numbers but counts the declared length, and goes on
    /// reading out of step with the file (how a 4 GB claim hid from this walk, found by
    /// the fuzzer: an FL element of 26 bytes).
    fn whole(&self, path: &Path) -> Result<()> {
        let size = match self.vr {
            VR::US | VR::OW | VR::SS => 2,
            VR::FL | VR::OF | VR::SL | VR::OL | VR::UL | VR::AT => 4,
            VR::FD | VR::OD | VR::SV | VR::OV | VR::UV => 8,
            _ => 1,
        };
        if self.length != UNDEFINED && !self.length.is_multiple_of(size) {
            return Err(DatasetError::corrupt(
                path,
                format!(
                    "element ({:04X},{:04X}) of VR {} declares {} bytes, which is not a whole \
                     number of its {size}-byte values",
                    self.tag.0,
                    self.tag.1,
                    self.vr.to_string(),
                    self.length
                ),
            ));
        }
        Ok(())
    }

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

/// The element header at `at`, or `None` when the bytes end inside it. Its VR is the one
/// the parser gives it: the two bytes in explicit VR (an unknown pair is UN), the data
/// dictionary's in implicit VR (`relaxed`: US for US-or-SS, OW for OB-or-OW; pixel and
/// overlay data OW; a tag it does not know UN).
fn element(bytes: &[u8], at: usize, s: Syntax) -> Option<Element> {
    let tag = (
        u16_at(bytes, at, s.big_endian),
        u16_at(bytes, at + 2, s.big_endian),
    );
    // Item and delimitation tags carry a 4-byte length and no VR in every syntax.
    if tag.0 == 0xFFFE {
        return Some(Element::item(
            tag,
            at + 8,
            u32_at(bytes, at + 4, s.big_endian),
        ));
    }
    if !s.explicit {
        let vr = if tag == PIXEL_DATA || (tag.0 >> 8 == 0x60 && tag.1 == 0x3000) {
            VR::OW
        } else {
            StandardDataDictionary
                .by_tag(Tag(tag.0, tag.1))
                .map(|entry| entry.vr().relaxed())
                .unwrap_or(VR::UN)
        };
        return Some(Element {
            tag,
            value: at + 8,
            length: u32_at(bytes, at + 4, s.big_endian),
            vr,
        });
    }
    let code: &[u8; 2] = bytes.get(at + 4..at + 6)?.try_into().ok()?;
    if !SHORT_VRS.contains(&code) {
        if at + 12 > bytes.len() {
            return None;
        }
        Some(Element {
            tag,
            value: at + 12,
            length: u32_at(bytes, at + 8, s.big_endian),
            vr: VR::from_binary(*code).unwrap_or(VR::UN),
        })
    } else {
        Some(Element {
            tag,
            value: at + 8,
            length: u32::from(u16_at(bytes, at + 6, s.big_endian)),
            vr: VR::from_binary(*code).unwrap_or(VR::UN),
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
        let group = 8 + uid.len() as u32;
        b.extend([0x02, 0x00, 0x00, 0x00, b'U', b'L', 4, 0]);
        b.extend(group.to_le_bytes());
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

    /// An item (FFFE,E000) of `len` bytes (or undefined) holding `body`.
    fn item(len: u32, body: &[u8]) -> Vec<u8> {
        let mut b = vec![0xFE, 0xFF, 0x00, 0xE0];
        b.extend(len.to_le_bytes());
        b.extend(body);
        b
    }

    const ITEM_DELIMITER: [u8; 8] = [0xFE, 0xFF, 0x0D, 0xE0, 0, 0, 0, 0];
    const SEQUENCE_DELIMITER: [u8; 8] = [0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0];

    #[test]
    fn undefined_length_sequences_are_walked_as_the_parser_reads_them() {
        let p = Path::new("x.dcm");
        let ts = "1.2.840.10008.1.2.1";
        let name = explicit((0x0010, 0x0010), b"PN", 4, b"A^B ");
        // SQ of undefined length: an undefined item (ends at its delimiter) and a defined
        // one, then the sequence delimiter; then the data set goes on.
        let mut body = explicit((0x0008, 0x1140), b"SQ", UNDEFINED, b"");
        let mut inner = name.clone();
        inner.extend(ITEM_DELIMITER);
        body.extend(item(UNDEFINED, &inner));
        body.extend(item(name.len() as u32, &name));
        body.extend(SEQUENCE_DELIMITER);
        let good = [body.clone(), name.clone()].concat();
        assert!(check(p, &file(ts, &good)).is_ok());
        // The same, with a 4 GB claim after the sequence: found (the walk used to stop at
        // the undefined length).
        let big = explicit((0x0009, 0x0010), b"OB", 0xF000_0000, b"xx");
        let e = check(p, &file(ts, &[body.clone(), big.clone()].concat()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("(0009,0010)"), "{e}");
        // Inside an item of undefined length.
        let mut deep = explicit((0x0008, 0x1140), b"SQ", UNDEFINED, b"");
        deep.extend(item(UNDEFINED, &big));
        assert!(check(p, &file(ts, &deep)).is_err());
        // An element of an unknown VR and undefined length, which the parser reads as a
        // sequence, whose item holds a 4 GB claim.
        let mut un = explicit((0x0000, 0x0000), b"\0\0", UNDEFINED, b"");
        un.extend(item(UNDEFINED, &big));
        assert!(check(p, &file(ts, &un)).is_err());
        // Delimiters where the parser skips them (outside any sequence) are skipped.
        let stray = [ITEM_DELIMITER.to_vec(), big].concat();
        assert!(check(p, &file(ts, &stray)).is_err());
        // Any other (FFFE,xxxx) tag in a data set is an element to the parser: its length
        // is checked (what the fuzzer found next: (FFFE,FFFF) claiming 4 GB).
        let mut odd = vec![0xFE, 0xFF, 0xFF, 0xFF];
        odd.extend(0xFEFF_FFFFu32.to_le_bytes());
        odd.extend(b"xxxx");
        let e = check(p, &file(ts, &[name.clone(), odd].concat()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("(FFFE,FFFF)"), "{e}");
    }

    #[test]
    fn a_number_value_of_a_broken_length_is_refused() {
        // What the fuzzer found (fuzz/seeds/dicom_series/malformed-meta-4GB): an FL element
        // of 26 bytes, of which the parser reads 24 (six floats) while counting 26; it then
        // read the next header 2 bytes early, where a length of 4 GB stood.
        let p = Path::new("x.dcm");
        let ts = "1.2.840.10008.1.2.1";
        let fl = explicit((0x0008, 0x0016), b"FL", 26, &[0; 26]);
        let e = check(p, &file(ts, &fl)).unwrap_err().to_string();
        assert!(e.contains("(0008,0016) of VR FL declares 26 bytes"), "{e}");
        assert!(
            check(
                p,
                &file(ts, &explicit((0x0008, 0x0016), b"FL", 24, &[0; 24]))
            )
            .is_ok()
        );
        // In implicit VR the VR is the dictionary's: Rows (0028,0010) is US.
        let mut rows = vec![0x28, 0x00, 0x10, 0x00];
        rows.extend(3u32.to_le_bytes());
        rows.extend([1, 2, 3]);
        let e = check(p, &file("1.2.840.10008.1.2", &rows))
            .unwrap_err()
            .to_string();
        assert!(e.contains("(0028,0010) of VR US"), "{e}");
    }

    #[test]
    fn the_meta_group_ends_where_the_parser_ends_it() {
        // The parser reads whole elements while fewer bytes than the group length have been
        // read: here the group length (10) ends inside the transfer syntax element (28
        // bytes), so the data set starts after that element, not 10 bytes in.
        let p = Path::new("x.dcm");
        let uid = b"1.2.840.10008.1.2.1\0";
        let mut b = vec![0u8; 128];
        b.extend(b"DICM");
        b.extend([0x02, 0x00, 0x00, 0x00, b'U', b'L', 4, 0]);
        b.extend(10u32.to_le_bytes());
        b.extend(explicit((0x0002, 0x0010), b"UI", uid.len() as u32, uid));
        b.extend(explicit((0x0009, 0x0010), b"OB", 0xF000_0000, b"xx"));
        let e = check(p, &b).unwrap_err().to_string();
        assert!(e.contains("(0009,0010)"), "{e}");
        // Without the group length the parser refuses the file itself: nothing to check.
        let mut no_group = vec![0u8; 128];
        no_group.extend(b"DICM");
        no_group.extend(explicit((0x0002, 0x0010), b"UI", uid.len() as u32, uid));
        no_group.extend(explicit((0x0009, 0x0010), b"OB", 0xF000_0000, b"xx"));
        assert!(check(p, &no_group).is_ok());
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
        // Encapsulated pixel data (undefined length): its fragments are checked, up to the
        // sequence delimitation.
        let fragment = |len: u32, data: &[u8]| {
            let mut b = vec![0xFE, 0xFF, 0x00, 0xE0];
            b.extend(len.to_le_bytes());
            b.extend(data);
            b
        };
        let mut enc = explicit((0x7FE0, 0x0010), b"OB", UNDEFINED, b"");
        enc.extend(fragment(0, b""));
        enc.extend(fragment(4, b"JPEG"));
        enc.extend([0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0]);
        assert!(check(p, &file("1.2.840.10008.1.2.4.50", &enc)).is_ok());
        let mut enc = explicit((0x7FE0, 0x0010), b"OB", UNDEFINED, b"");
        enc.extend(fragment(0x8000_0000, b"JPEG"));
        assert!(check(p, &file("1.2.840.10008.1.2.4.50", &enc)).is_err());
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
