//! Image writers read back with each format's own decoder: values and orientation (row 0
//! at the top) on a non-symmetric 3 × 5 image whose pixel (r, c) holds 10·r + c.

use std::fs::File;
use std::path::Path;
use tomograf_datasets::image::{read_npy, write_exr, write_npy, write_png, write_tiff};
use tomograf_sim::Projection;

const ROWS: usize = 3;
const COLS: usize = 5;

fn image() -> Projection {
    let data = (0..ROWS * COLS)
        .map(|n| (10 * (n / COLS) + n % COLS) as f32)
        .collect();
    Projection {
        rows: ROWS,
        cols: COLS,
        data,
    }
}

fn only_file(dir: &Path, name: &str) {
    let names: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec![name.to_string()], "temporary files left behind");
}

#[test]
fn exr_single_float_channel_y() {
    use exr::prelude::{FlatSamples, SampleType};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.exr");
    write_exr(&path, &image()).unwrap();
    only_file(dir.path(), "p.exr");

    let img = exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
    let layer = &img.layer_data;
    assert_eq!((layer.size.width(), layer.size.height()), (COLS, ROWS));
    assert!(!layer.encoding.compression.may_loose_data());
    let channels = &layer.channel_data.list;
    assert_eq!(channels.len(), 1);
    assert_eq!(channels[0].name.to_string(), "Y");
    match &channels[0].sample_data {
        FlatSamples::F32(v) => assert_eq!(v, &image().data), // first scanline = row 0
        other => panic!("expected f32 samples, got {other:?}"),
    }
    let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
    assert_eq!(
        meta.headers[0].channels.list[0].sample_type,
        SampleType::F32
    );
}

#[test]
fn tiff_float32_grey() {
    use tiff::decoder::{Decoder, DecodingResult};
    use tiff::tags::Tag;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.tif");
    write_tiff(&path, &image()).unwrap();
    only_file(dir.path(), "p.tif");

    let mut d = Decoder::new(File::open(&path).unwrap()).unwrap();
    assert_eq!(d.dimensions().unwrap(), (COLS as u32, ROWS as u32));
    assert_eq!(d.colortype().unwrap(), tiff::ColorType::Gray(32));
    assert_eq!(d.get_tag_u32(Tag::SampleFormat).unwrap(), 3); // IEEEFP
    match d.read_image().unwrap() {
        DecodingResult::F32(v) => assert_eq!(v, image().data),
        _ => panic!("expected f32 samples"),
    }
}

#[test]
fn npy_little_endian_f4_c_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.npy");
    let img = image();
    write_npy(&path, &img.data, &[ROWS, COLS]).unwrap();
    only_file(dir.path(), "p.npy");

    let bytes = std::fs::read(&path).unwrap();
    let header = String::from_utf8_lossy(&bytes[..128]);
    assert!(header.contains("'descr': '<f4'"), "{header}");
    assert!(header.contains("'fortran_order': False"), "{header}");
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    assert_eq!(npy.shape(), &[ROWS as u64, COLS as u64]);
    assert_eq!(npy.order(), npyz::Order::C);
    assert_eq!(npy.into_vec::<f32>().unwrap(), img.data);
    // Raw payload: little-endian f32, row 0 first.
    let payload = &bytes[bytes.len() - 4 * ROWS * COLS..];
    assert_eq!(&payload[4 * 6..4 * 7], &11f32.to_le_bytes()); // (r=1, c=1)

    let e = write_npy(&dir.path().join("bad.npy"), &img.data, &[4, 4]).unwrap_err();
    assert!(
        e.to_string().contains("bad.npy") && e.to_string().contains("[4, 4]"),
        "{e}"
    );
    only_file(dir.path(), "p.npy");
}

#[test]
fn png_windowed_8bit_grey() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.png");
    write_png(&path, &image(), (2.0, 22.0)).unwrap();
    only_file(dir.path(), "p.png");

    let decoder = png::Decoder::new(std::io::BufReader::new(File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (COLS as u32, ROWS as u32));
    assert_eq!(info.color_type, png::ColorType::Grayscale);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    let px = &buf[..info.buffer_size()];
    for r in 0..ROWS {
        for c in 0..COLS {
            let v = (10 * r + c) as f64;
            let want = ((v - 2.0) / 20.0 * 255.0).round().clamp(0.0, 255.0) as u8;
            assert_eq!(px[r * info.line_size + c], want, "pixel ({r}, {c})");
        }
    }
    assert_eq!(px[0], 0); // 0 < lo: clamped
    assert_eq!(px[2 * info.line_size + 4], 255); // 24 > hi: clamped
    assert_eq!(px[info.line_size + 2], 128); // 12 is mid-window: 127.5 rounds up

    for window in [(5.0, 5.0), (9.0, 1.0), (f32::NAN, 1.0)] {
        let e = write_png(&dir.path().join("w.png"), &image(), window).unwrap_err();
        assert!(
            e.to_string().contains("window") && e.to_string().contains("w.png"),
            "{e}"
        );
    }
    only_file(dir.path(), "p.png");
}

/// `read_npy` gives back what `write_npy` wrote (values and shape); a truncated file, a
/// file that is not NPY and a float64 array are refused with the file named.
#[test]
fn npy_reads_back_and_refuses_what_it_cannot_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("stack.npy");
    let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.5 - 3.0).collect();
    write_npy(&path, &data, &[2, 3, 4]).unwrap();
    assert_eq!(read_npy(&path).unwrap(), (data.clone(), vec![2, 3, 4]));

    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.npy");
    std::fs::write(&cut, &bytes[..bytes.len() - 5]).unwrap();
    let text = dir.path().join("text.npy");
    std::fs::write(&text, b"not an array").unwrap();
    let f8 = dir.path().join("f8.npy");
    use npyz::WriterBuilder;
    let mut w = npyz::WriteOptions::<f64>::new()
        .dtype(npyz::DType::Plain("<f8".parse().unwrap()))
        .shape(&[2])
        .writer(File::create(&f8).unwrap())
        .begin_nd()
        .unwrap();
    w.extend([1.0f64, 2.0]).unwrap();
    w.finish().unwrap();
    for p in [&cut, &text, &f8] {
        let msg = read_npy(p).unwrap_err().to_string();
        let name = p.file_name().unwrap().to_str().unwrap();
        assert!(msg.contains(name), "{msg}");
    }
}
