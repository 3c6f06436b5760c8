//! Whole-buffer gzip inflate of a `.nii.gz` (libdeflate), for files whose size is known
//! before inflating.
//!
//! A streaming inflate (flate2) needs no size, but libdeflate, which inflates into one
//! buffer, is 1.5–1.6× faster on CT volumes (docs/datasets.md, "Loading speed"). The size
//! is known when the NIfTI header (inflated first, by streaming: a few hundred bytes) and
//! the gzip trailer (ISIZE, the uncompressed length mod 2³²) agree on it. Anything else —
//! a header that does not parse, extra bytes after the voxels, several gzip members, a
//! corrupt stream, a size that cannot be allocated — returns `None`, and the caller
//! streams the file as before, which reports any problem with its usual, precise errors.

use super::decode::zeroed_words;
use libdeflater::Decompressor;

/// The uncompressed length mod 2³² that a gzip file's trailer records (its last member's).
fn trailer_size(gz: &[u8]) -> Option<u32> {
    let tail: [u8; 4] = gz.get(gz.len().checked_sub(4)?..)?.try_into().ok()?;
    Some(u32::from_le_bytes(tail))
}

/// The inflated bytes of a `.nii.gz`, held in a word buffer so that its voxels can be
/// decoded to `f32` where they lie ([`super::decode::decode_in_place`]).
pub(super) struct Inflated {
    /// At least `len` bytes and `min_words` words (see [`whole`]).
    pub words: Vec<f32>,
    /// Inflated bytes at the start of `words`.
    pub len: usize,
}

impl Inflated {
    /// The inflated file: header, extensions and voxels.
    pub fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice(&self.words)[..self.len]
    }
}

/// Inflates the gzip file `gz` into a buffer of at least `min_words` words that starts
/// with exactly `expected` bytes, verifying the CRC-32 and length in its trailer; `None`
/// unless it holds exactly that many bytes (see the module documentation).
pub(super) fn whole(gz: &[u8], expected: u64, min_words: usize) -> Option<Inflated> {
    if u64::from(trailer_size(gz)?) != expected % (1u64 << 32) {
        return None;
    }
    let len = usize::try_from(expected).ok()?;
    let mut words = zeroed_words(len.div_ceil(4).max(min_words))?;
    let out: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
    let n = Decompressor::new()
        .gzip_decompress(gz, &mut out[..len])
        .ok()?;
    (n == len).then_some(Inflated { words, len })
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::Compression;
    use flate2::write::GzEncoder;
    use std::io::Write;

    fn gzip(data: &[u8]) -> Vec<u8> {
        let mut e = GzEncoder::new(Vec::new(), Compression::fast());
        e.write_all(data).unwrap();
        e.finish().unwrap()
    }

    #[test]
    fn inflates_exactly_the_expected_bytes_and_nothing_else() {
        let data: Vec<u8> = (0..100_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let gz = gzip(&data);
        assert_eq!(
            whole(&gz, data.len() as u64, 0)
                .as_ref()
                .map(Inflated::bytes),
            Some(&data[..])
        );
        // Another expected size (the header disagrees with the trailer): not attempted.
        assert!(whole(&gz, data.len() as u64 - 1, 0).is_none());
        // Two members: the trailer is the second's, so the sizes disagree.
        let two = [gzip(&data[..500]), gzip(&data[500..])].concat();
        assert!(whole(&two, data.len() as u64, 0).is_none());
        // A flipped bit in the stream fails the CRC (or the inflate).
        let mut bad = gz.clone();
        let mid = bad.len() / 2;
        bad[mid] ^= 0x10;
        assert!(whole(&bad, data.len() as u64, 0).is_none());
        // Truncated files, including ones shorter than a trailer.
        assert!(whole(&gz[..gz.len() - 9], data.len() as u64, 0).is_none());
        assert!(whole(&gz[..3], 3, 0).is_none());
    }
}
