//! Unit tests of the NIfTI reader's private parts (decoding, layout, inflate paths).

use super::*;
use ndarray::{Array, IxDyn};

/// Decoding gives the crate's values, then `map`, bit for bit: every CT type, both byte
/// orders, with and without scaling and a map, for a volume decoded value by value and
/// one large enough for 2-byte voxels to be decoded through a table (`decode::TABLE_MIN`).
#[test]
fn parallel_decoding_equals_the_crates_bit_for_bit() {
    use nifti::NiftiType;
    // 3 × 5 × 20001 voxels: several of the parallel blocks, a partial last one, and a
    // table for 2-byte voxels; 3 × 5 × 7: no table.
    const { assert!(3 * 5 * 20001 >= decode::TABLE_MIN && 3 * 5 * 7 < decode::TABLE_MIN) };
    let hu_to_mu = |hu: f32| (0.0195f64 * (1.0 + f64::from(hu.max(-1000.0)) / 1000.0)) as f32;
    for dims in [[3usize, 5, 20001], [3, 5, 7]] {
        let n: usize = dims.iter().product();
        let mut state = 12345u64;
        let mut bytes = vec![0u8; n * 4];
        for b in bytes.iter_mut() {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *b = (state >> 33) as u8;
        }
        for dtype in [NiftiType::Int16, NiftiType::Uint16, NiftiType::Float32] {
            let size = dtype.size_of();
            for endianness in [Endianness::Little, Endianness::Big] {
                let mut raw = bytes[..n * size].to_vec();
                if dtype == NiftiType::Float32 {
                    // Finite values only: clear the exponent's top bit (its byte by order).
                    let top = if endianness == Endianness::Little {
                        3
                    } else {
                        0
                    };
                    for c in raw.chunks_exact_mut(4) {
                        c[top] &= 0x3f;
                    }
                }
                for (slope, inter) in [(0.0f32, 0.0f32), (1.0, -1024.0), (0.37, 12.5)] {
                    for mapped in [false, true] {
                        let map = move |x: f32| if mapped { hu_to_mu(x) } else { x };
                        let fast = decode_parallel(
                            &raw,
                            dtype,
                            endianness,
                            decode::scaling(slope, inter, map),
                        )
                        .unwrap();
                        let h = NiftiHeader {
                            dim: [
                                3,
                                dims[0] as u16,
                                dims[1] as u16,
                                dims[2] as u16,
                                1,
                                1,
                                1,
                                1,
                            ],
                            datatype: dtype as i16,
                            bitpix: (size * 8) as i16,
                            scl_slope: slope,
                            scl_inter: inter,
                            endianness,
                            ..NiftiHeader::default()
                        };
                        let array = InMemNiftiVolume::from_reader(&raw[..], &h)
                            .unwrap()
                            .into_ndarray::<f32>()
                            .unwrap();
                        let slow = i_fastest(array, dims).unwrap();
                        assert_eq!(fast.len(), slow.len());
                        for (i, (a, b)) in fast.iter().zip(&slow).enumerate() {
                            assert_eq!(
                                a.to_bits(),
                                map(*b).to_bits(),
                                "{dims:?} {dtype:?} {endianness:?} slope {slope} map {mapped}: voxel {i}"
                            );
                        }
                    }
                }
            }
        }
    }
    assert!(
        decode_parallel(
            &[0u8; 64],
            NiftiType::Float64,
            Endianness::Little,
            decode::scaling(0.0, 0.0, std::convert::identity)
        )
        .is_none()
    );
}

/// Whatever the memory order of the decoded array, voxels come out `i` fastest.
#[test]
fn i_fastest_follows_logical_indices_not_memory_order() {
    let dims = [3, 2, 4];
    let value = |i: usize, j: usize, k: usize| (100 * i + 10 * j + k) as f32;
    let want: Vec<f32> = (0..4)
        .flat_map(|k| (0..2).flat_map(move |j| (0..3).map(move |i| value(i, j, k))))
        .collect();
    let fortran = Array::from_shape_fn(IxDyn(&dims).f(), |ix| value(ix[0], ix[1], ix[2]));
    let c_order = Array::from_shape_fn(IxDyn(&dims), |ix| value(ix[0], ix[1], ix[2]));
    let four = Array::from_shape_fn(IxDyn(&[3, 2, 4, 1]), |ix| value(ix[0], ix[1], ix[2]));
    for array in [fortran, c_order, four] {
        assert_eq!(i_fastest(array, dims).unwrap(), want);
    }
    let two = Array::from_shape_fn(IxDyn(&[3, 2]).f(), |ix| value(ix[0], ix[1], 0));
    assert_eq!(i_fastest(two, [3, 2, 1]).unwrap(), want[..6]);
    let wrong = Array::zeros(IxDyn(&[3, 2, 4]));
    assert!(i_fastest(wrong, [3, 4, 2]).unwrap_err().contains("shape"));
}

/// A single-member `.nii.gz` whose header and trailer agree on its size is inflated whole
/// (libdeflate) and reads as the plain file does, extension bytes before the voxels
/// included; the size is the header's, not a guess.
#[test]
fn a_single_member_nii_gz_is_inflated_whole_and_reads_as_the_plain_file() {
    use flate2::write::GzEncoder;
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let dims = [7, 5, 3];
    let data: Vec<f32> = (0..105).map(|i| i as f32 * 3.25 - 100.0).collect();
    let v = Volume::new(
        dims,
        DVec3::new(0.7, 0.8, 2.5),
        DVec3::new(-10.0, 4.0, 2.0),
        DMat3::IDENTITY,
        data,
    )
    .unwrap();
    let plain = dir.path().join("v.nii");
    write_nifti(&plain, &v).unwrap();
    // The same file with a 16-byte extension before the voxels (vox_offset 368).
    let mut bytes = std::fs::read(&plain).unwrap();
    bytes[108..112].copy_from_slice(&368f32.to_le_bytes());
    bytes[348] = 1;
    let extension = [16i32.to_le_bytes(), 0i32.to_le_bytes(), [7; 4], [9; 4]].concat();
    bytes.splice(352..352, extension);
    std::fs::write(&plain, &bytes).unwrap();
    let mut e = GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(&bytes).unwrap();
    let gz = e.finish().unwrap();
    let packed = dir.path().join("v.nii.gz");
    std::fs::write(&packed, &gz).unwrap();

    assert_eq!(expected_size(&gz, &packed), Some((bytes.len() as u64, 105)));
    let mut reader = BufReader::new(File::open(&packed).unwrap());
    let read = inflate::read(
        &mut reader,
        Some(gz.len() as u64),
        Some(bytes.len() as u64),
        105,
        MAX_DEFLATE_RATIO,
    )
    .unwrap();
    let inflate::GzFile::Inflated(whole) = read else {
        panic!("not inflated whole")
    };
    assert_eq!(whole.bytes(), &bytes[..]);
    let from_plain = read_nifti(&plain).unwrap();
    assert_eq!(from_plain.data(), v.data());
    assert_eq!(read_nifti(&packed).unwrap(), from_plain);
}

/// Grid of the hand-made CT files below.
const CT_DIMS: [usize; 3] = [33, 17, 9];

/// Writes a float32 NIfTI of zeros on [`CT_DIMS`] to `path` and returns its 352-byte header.
fn float32_file(path: &Path) -> Vec<u8> {
    let count = CT_DIMS.iter().product::<usize>();
    let v = Volume::new(
        CT_DIMS,
        DVec3::new(0.7, 0.8, 2.5),
        DVec3::new(-10.0, 4.0, 2.0),
        DMat3::IDENTITY,
        vec![0.0; count],
    )
    .unwrap();
    write_nifti(path, &v).unwrap();
    std::fs::read(path).unwrap()[..352].to_vec()
}

/// Writes the int16 CT file of [`int16_file_bytes`] to `path` and returns its bytes.
fn int16_file(path: &Path) -> Vec<u8> {
    let bytes = int16_file_bytes(&float32_file(path));
    std::fs::write(path, &bytes).unwrap();
    bytes
}

/// The float32 `header` made int16 (datatype 4, bitpix 16) scaled by 1 and −1024 (a CT in
/// HU), with its voxels: voxel `n` stores `(37·n mod 4000) − 24`.
fn int16_file_bytes(header: &[u8]) -> Vec<u8> {
    let mut bytes = header.to_vec();
    bytes[70..72].copy_from_slice(&4i16.to_le_bytes());
    bytes[72..74].copy_from_slice(&16i16.to_le_bytes());
    bytes[112..116].copy_from_slice(&1f32.to_le_bytes());
    bytes[116..120].copy_from_slice(&(-1024f32).to_le_bytes());
    for n in 0..CT_DIMS.iter().product::<usize>() {
        bytes.extend_from_slice(&((n * 37 % 4000) as i16 - 24).to_le_bytes());
    }
    bytes
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

/// An int16 `.nii` and `.nii.gz` with scaling (the usual CT file), decoded in place, hold
/// the values written.
#[test]
fn int16_files_decoded_in_place_hold_the_values_written() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("v.nii");
    let bytes = int16_file(&plain);
    let packed = dir.path().join("v.nii.gz");
    std::fs::write(&packed, gzip(&bytes)).unwrap();

    // Both files decode in place (the plain one into the buffer its voxels are read
    // into): the values are checked against the formula that wrote them.
    let want: Vec<f32> = (0..CT_DIMS.iter().product::<usize>())
        .map(|i| f32::from((i * 37 % 4000) as i16 - 24) * 1.0 - 1024.0)
        .collect();
    let from_plain = read_nifti(&plain).unwrap();
    assert_eq!(from_plain.data(), &want[..]);
    assert_eq!(read_nifti(&packed).unwrap(), from_plain);
}

/// A `.nii.gz` that cannot be sought (a named pipe) is streamed, as it comes.
#[cfg(unix)]
#[test]
fn a_nii_gz_from_a_pipe_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("v.nii");
    let bytes = int16_file(&plain);
    let pipe = dir.path().join("pipe.nii.gz");
    let made = std::process::Command::new("mkfifo").arg(&pipe).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo failed");
    let gz = gzip(&bytes);
    let writer = {
        let pipe = pipe.clone();
        std::thread::spawn(move || std::fs::write(pipe, gz).unwrap())
    };
    let from_pipe = read_nifti(&pipe);
    writer.join().unwrap();
    assert_eq!(from_pipe.unwrap(), read_nifti(&plain).unwrap());
}

/// `read_nifti_mapped` gives `read_nifti`'s values mapped afterwards, bit for bit, on every
/// decoding path: in place (a plain int16 file, a `.nii.gz` inflated whole), streamed (a
/// `.nii.gz` of two gzip members) and through the crate (float64). A NaN voxel is still
/// refused, by the volume's check after the map.
#[test]
fn mapping_while_decoding_equals_mapping_afterwards() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("f32.nii");
    let header = float32_file(&plain);
    let count = CT_DIMS.iter().product::<usize>();
    let int16 = int16_file_bytes(&header);
    // float64 (decoded by the crate).
    let mut float64 = header.clone();
    float64[70..72].copy_from_slice(&64i16.to_le_bytes());
    float64[72..74].copy_from_slice(&64i16.to_le_bytes());
    for i in 0..count {
        float64.extend_from_slice(&(i as f64 * 0.75 - 300.0).to_le_bytes());
    }
    let (half_a, half_b) = int16.split_at(int16.len() / 2);
    let files = [
        ("i16.nii", int16.clone()),
        ("i16.nii.gz", gzip(&int16)),
        ("two-members.nii.gz", [gzip(half_a), gzip(half_b)].concat()),
        ("f64.nii", float64),
    ];
    let map = |x: f32| {
        if x.is_finite() {
            x.max(-1000.0) * 0.021 + 0.3
        } else {
            x
        }
    };
    for (name, bytes) in files {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let want: Vec<u32> = read_nifti(&path)
            .unwrap()
            .data()
            .iter()
            .map(|&x| map(x).to_bits())
            .collect();
        let got = read_nifti_mapped(&path, map).unwrap();
        let got: Vec<u32> = got.data().iter().map(|x| x.to_bits()).collect();
        assert!(got == want, "{name}");
    }
    // A float32 file with a NaN voxel: the map keeps it, and the volume's check finds it.
    let mut nan = std::fs::read(&plain).unwrap();
    let at = 352 + 4 * 700;
    nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let path = dir.path().join("nan.nii");
    std::fs::write(&path, nan).unwrap();
    let err = read_nifti_mapped(&path, map).unwrap_err().to_string();
    assert!(err.contains("NaN"), "{err}");
}
