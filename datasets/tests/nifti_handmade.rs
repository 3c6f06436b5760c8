//! Independent checks of the NIfTI reader: files are assembled byte by byte here, following
//! the NIfTI-1/NIfTI-2 specifications (field offsets written out below), without using any
//! NIfTI writer. Expected world positions are computed by hand: LPS = RAS with x, y negated.

use glam::DVec3;
use std::io::Write;
use std::path::{Path, PathBuf};
use tomograf_datasets::nifti::read_nifti;

/// The NIfTI-1 header fields these tests set (everything else is zero).
#[derive(Clone)]
struct Spec {
    dim: [i16; 8],
    datatype: i16,
    bitpix: i16,
    pixdim: [f32; 8],
    vox_offset: f32,
    scl_slope: f32,
    scl_inter: f32,
    qform_code: i16,
    sform_code: i16,
    quatern: [f32; 3],
    qoffset: [f32; 3],
    srow: [[f32; 4]; 3],
    magic: [u8; 4],
}

impl Spec {
    fn new(dim: [i16; 3], datatype: i16, bitpix: i16) -> Self {
        Spec {
            dim: [3, dim[0], dim[1], dim[2], 1, 1, 1, 1],
            datatype,
            bitpix,
            pixdim: [1.0; 8],
            vox_offset: 352.0,
            scl_slope: 0.0,
            scl_inter: 0.0,
            qform_code: 0,
            sform_code: 0,
            quatern: [0.0; 3],
            qoffset: [0.0; 3],
            srow: [[0.0; 4]; 3],
            magic: *b"n+1\0",
        }
    }

    /// 348-byte header + 4-byte extension flag, then `data` (already in file byte order).
    fn bytes(&self, big_endian: bool, data: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8; 352];
        let mut put = |off: usize, v: &[u8]| b[off..off + v.len()].copy_from_slice(v);
        macro_rules! e {
            ($v:expr) => {
                if big_endian {
                    $v.to_be_bytes()
                } else {
                    $v.to_le_bytes()
                }
            };
        }
        put(0, &e!(348i32)); // sizeof_hdr
        for (i, d) in self.dim.iter().enumerate() {
            put(40 + 2 * i, &e!(*d)); // dim[8]
        }
        put(70, &e!(self.datatype));
        put(72, &e!(self.bitpix));
        for (i, p) in self.pixdim.iter().enumerate() {
            put(76 + 4 * i, &e!(*p)); // pixdim[8]
        }
        put(108, &e!(self.vox_offset));
        put(112, &e!(self.scl_slope));
        put(116, &e!(self.scl_inter));
        put(252, &e!(self.qform_code));
        put(254, &e!(self.sform_code));
        for (i, q) in self.quatern.iter().chain(&self.qoffset).enumerate() {
            put(256 + 4 * i, &e!(*q)); // quatern_b,c,d, qoffset_x,y,z
        }
        for (r, row) in self.srow.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                put(280 + 16 * r + 4 * c, &e!(*v)); // srow_x, srow_y, srow_z
            }
        }
        put(344, &self.magic);
        b.extend_from_slice(data);
        b
    }
}

fn le_i16(v: &[i16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn save(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).abs().max_element() <= tol
}

#[test]
fn sform_int16_scaled_world_positions_and_values() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Spec::new([3, 4, 5], 4, 16);
    s.sform_code = 1;
    s.srow = [
        [-0.7, 0.0, 0.0, 10.0],
        [0.0, 0.8, 0.0, -20.0],
        [0.0, 0.0, 2.5, 30.0],
    ];
    s.scl_slope = 2.0;
    s.scl_inter = -1000.0;
    s.qform_code = 1; // present but must be ignored: the sform wins
    s.quatern = [0.3, 0.1, 0.2];
    let raw: Vec<i16> = (0..60).map(|n| n * 37 - 900).collect();
    let path = save(dir.path(), "sform.nii", &s.bytes(false, &le_i16(&raw)));
    let v = read_nifti(&path).unwrap();
    assert_eq!(v.dims(), [3, 4, 5]);
    for (i, j, k) in [
        (0, 0, 0),
        (2, 0, 0),
        (0, 3, 0),
        (0, 0, 4),
        (2, 3, 4),
        (1, 2, 3),
    ] {
        let (fi, fj, fk) = (i as f64, j as f64, k as f64);
        // RAS = (10 - 0.7 i, -20 + 0.8 j, 30 + 2.5 k); LPS negates x and y.
        let want = DVec3::new(-(10.0 - 0.7 * fi), -(-20.0 + 0.8 * fj), 30.0 + 2.5 * fk);
        let got = v.index_to_world(DVec3::new(fi, fj, fk));
        assert!(
            close(got, want, 1e-5),
            "voxel ({i},{j},{k}): {got} vs {want}"
        );
        let stored = raw[i + 3 * (j + 4 * k)] as f32;
        assert_eq!(v.get(i, j, k), stored * 2.0 - 1000.0);
    }
    assert!(close(v.spacing(), DVec3::new(0.7, 0.8, 2.5), 1e-6));
    assert!(close(v.origin(), DVec3::new(-10.0, 20.0, 30.0), 1e-6));
}

/// Checks world positions of a qform file: 90° about z, `pixdim` (0.5, 0.75, 2), offset
/// (10, 20, 30). R maps i → +y, j → −x, so RAS = (10 − 0.75 j, 20 + 0.5 i, 30 ± 2 k).
fn check_qform(qfac: f32) {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Spec::new([2, 3, 4], 2, 8);
    s.qform_code = 1;
    s.sform_code = 0;
    s.srow = [[9.0, 9.0, 9.0, 9.0]; 3]; // garbage, must be ignored with sform_code 0
    s.quatern = [0.0, 0.0, std::f32::consts::FRAC_1_SQRT_2];
    s.qoffset = [10.0, 20.0, 30.0];
    s.pixdim = [qfac, 0.5, 0.75, 2.0, 1.0, 1.0, 1.0, 1.0];
    let raw: Vec<u8> = (0..24).map(|n| n * 10).collect();
    let path = save(dir.path(), "qform.nii", &s.bytes(false, &raw));
    let v = read_nifti(&path).unwrap();
    for (i, j, k) in [(0, 0, 0), (1, 0, 0), (0, 2, 0), (0, 0, 3), (1, 2, 3)] {
        let (fi, fj, fk) = (i as f64, j as f64, k as f64);
        let ras = DVec3::new(
            10.0 - 0.75 * fj,
            20.0 + 0.5 * fi,
            30.0 + 2.0 * fk * qfac as f64,
        );
        let want = ras * DVec3::new(-1.0, -1.0, 1.0);
        let got = v.index_to_world(DVec3::new(fi, fj, fk));
        assert!(
            close(got, want, 1e-6),
            "qfac {qfac} ({i},{j},{k}): {got} vs {want}"
        );
        assert_eq!(v.get(i, j, k), raw[i + 2 * (j + 3 * k)] as f32); // slope 0: unscaled
    }
    assert!(close(v.spacing(), DVec3::new(0.5, 0.75, 2.0), 1e-6));
}

#[test]
fn qform_rotation_quaternion() {
    check_qform(1.0);
}

#[test]
fn qform_with_negative_qfac_flips_the_third_axis() {
    check_qform(-1.0);
}

#[test]
fn no_transform_uses_pixdim_and_zero_origin() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Spec::new([2, 2, 2], 512, 16);
    s.pixdim = [1.0, 0.5, 0.75, 2.0, 1.0, 1.0, 1.0, 1.0];
    let raw: Vec<u8> = (0..8u16)
        .flat_map(|n| (52000 + n * 1000).to_le_bytes())
        .collect();
    let path = save(dir.path(), "plain.nii", &s.bytes(false, &raw));
    let v = read_nifti(&path).unwrap();
    let got = v.index_to_world(DVec3::new(1.0, 1.0, 1.0));
    assert!(close(got, DVec3::new(-0.5, -0.75, 2.0), 1e-12), "{got}");
    assert_eq!(v.origin(), DVec3::ZERO);
    assert_eq!(v.get(1, 1, 1), 59000.0); // uint16 above i16::MAX
}

#[test]
fn big_endian_float32_and_gzip() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Spec::new([2, 2, 1], 16, 32);
    s.sform_code = 2;
    s.srow = [
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, 2.0],
        [0.0, 0.0, 1.0, 3.0],
    ];
    let vals = [1.5f32, -2.25, 3e6, -0.0];
    let raw: Vec<u8> = vals.iter().flat_map(|x| x.to_be_bytes()).collect();
    let bytes = s.bytes(true, &raw);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&bytes).unwrap();
    let plain = read_nifti(&save(dir.path(), "be.nii", &bytes)).unwrap();
    let packed = read_nifti(&save(dir.path(), "be.nii.gz", &gz.finish().unwrap())).unwrap();
    assert_eq!(plain, packed);
    assert_eq!(plain.data(), &vals);
    assert_eq!(plain.origin(), DVec3::new(-1.0, -2.0, 3.0));
}

/// A valid NIfTI-2 file: the `nifti` crate reads NIfTI-1 only, so it must be refused with
/// a clear "not supported" error (plain, gzip-compressed and big-endian alike).
#[test]
fn nifti2_is_refused_as_unsupported() {
    // NIfTI-2: 540-byte header, magic at 4, datatype 12, bitpix 14, dim i64[8] at 16,
    // pixdim f64[8] at 104, vox_offset i64 at 168, scl_slope/inter f64 at 176/184,
    // qform/sform i32 at 344/348, srow_x/y/z f64[4] at 400/432/464.
    let mut b = vec![0u8; 560];
    let mut put = |off: usize, v: &[u8]| b[off..off + v.len()].copy_from_slice(v);
    put(0, &540i32.to_le_bytes());
    put(4, b"n+2\0\r\n\x1a\n");
    put(12, &64i16.to_le_bytes());
    put(14, &64i16.to_le_bytes());
    for (i, d) in [3i64, 2, 1, 1, 1, 1, 1, 1].iter().enumerate() {
        put(16 + 8 * i, &d.to_le_bytes());
    }
    put(168, &560i64.to_le_bytes());
    put(176, &0.5f64.to_le_bytes());
    put(184, &10.0f64.to_le_bytes());
    put(348, &1i32.to_le_bytes());
    let srow = [
        [0.0, 0.0, 3.0, 5.0],
        [2.0, 0.0, 0.0, 6.0],
        [0.0, 1.5, 0.0, 7.0],
    ];
    for (r, row) in srow.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            put(400 + 32 * r + 8 * c, &f64::to_le_bytes(*v));
        }
    }
    for v in [4.0f64, -8.0] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    let unsupported = |msg: String| {
        assert!(
            msg.contains("not supported") && msg.contains("NIfTI-2"),
            "{msg}"
        );
    };
    unsupported(read_err("v2.nii", &b));
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&b).unwrap();
    unsupported(read_err("v2.nii.gz", &gz.finish().unwrap()));
    b[..4].copy_from_slice(&540i32.to_be_bytes());
    unsupported(read_err("v2be.nii", &b));
}

/// Voxel order with fewer and more than three axes (`dim[0]` = 2 and 4 with a single
/// volume), an extension gap before the data (`vox_offset` > 352) and int32 voxels.
#[test]
fn two_and_four_axes_keep_i_fastest_order() {
    let dir = tempfile::tempdir().unwrap();
    let raw: Vec<i32> = (0..12).map(|n| n * n - 40).collect();
    let le: Vec<u8> = raw.iter().flat_map(|x| x.to_le_bytes()).collect();
    for (name, dim, shape) in [
        ("two.nii", [2, 4, 3, 0, 0, 0, 0, 0], [4, 3, 1]),
        ("four.nii", [4, 2, 3, 2, 1, 0, 0, 0], [2, 3, 2]),
    ] {
        let mut s = Spec::new([1, 1, 1], 8, 32);
        s.dim = dim;
        s.vox_offset = 368.0;
        let mut bytes = s.bytes(false, &[]);
        bytes[348] = 1; // extension flag; 16 bytes of extension follow
        bytes.extend_from_slice(&16i32.to_le_bytes());
        bytes.extend_from_slice(&[0u8; 12]);
        bytes.extend_from_slice(&le);
        let v = read_nifti(&save(dir.path(), name, &bytes)).unwrap();
        assert_eq!(v.dims(), shape, "{name}");
        for k in 0..shape[2] {
            for j in 0..shape[1] {
                for i in 0..shape[0] {
                    let n = i + shape[0] * (j + shape[1] * k);
                    assert_eq!(v.get(i, j, k), raw[n] as f32, "{name} ({i},{j},{k})");
                }
            }
        }
    }
}

/// Compression is recognised from the content (a gzip file named `.nii` reads), and a
/// multi-member gzip stream (as written by parallel compressors) is read to its end.
#[test]
fn gzip_by_content_and_multi_member() {
    let dir = tempfile::tempdir().unwrap();
    let s = Spec::new([2, 2, 2], 2, 8);
    let bytes = s.bytes(false, &[1, 2, 3, 4, 5, 6, 7, 8]);
    let member = |part: &[u8]| {
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        gz.write_all(part).unwrap();
        gz.finish().unwrap()
    };
    let single = member(&bytes);
    let v = read_nifti(&save(dir.path(), "packed_but_named.nii", &single)).unwrap();
    assert_eq!(v.data(), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
    let mut multi = member(&bytes[..200]);
    multi.extend(member(&bytes[200..355]));
    multi.extend(member(&bytes[355..]));
    let w = read_nifti(&save(dir.path(), "multi.nii.gz", &multi)).unwrap();
    assert_eq!(v, w);
}

fn read_err(name: &str, bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = save(dir.path(), name, bytes);
    let msg = read_nifti(&path).unwrap_err().to_string();
    assert!(msg.contains(name), "error does not name the file: {msg}");
    msg
}

#[test]
fn sheared_affine_is_refused() {
    let mut s = Spec::new([2, 2, 2], 2, 8);
    s.sform_code = 1;
    s.srow = [
        [1.0, 0.2, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    let msg = read_err("shear.nii", &s.bytes(false, &[0; 8]));
    assert!(
        msg.contains("sheared") && msg.contains("not orthogonal"),
        "{msg}"
    );
}

#[test]
fn four_d_with_two_volumes_is_refused() {
    let mut s = Spec::new([2, 2, 2], 2, 8);
    s.dim = [4, 2, 2, 2, 2, 1, 1, 1];
    let msg = read_err("fourd.nii", &s.bytes(false, &[0; 16]));
    assert!(
        msg.contains("not supported") && msg.contains("4-D"),
        "{msg}"
    );
    // A 4-D file holding a single volume is fine.
    s.dim = [4, 2, 2, 2, 1, 1, 1, 1];
    let dir = tempfile::tempdir().unwrap();
    assert!(read_nifti(&save(dir.path(), "one.nii", &s.bytes(false, &[0; 8]))).is_ok());
}

#[test]
fn bad_dimensions_are_refused_before_reading_data() {
    let mut s = Spec::new([2, 0, 2], 2, 8);
    let msg = read_err("zero.nii", &s.bytes(false, &[]));
    assert!(msg.contains("dim[2] = 0"), "{msg}");
    s.dim = [3, -4, 2, 2, 1, 1, 1, 1];
    assert!(read_err("neg.nii", &s.bytes(false, &[])).contains("dim[1] = -4"));
    s.dim = [3, 30000, 30000, 30000, 1, 1, 1, 1];
    let msg = read_err("huge.nii", &s.bytes(false, &[]));
    assert!(msg.contains("volume too large for memory"), "{msg}");
    s.dim = [9, 2, 2, 2, 1, 1, 1, 1];
    assert!(read_err("dim0.nii", &s.bytes(false, &[])).contains("dim[0] = 9"));
}

#[test]
fn unsupported_type_bad_magic_and_nan_are_clear() {
    let s = Spec::new([1, 1, 1], 32, 64);
    assert!(read_err("cplx.nii", &s.bytes(false, &[0; 8])).contains("complex"));
    let mut s = Spec::new([1, 1, 1], 16, 32);
    s.magic = *b"ni1\0";
    assert!(read_err("pair.nii", &s.bytes(false, &[0; 4])).contains(".hdr/.img"));
    s.magic = *b"n+1\0";
    let msg = read_err("nan.nii", &s.bytes(false, &f32::NAN.to_le_bytes()));
    assert!(msg.contains("non-finite"), "{msg}");
}

#[test]
fn truncated_garbage_and_empty_files() {
    let s = Spec::new([4, 4, 4], 4, 16);
    let full = s.bytes(false, &le_i16(&[7; 64]));
    let msg = read_err("short.nii", &full[..full.len() - 10]);
    assert!(msg.contains("truncated"), "{msg}");
    let msg = read_err("short_header.nii", &full[..200]);
    assert!(msg.contains("truncated") && msg.contains("348"), "{msg}");

    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&full).unwrap();
    let packed = gz.finish().unwrap();
    let msg = read_err("short.nii.gz", &packed[..packed.len() / 2]);
    assert!(msg.contains("truncated"), "{msg}");
    // Only the gzip trailer (CRC-32, length) missing: still truncated.
    let msg = read_err("trailer.nii.gz", &packed[..packed.len() - 3]);
    assert!(msg.contains("truncated"), "{msg}");
    // A flipped bit in the CRC is caught.
    let mut flipped = packed.clone();
    let n = flipped.len();
    flipped[n - 6] ^= 0x10;
    let msg = read_err("crc.nii.gz", &flipped);
    assert!(msg.contains("corrupt gzip data"), "{msg}");

    // Deterministic pseudo-random bytes (xorshift).
    let mut x = 0x2545_f491_4f6c_dd1du64;
    let garbage: Vec<u8> = (0..4096)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 24) as u8
        })
        .collect();
    let msg = read_err("garbage.nii", &garbage);
    assert!(msg.contains("not a NIfTI file"), "{msg}");
    let mut bad_gz = vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3];
    bad_gz.extend_from_slice(&garbage);
    let msg = read_err("garbage.nii.gz", &bad_gz);
    assert!(msg.contains("corrupt gzip data"), "{msg}");
    assert!(read_err("empty.nii", &[]).contains("empty"));

    let missing = Path::new("/definitely/not/here.nii");
    let msg = read_nifti(missing).unwrap_err().to_string();
    assert!(
        msg.contains("/definitely/not/here.nii") && msg.contains("opening"),
        "{msg}"
    );
}

/// A `.nii.gz` whose header asks for more voxel bytes than its compressed size can hold
/// (deflate expands at most 1032:1) is refused as truncated before anything that size is
/// allocated (found by fuzzing: a 844-byte file asked for 3.5 GB).
#[test]
fn gzip_too_small_for_its_header_is_refused_before_allocation() {
    // 2000 × 2000 × 400 int16: 3.2 GB of voxels, behind a header of a few hundred bytes.
    let s = Spec::new([2000, 2000, 400], 4, 16);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&s.bytes(false, &[0u8; 64])).unwrap();
    let msg = read_err("huge.nii.gz", &gz.finish().unwrap());
    assert!(
        msg.contains("truncated") && msg.contains("deflate expands at most 1032:1"),
        "{msg}"
    );
}
