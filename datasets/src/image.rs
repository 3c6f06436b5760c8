//! Projection images → files (OpenEXR, TIFF, NPY, PNG), all written atomically; and NPY
//! stacks read back ([`read_npy`]).
//!
//! # Orientation
//! A [`Projection`] is `rows × cols`, row-major, row 0 at the top. Every format here keeps
//! that layout: image width = `cols`, height = `rows`, the first stored scanline is row 0
//! and is displayed at the top (EXR increasing line order, TIFF's default top-left
//! orientation, PNG's first row, NPY C order with shape `[rows, cols]` when the caller
//! passes it).

use crate::atomic::write_atomic;
use crate::error::{DatasetError, Result};
use std::io::{self, Write};
use std::path::Path;
use tomograf_sim::Projection;

/// Checks that `image` is non-empty, consistent and small enough for 32-bit formats.
fn check_image(path: &Path, image: &Projection) -> Result<(u32, u32)> {
    let (rows, cols) = (image.rows, image.cols);
    if rows == 0 || cols == 0 {
        return Err(DatasetError::invalid_output(
            path,
            format!("the image is empty ({rows} rows × {cols} columns)"),
        ));
    }
    if rows.checked_mul(cols) != Some(image.data.len()) {
        return Err(DatasetError::invalid_output(
            path,
            format!(
                "{rows} rows × {cols} columns need {} values but the image holds {}",
                rows.saturating_mul(cols),
                image.data.len()
            ),
        ));
    }
    match (u32::try_from(cols), u32::try_from(rows)) {
        (Ok(w), Ok(h)) if w <= i32::MAX as u32 && h <= i32::MAX as u32 => Ok((w, h)),
        _ => Err(DatasetError::invalid_output(
            path,
            format!("the image is too large ({rows} rows × {cols} columns)"),
        )),
    }
}

/// Writes `image` as an OpenEXR file with one 32-bit float channel named `"Y"`,
/// lossless ZIP compression (16 scanlines per block), data window
/// `(0, 0)–(cols−1, rows−1)`, scanlines in increasing order (row 0 first, at the top).
/// Values are stored as they are (NaN and ±Inf included).
pub fn write_exr(path: &Path, image: &Projection) -> Result<()> {
    use exr::prelude::{Blocks, Encoding, Image, LineOrder, SpecificChannels, Vec2, WritableImage};
    check_image(path, image)?;
    let (cols, data) = (image.cols, &image.data);
    let channels = SpecificChannels::build()
        .with_channel("Y")
        .with_pixel_fn(|pos: Vec2<usize>| (data[pos.y() * cols + pos.x()],));
    let encoding = Encoding {
        compression: exr::compression::Compression::ZIP16,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let exr_image = Image::from_encoded_channels((image.cols, image.rows), encoding, channels);
    write_atomic(path, |w| {
        exr_image
            .write()
            .to_buffered(w)
            .map_err(|e| io::Error::other(format!("OpenEXR encoder: {e}")))
    })
}

/// Writes `image` as a baseline TIFF: one 32-bit IEEE float grey sample per pixel
/// (`SampleFormat` = IEEEFP, `BitsPerSample` = 32, `PhotometricInterpretation` =
/// BlackIsZero), uncompressed, width = `cols`, height = `rows`, row 0 first (top).
pub fn write_tiff(path: &Path, image: &Projection) -> Result<()> {
    use tiff::encoder::{TiffEncoder, colortype::Gray32Float};
    let (width, height) = check_image(path, image)?;
    let tiff_err = |e: tiff::TiffError| io::Error::other(format!("TIFF encoder: {e}"));
    write_atomic(path, |w| {
        let mut encoder = TiffEncoder::new(w).map_err(tiff_err)?;
        encoder
            .write_image::<Gray32Float>(width, height, &image.data)
            .map_err(tiff_err)
    })
}

/// Writes `data` as a NumPy `.npy` array of dtype `'<f4'` (little-endian float32), C
/// order (last index fastest), with the given `shape` — `[rows, cols]` for a
/// [`Projection`], `[nz, ny, nx]` for a volume stored `i` fastest.
///
/// The product of `shape` must equal `data.len()` (an empty shape is a scalar: one value).
pub fn write_npy(path: &Path, data: &[f32], shape: &[usize]) -> Result<()> {
    use npyz::WriterBuilder;
    let count = shape.iter().try_fold(1usize, |acc, &n| acc.checked_mul(n));
    if count != Some(data.len()) {
        return Err(DatasetError::invalid_output(
            path,
            format!(
                "shape {shape:?} holds {} values but {} were given",
                count.map_or_else(|| "too many".to_string(), |c| c.to_string()),
                data.len()
            ),
        ));
    }
    let shape: Vec<u64> = shape.iter().map(|&n| n as u64).collect();
    write_atomic(path, |w| {
        let type_str: npyz::TypeStr = "<f4"
            .parse()
            .map_err(|e| io::Error::other(format!("NPY dtype: {e}")))?;
        let mut writer = npyz::WriteOptions::<f32>::new()
            .dtype(npyz::DType::Plain(type_str))
            .shape(&shape)
            .writer(w)
            .begin_nd()?;
        writer.extend(data.iter().copied())?;
        writer.finish()
    })
}

/// The shape a NumPy `.npy` file's header declares, reading the header only (for sizing a
/// job before its data are loaded; [`read_npy`] checks the values).
pub fn npy_shape(path: &Path) -> Result<Vec<u64>> {
    let file = std::fs::File::open(path).map_err(|e| DatasetError::io(path, "reading", e))?;
    let npy = npyz::NpyFile::new(std::io::BufReader::new(file))
        .map_err(|e| DatasetError::corrupt(path, format!("not a .npy array: {e}")))?;
    Ok(npy.shape().to_vec())
}

/// Reads a NumPy `.npy` array of float32 (either byte order) in C order: `(values,
/// shape)`. The shape must hold exactly the stored values; errors name the file.
pub fn read_npy(path: &Path) -> Result<(Vec<f32>, Vec<usize>)> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, "reading", e))?;
    let bad = |e: &dyn std::fmt::Display| {
        DatasetError::corrupt(path, format!("not a float32 .npy array: {e}"))
    };
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| bad(&e))?;
    if npy.order() != npyz::Order::C {
        return Err(DatasetError::unsupported(
            path,
            "Fortran-ordered .npy arrays are not read",
        ));
    }
    let shape: Vec<usize> = npy
        .shape()
        .iter()
        .map(|&n| usize::try_from(n).map_err(|e| bad(&e)))
        .collect::<Result<_>>()?;
    let count = shape.iter().try_fold(1usize, |acc, &n| acc.checked_mul(n));
    let values: Vec<f32> = npy.into_vec().map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            DatasetError::truncated(
                path,
                format!(
                    "its header promises shape {shape:?} ({} float32 values) but the file ends \
                     before them",
                    count.map_or("too many".to_string(), |c| c.to_string())
                ),
            )
        } else {
            bad(&e)
        }
    })?;
    if count != Some(values.len()) {
        return Err(DatasetError::truncated(
            path,
            format!("shape {shape:?} but {} values", values.len()),
        ));
    }
    Ok((values, shape))
}

/// Writes `image` as an 8-bit greyscale PNG for viewing.
///
/// `window = (lo, hi)` maps values linearly: `lo` (and below) → 0, `hi` (and above) →
/// 255, rounded to nearest; NaN → 0. `lo` and `hi` must be finite with `lo < hi`.
/// Width = `cols`, height = `rows`, row 0 at the top.
pub fn write_png(path: &Path, image: &Projection, window: (f32, f32)) -> Result<()> {
    let (width, height) = check_image(path, image)?;
    let (lo, hi) = window;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(DatasetError::invalid_output(
            path,
            format!("PNG display window [{lo}, {hi}] is invalid: it needs finite lo < hi"),
        ));
    }
    let pixels = to_grey8(&image.data, lo, hi);
    write_atomic(path, |w| {
        let png_err = |e: png::EncodingError| io::Error::other(format!("PNG encoder: {e}"));
        let mut encoder = png::Encoder::new(&mut *w, width, height);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(png_err)?;
        writer.write_image_data(&pixels).map_err(png_err)?;
        writer.finish().map_err(png_err)?;
        w.flush()
    })
}

/// Maps values to 0..=255 through the window `[lo, hi]` (clamped, rounded, NaN → 0).
fn to_grey8(data: &[f32], lo: f32, hi: f32) -> Vec<u8> {
    let (lo, scale) = (f64::from(lo), 255.0 / (f64::from(hi) - f64::from(lo)));
    data.iter()
        .map(|&v| {
            let g = ((f64::from(v) - lo) * scale).round();
            // `as u8` saturates and maps NaN to 0.
            g.clamp(0.0, 255.0) as u8
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_mapping_clamps_and_rounds() {
        let v = to_grey8(&[-5.0, 0.0, 0.5, 1.0, 7.0, f32::NAN, 0.25], 0.0, 1.0);
        assert_eq!(v, vec![0, 0, 128, 255, 255, 0, 64]);
    }

    #[test]
    fn inconsistent_images_are_refused() {
        let p = Projection {
            rows: 2,
            cols: 3,
            data: vec![0.0; 5],
        };
        let e = write_tiff(Path::new("/nonexistent/x.tif"), &p).unwrap_err();
        assert!(e.to_string().contains("need 6 values"), "{e}");
        let empty = Projection {
            rows: 0,
            cols: 3,
            data: vec![],
        };
        let e = write_exr(Path::new("/nonexistent/x.exr"), &empty).unwrap_err();
        assert!(e.to_string().contains("empty"), "{e}");
    }
}
