//! Inflate speed of a `.nii.gz`: libdeflate (whole buffer, what `read_nifti` uses when the
//! size is known), flate2 with its zlib-rs backend (streaming, `read_nifti`'s fallback) and
//! miniz_oxide (flate2's default backend) on the same bytes, interleaved; and the whole
//! NIfTI read (inflate + voxel conversion) for scale. Not part of the test suite.
//!
//! `cargo run --release -p tomograf-datasets --example inflate_speed -- CT.nii.gz [repeats]`

#[path = "common/timing.rs"]
mod timing;

use std::io::Read;
use std::time::Instant;

fn main() {
    let (path, repeats): (String, usize) = timing::args("inflate_speed CT.nii.gz [repeats]", 7);
    let gz = std::fs::read(&path).expect("readable file");
    // The raw deflate stream: after the 10-byte gzip header (and the optional fields the
    // FLG byte announces), before the 8-byte trailer.
    let flg = gz[3];
    let mut at = 10;
    if flg & 4 != 0 {
        at += 2 + u16::from_le_bytes([gz[at], gz[at + 1]]) as usize;
    }
    for bit in [8u8, 16] {
        if flg & bit != 0 {
            at += gz[at..].iter().position(|&b| b == 0).expect("terminated") + 1;
        }
    }
    if flg & 2 != 0 {
        at += 2;
    }
    let raw = &gz[at..gz.len() - 8];
    let (mut a, mut b, mut c, mut d) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut size = 0;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        let mut out = Vec::new();
        flate2::read::MultiGzDecoder::new(&gz[..])
            .read_to_end(&mut out)
            .expect("inflates");
        a.push(t.elapsed().as_secs_f64());
        size = out.len();
        let t = Instant::now();
        let out2 = miniz_oxide::inflate::decompress_to_vec(raw).expect("inflates");
        b.push(t.elapsed().as_secs_f64());
        assert_eq!(out2.len(), size, "both inflate the same bytes");
        let t = Instant::now();
        let mut out3 = vec![0u8; size];
        let n = libdeflater::Decompressor::new()
            .gzip_decompress(&gz, &mut out3)
            .expect("inflates (one gzip member)");
        d.push(t.elapsed().as_secs_f64());
        assert!(n == size && out3 == out, "all inflate the same bytes");
        let t = Instant::now();
        let v = tomograf_datasets::nifti::read_nifti(std::path::Path::new(&path)).expect("reads");
        c.push(t.elapsed().as_secs_f64());
        std::hint::black_box(v);
    }
    let (a, b, c, d) = (
        timing::median(a),
        timing::median(b),
        timing::median(c),
        timing::median(d),
    );
    println!(
        "{path}: {:.1} MB compressed, {:.1} MB inflated; median of {repeats}:\n\
         libdeflate {:.0} ms ({:.0} MB/s) | flate2 (zlib-rs) ÷ libdeflate {:.2}\n\
         flate2 (zlib-rs) {:.0} ms ({:.0} MB/s) | miniz_oxide {:.0} ms ({:.0} MB/s) | ratio {:.2}\n\
         whole NIfTI read (inflate + conversion to f32): {:.0} ms",
        gz.len() as f64 / 1e6,
        size as f64 / 1e6,
        d * 1e3,
        size as f64 / 1e6 / d,
        a / d,
        a * 1e3,
        size as f64 / 1e6 / a,
        b * 1e3,
        size as f64 / 1e6 / b,
        b / a,
        c * 1e3
    );
}
