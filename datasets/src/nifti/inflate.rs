//! Whole-buffer gzip inflate of a `.nii.gz` (libdeflate), for files whose size is known
//! before inflating.
//!
//! A streaming inflate (flate2) needs no size, but libdeflate, which inflates into one
//! buffer, is 1.5–1.6× faster on CT volumes (docs/datasets.md, "Loading speed"). The size
//! is known when the NIfTI header (inflated first, by streaming: a few hundred bytes) and
//! the gzip trailer (ISIZE, the uncompressed length mod 2³²) agree on it. Anything else —
//! a header that does not parse, extra bytes after the voxels, several gzip members, a
//! corrupt stream, a size that cannot be allocated — gives the compressed bytes back, and
//! the caller streams them as before, which reports any problem with its usual, precise
//! errors.
//!
//! # Memory
//! Fresh memory is dear on the virtual machines we measure on (the kernel zeroes each new
//! page, at roughly 0.5 GB/s per core), so the file is inflated with no buffer beyond the
//! `f32` volume's own: the compressed bytes are read into the **end** of the word buffer
//! the voxels will be decoded into, and inflated into its **start** (an int16 CT's
//! inflated bytes fill half of it, its compressed ones typically less than a quarter).
//! Only where the two do not fit side by side (float32 voxels, or a file that hardly
//! compresses) are the compressed bytes read into a buffer of their own. The pages are
//! first touched on every core, the part only the decoding writes while the one-threaded
//! inflate runs.

use super::decode::{touch_pages, unfaulted_words};
use libdeflater::Decompressor;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};

/// The inflated bytes of a `.nii.gz`, held in a word buffer so that its voxels can be
/// decoded to `f32` where they lie ([`super::decode::decode_in_place`]).
pub(super) struct Inflated {
    /// At least `len` bytes and `min_words` words (see [`read`]).
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

/// A `.nii.gz` as [`read`] leaves it.
pub(super) enum GzFile {
    /// Inflated whole.
    Inflated(Inflated),
    /// Not inflated (see the module documentation): the file's bytes, to be streamed.
    Compressed(Vec<u8>),
}

/// Reads the gzip file behind `reader` (whose first bytes may be buffered already; any
/// position) of `file_len` bytes and, where `expected` bytes (header, extensions and
/// voxels, as the NIfTI header states) are at most `max_ratio` per compressed byte and the
/// gzip trailer agrees, inflates it whole into a buffer of at least `min_words` words,
/// verifying the trailer's CRC-32 and length; otherwise returns the file's bytes.
///
/// Errors are those of reading the file (a file that ends early is read again for the
/// streaming reader, which reports where it ends).
pub(super) fn read(
    reader: &mut BufReader<File>,
    file_len: Option<u64>,
    expected: Option<u64>,
    min_words: usize,
    max_ratio: u64,
) -> io::Result<GzFile> {
    if let (Some(len), Some(n)) = (file_len, expected)
        && n <= max_ratio.saturating_mul(len)
    {
        if let Some(whole) = whole(reader, len, n, min_words)? {
            return Ok(GzFile::Inflated(whole));
        }
        reader.seek(SeekFrom::Start(0))?;
    }
    // Not moved unless tried above: a file that cannot seek (a pipe) is read as it comes.
    let mut bytes = Vec::with_capacity(file_len.map_or(0, |n| n as usize));
    reader.read_to_end(&mut bytes)?;
    Ok(GzFile::Compressed(bytes))
}

/// [`read`]'s whole-buffer inflate of a file of `len` bytes into `n` bytes; `None` where it
/// does not apply or fails.
fn whole(
    reader: &mut BufReader<File>,
    len: u64,
    n: u64,
    min_words: usize,
) -> io::Result<Option<Inflated>> {
    // The uncompressed length mod 2³² that the trailer records (its last member's).
    if len < 18 {
        return Ok(None);
    }
    reader.seek(SeekFrom::End(-4))?;
    let mut tail = [0u8; 4];
    reader.read_exact(&mut tail)?;
    if u64::from(u32::from_le_bytes(tail)) != n % (1u64 << 32) {
        return Ok(None);
    }
    let (Ok(len), Ok(n)) = (usize::try_from(len), usize::try_from(n)) else {
        return Ok(None);
    };
    let words_len = n.div_ceil(4).max(min_words);
    let Some(mut words) = unfaulted_words(words_len) else {
        return Ok(None);
    };
    let mut own = Vec::new();
    let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
    let side_by_side = n + len <= bytes.len();
    let (front, back) = bytes.split_at_mut(if side_by_side {
        bytes.len() - len
    } else {
        bytes.len()
    });
    let compressed: &mut [u8] = if side_by_side {
        back
    } else {
        if own.try_reserve_exact(len).is_err() {
            return Ok(None);
        }
        own.resize(len, 0u8);
        &mut own
    };
    let (out, middle) = front.split_at_mut(n);
    if side_by_side {
        // (A buffer of their own was written by `resize` already.)
        touch_pages(compressed);
    }
    reader.seek(SeekFrom::Start(0))?;
    let (read, ()) = rayon::join(|| reader.read_exact(compressed), || touch_pages(out));
    match read {
        Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(None),
        r => r?,
    }
    let (inflated, ()) = rayon::join(
        || Decompressor::new().gzip_decompress(compressed, out),
        || touch_pages(middle),
    );
    Ok((inflated.ok() == Some(n)).then_some(Inflated { words, len: n }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::Compression;
    use flate2::write::GzEncoder;
    use std::io::{BufRead, Write};

    fn gzip(data: &[u8]) -> Vec<u8> {
        let mut e = GzEncoder::new(Vec::new(), Compression::fast());
        e.write_all(data).unwrap();
        e.finish().unwrap()
    }

    /// `read` of `gz` written to a file, its first bytes buffered as the NIfTI reader
    /// leaves them: the inflated bytes, or `None` where the file's bytes came back.
    fn read_file(gz: &[u8], expected: u64, min_words: usize) -> Option<Vec<u8>> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.gz");
        std::fs::write(&path, gz).unwrap();
        let mut reader = BufReader::with_capacity(64, File::open(&path).unwrap());
        reader.fill_buf().unwrap();
        match read(
            &mut reader,
            Some(gz.len() as u64),
            Some(expected),
            min_words,
            1032,
        )
        .unwrap()
        {
            GzFile::Inflated(w) => {
                assert!(w.words.len() >= min_words && w.words.len() * 4 >= w.len);
                Some(w.bytes().to_vec())
            }
            GzFile::Compressed(bytes) => {
                assert_eq!(bytes, gz, "the file's bytes come back whole");
                None
            }
        }
    }

    #[test]
    fn inflates_exactly_the_expected_bytes_and_nothing_else() {
        let data: Vec<u8> = (0..100_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let n = data.len() as u64;
        let gz = gzip(&data);
        // The compressed bytes beside the inflated ones at the end of the word buffer (an
        // int16 CT: twice as many words as inflated bytes), and in a buffer of their own
        // (float32: one word per four inflated bytes).
        assert!(data.len() + gz.len() <= data.len() * 2);
        assert_eq!(
            read_file(&gz, n, data.len() / 2).as_deref(),
            Some(&data[..])
        );
        assert_eq!(
            read_file(&gz, n, data.len() / 4).as_deref(),
            Some(&data[..])
        );
        // Another expected size (the header disagrees with the trailer): not attempted.
        assert!(read_file(&gz, n - 1, 0).is_none());
        // Two members: the trailer is the second's, so the sizes disagree.
        let two = [gzip(&data[..500]), gzip(&data[500..])].concat();
        assert!(read_file(&two, n, 0).is_none());
        // A flipped bit in the stream fails the CRC (or the inflate), either way.
        let mut bad = gz.clone();
        let mid = bad.len() / 2;
        bad[mid] ^= 0x10;
        assert!(read_file(&bad, n, data.len() / 2).is_none());
        assert!(read_file(&bad, n, 0).is_none());
        // Truncated files, including ones shorter than a trailer.
        assert!(read_file(&gz[..gz.len() - 9], n, 0).is_none());
        assert!(read_file(&gz[..3], 3, 0).is_none());
    }
}
