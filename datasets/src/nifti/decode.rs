//! Stored voxel values → `f32`, on every core.
//!
//! Two ways for the CT voxel types (int16, uint16, float32):
//! * [`decode_parallel`] reads raw bytes and returns a new buffer;
//! * [`decode_in_place`] decodes voxels that lie in the bytes of the `f32` buffer they are
//!   decoded into (a `.nii.gz` inflated whole, [`super::inflate::read`]): no second buffer
//!   of the volume's size is allocated. On the virtual machines we measure on, the kernel
//!   zeroes fresh pages at about 0.5 GB/s, so a 140 MB buffer not allocated is worth more
//!   than the decoding itself (docs/datasets.md, "Loading speed").
//!
//! Both give the same values as the `nifti` crate's `into_ndarray::<f32>`: each value cast
//! to f32, then `x·slope + inter` in f32 when the slope is not 0 (tested bit for bit), then
//! the caller's `map` (e.g. HU → mu, in the same pass; `std::convert::identity` for none).

use nifti::{Endianness, NiftiType};
use rayon::prelude::*;

/// Voxels per parallel task: large enough that scheduling costs nothing.
const BLOCK: usize = 1 << 16;

/// The stored value of `N` bytes → f32, before scaling: int16 (`signed`) or uint16.
fn two_bytes(signed: bool, le: bool) -> impl Fn([u8; 2]) -> f32 + Sync + Copy {
    move |b| {
        let bits = if le {
            u16::from_le_bytes(b)
        } else {
            u16::from_be_bytes(b)
        };
        if signed {
            f32::from(bits.cast_signed())
        } else {
            f32::from(bits)
        }
    }
}
fn float32(le: bool) -> impl Fn([u8; 4]) -> f32 + Sync + Copy {
    move |b| {
        if le {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    }
}

/// The header's scaling (none when the slope is 0), then `map`: what each stored value
/// becomes after its cast to f32.
pub(super) fn scaling(
    slope: f32,
    inter: f32,
    map: impl Fn(f32) -> f32 + Sync + Copy,
) -> impl Fn(f32) -> f32 + Sync + Copy {
    move |x| map(if slope == 0.0 { x } else { x * slope + inter })
}

/// `decode`, then `scale`.
fn then<const N: usize>(
    decode: impl Fn([u8; N]) -> f32 + Sync + Copy,
    scale: impl Fn(f32) -> f32 + Sync + Copy,
) -> impl Fn([u8; N]) -> f32 + Sync + Copy {
    move |b| scale(decode(b))
}

/// Volumes of at least this many 2-byte voxels are decoded through a table.
pub(super) const TABLE_MIN: usize = 1 << 18;

/// For `count ≥ TABLE_MIN` voxels, `decode`'s values for all 2¹⁶ stored values, indexed by
/// the stored bytes read as a native `u16` (256 KiB: it stays in the L2 cache).
type Table = Option<Box<[f32; 1 << 16]>>;

fn table(count: usize, decode: impl Fn([u8; 2]) -> f32) -> Table {
    (count >= TABLE_MIN).then(|| {
        let values: Vec<f32> = (0..=u16::MAX).map(|i| decode(i.to_ne_bytes())).collect();
        values.into_boxed_slice().try_into().expect("2^16 values")
    })
}

/// `decode`, or a lookup in its [`table`] where there is one: the same values bit for bit,
/// since each entry is `decode`'s own, but one load per voxel instead of the scaling and
/// `map` (HU → mu divides in f64, which made decoding a CT take 30 ms on two cores).
fn lookup(
    table: Option<&[f32; 1 << 16]>,
    decode: impl Fn([u8; 2]) -> f32 + Sync + Copy,
) -> impl Fn([u8; 2]) -> f32 + Sync + Copy {
    move |b| match table {
        Some(t) => t[usize::from(u16::from_ne_bytes(b))],
        None => decode(b),
    }
}

/// The CT voxel types (int16, uint16, float32) decoded to `f32` on every core, in the
/// file's order (i fastest). `None` for other types, which the crate decodes.
pub(super) fn decode_parallel(
    raw: &[u8],
    dtype: NiftiType,
    endianness: Endianness,
    scale: impl Fn(f32) -> f32 + Sync + Copy,
) -> Option<Vec<f32>> {
    let le = endianness == Endianness::Little;
    let count = raw.len() / dtype.size_of();
    Some(match dtype {
        NiftiType::Int16 | NiftiType::Uint16 => {
            let d = then(two_bytes(dtype == NiftiType::Int16, le), scale);
            convert(raw, lookup(table(count, d).as_deref(), d))
        }
        NiftiType::Float32 => convert(raw, then(float32(le), scale)),
        _ => return None,
    })
}

/// `raw` as values of `N` bytes each, decoded by `decode`, into a new buffer.
fn convert<const N: usize>(raw: &[u8], decode: impl Fn([u8; N]) -> f32 + Sync) -> Vec<f32> {
    let mut out = vec![0.0f32; raw.len() / N];
    out.par_chunks_mut(BLOCK)
        .zip(raw.par_chunks(BLOCK * N))
        .for_each(|(o, bytes)| decode_into(o, bytes, &decode));
    out
}

fn decode_into<const N: usize>(out: &mut [f32], bytes: &[u8], decode: &impl Fn([u8; N]) -> f32) {
    for (v, b) in out.iter_mut().zip(bytes.as_chunks::<N>().0) {
        *v = decode(*b);
    }
}

/// `len` zero words, or `None` where they cannot be allocated; their pages are first
/// touched on every core ([`touch_pages`]).
pub(super) fn zeroed_words(len: usize) -> Option<Vec<f32>> {
    let mut words = unfaulted_words(len)?;
    touch_pages(bytemuck::cast_slice_mut(&mut words));
    Some(words)
}

/// `len` zero words, or `None` where they cannot be allocated. Zeroed by the allocator
/// (fresh pages from the system are zero already: no pass over them), unlike
/// `try_reserve` + `resize`; unlike `vec![0; len]`, a failed allocation is not an abort.
pub(super) fn unfaulted_words(len: usize) -> Option<Vec<f32>> {
    if len == 0 {
        return Some(Vec::new());
    }
    let layout = std::alloc::Layout::array::<f32>(len).ok()?;
    // SAFETY: `layout` has a non-zero size.
    let p = unsafe { std::alloc::alloc_zeroed(layout) };
    if p.is_null() {
        return None;
    }
    // SAFETY: `p` was allocated by the global allocator with the layout of `len` f32s (so
    // capacity `len`), and all of them are initialised (all-zero bits are 0.0).
    Some(unsafe { Vec::from_raw_parts(p.cast::<f32>(), len, len) })
}

/// Writes a zero into each 4 KiB page of `bytes` (which must hold zeros), on every core.
///
/// The kernel zeroes each fresh page when it is first written; this has that done here,
/// in parallel, rather than later inside a one-threaded inflate or read.
pub(super) fn touch_pages(bytes: &mut [u8]) {
    const PAGE: usize = 4096;
    bytes.par_chunks_mut(256 * PAGE).for_each(|chunk| {
        for b in chunk.iter_mut().step_by(PAGE) {
            // Volatile: the write must happen although it stores the value already there.
            // SAFETY: `b` is a valid, exclusive reference.
            unsafe { std::ptr::write_volatile(b, 0) };
        }
    });
}

/// Whether [`decode_in_place`] decodes `dtype`.
pub(super) fn decodes_in_place(dtype: NiftiType) -> bool {
    matches!(
        dtype,
        NiftiType::Int16 | NiftiType::Uint16 | NiftiType::Float32
    )
}

/// Decodes the `count` voxels stored from byte `offset` of `words`' own bytes into
/// `words[..count]` and returns the buffer cut to `count` values (its capacity is kept).
///
/// `words` must hold at least `count` values and `offset + size·count` bytes, and `dtype`
/// be one of [`decodes_in_place`]'s; panics otherwise (a caller's bug, not bad input).
///
/// * 4-byte voxels move down by `offset` bytes (one `memmove`), then are decoded where
///   they lie.
/// * 2-byte voxels spread out to 4 bytes: voxels `[s, n)` are decoded, in parallel, into
///   words that no voxel still to be decoded occupies (`4s ≥ offset + 2n`), then the same
///   for `[s', s)`, … — about half of what is left each pass — and the last few (their
///   bytes overlap their own words) from a copy.
pub(super) fn decode_in_place(
    mut words: Vec<f32>,
    offset: usize,
    count: usize,
    dtype: NiftiType,
    endianness: Endianness,
    scale: impl Fn(f32) -> f32 + Sync + Copy,
) -> Vec<f32> {
    let le = endianness == Endianness::Little;
    match dtype {
        NiftiType::Int16 | NiftiType::Uint16 => {
            let d = then(two_bytes(dtype == NiftiType::Int16, le), scale);
            spread(
                &mut words,
                offset,
                count,
                lookup(table(count, d).as_deref(), d),
            );
        }
        NiftiType::Float32 => {
            let decode = then(float32(le), scale);
            let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
            bytes.copy_within(offset..offset + 4 * count, 0);
            words[..count].par_chunks_mut(BLOCK).for_each(|c| {
                for v in c {
                    *v = decode(v.to_ne_bytes());
                }
            });
        }
        other => panic!("decode_in_place does not decode {other:?}"),
    }
    words.truncate(count);
    words
}

/// The 2-byte case of [`decode_in_place`].
fn spread(
    words: &mut [f32],
    offset: usize,
    count: usize,
    decode: impl Fn([u8; 2]) -> f32 + Sync + Copy,
) {
    assert!(words.len() >= count && 4 * words.len() >= offset + 2 * count);
    let mut n = count;
    while n > 0 {
        // Words [s, n) lie past every byte of the voxels [0, n) still to be decoded.
        let s = (offset + 2 * n).div_ceil(4);
        if s >= n {
            break;
        }
        let (lo, hi) = words.split_at_mut(s);
        let raw = &bytemuck::cast_slice::<f32, u8>(lo)[offset + 2 * s..offset + 2 * n];
        hi[..n - s]
            .par_chunks_mut(BLOCK)
            .zip(raw.par_chunks(2 * BLOCK))
            .for_each(|(o, b)| decode_into(o, b, &decode));
        n = s;
    }
    let bytes: &[u8] = bytemuck::cast_slice(words);
    let head = bytes[offset..offset + 2 * n].to_vec();
    decode_into(&mut words[..n], &head, &decode);
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::convert::identity as id;

    /// In-place decoding gives decode_parallel's values bit for bit, for every type, byte
    /// order, scaling and header offset (odd ones included), from 0 voxels to many blocks.
    #[test]
    fn in_place_equals_a_separate_buffer() {
        let mut state = 99u64;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u8
        };
        for count in [0usize, 1, 3, 177, 1000, 3 * BLOCK + 17] {
            for offset in [348usize, 352, 353, 368, 1001] {
                for dtype in [NiftiType::Int16, NiftiType::Uint16, NiftiType::Float32] {
                    let size = dtype.size_of();
                    let mut raw: Vec<u8> = (0..size * count).map(|_| random()).collect();
                    if dtype == NiftiType::Float32 {
                        // Finite values (both byte orders' exponent bytes cleared a little).
                        raw.chunks_exact_mut(4).for_each(|c| {
                            c[0] &= 0x3f;
                            c[3] &= 0x3f;
                        });
                    }
                    for endianness in [Endianness::Little, Endianness::Big] {
                        for (slope, inter) in [(0.0f32, 0.0f32), (0.37, 12.5)] {
                            let want =
                                decode_parallel(&raw, dtype, endianness, scaling(slope, inter, id))
                                    .unwrap();
                            let len = count.max((offset + raw.len()).div_ceil(4));
                            let mut words = vec![f32::NAN; len];
                            let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
                            bytes[offset..offset + raw.len()].copy_from_slice(&raw);
                            let got = decode_in_place(
                                words,
                                offset,
                                count,
                                dtype,
                                endianness,
                                scaling(slope, inter, id),
                            );
                            assert_eq!(got.len(), count);
                            let (a, b): (Vec<u32>, Vec<u32>) = (
                                got.iter().map(|v| v.to_bits()).collect(),
                                want.iter().map(|v| v.to_bits()).collect(),
                            );
                            assert!(
                                a == b,
                                "{dtype:?} {endianness:?} offset {offset} count {count}"
                            );
                        }
                    }
                }
            }
        }
    }
}
