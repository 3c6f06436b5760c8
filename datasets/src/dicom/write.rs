//! Writing a volume as a DICOM CT series (one slice per file), e.g. to hand tomograf's
//! phantoms to tools that read DICOM.

use crate::atomic::write_atomic_to_path;
use crate::error::{DatasetError, Result};
use dicom_core::value::PrimitiveValue;
use dicom_core::{DataElement, Tag, VR};
use dicom_dictionary_std::{tags, uids};
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};
use std::path::Path;
use tomograf_sim::Volume;

/// Stored value = HU − this; HU is rounded to whole units (RescaleSlope 1).
const INTERCEPT: f64 = -1024.0;

fn ds(values: &[f64]) -> PrimitiveValue {
    let s: Vec<String> = values.iter().map(|v| format!("{v:.6}")).collect();
    PrimitiveValue::from(s.join("\\"))
}

/// Writes `volume` (HU) as a CT series into folder `dir` (created if missing): slice `k` is
/// `slice_NNNN.dcm`, int16 with RescaleIntercept −1024, HU rounded to whole units and
/// clamped to the int16 range, geometry from the volume's LPS placement
/// (ImagePositionPatient = centre of voxel (0, 0, k); ImageOrientationPatient = the i and j
/// directions). Explicit VR Little Endian; each file is written atomically.
/// `series_uid` must be a valid DICOM UID (digits and dots).
pub fn write_dicom_series(dir: &Path, volume: &Volume, series_uid: &str) -> Result<()> {
    if series_uid.is_empty()
        || series_uid.len() > 64
        || !series_uid.chars().all(|c| c.is_ascii_digit() || c == '.')
    {
        return Err(DatasetError::Series {
            folder: dir.to_owned(),
            reason: format!("'{series_uid}' is not a DICOM UID (digits and dots, ≤ 64 characters)"),
        });
    }
    std::fs::create_dir_all(dir).map_err(|e| DatasetError::io(dir, "creating the folder", e))?;
    let [nx, ny, nz] = volume.dims();
    if nx > u16::MAX as usize || ny > u16::MAX as usize {
        return Err(DatasetError::Series {
            folder: dir.to_owned(),
            reason: format!("slices of {nx}×{ny} pixels exceed DICOM's 65535 rows or columns"),
        });
    }
    let (d, s) = (volume.direction(), volume.spacing());
    let iop = [d.x_axis.to_array(), d.y_axis.to_array()].concat();
    for k in 0..nz {
        let position = volume.index_to_world(glam::DVec3::new(0.0, 0.0, k as f64));
        let plane = &volume.data()[k * nx * ny..(k + 1) * nx * ny];
        let words: Vec<u16> = plane
            .iter()
            .map(|&hu| {
                (f64::from(hu) - INTERCEPT)
                    .round()
                    .clamp(i16::MIN.into(), i16::MAX.into()) as i16 as u16
            })
            .collect();
        let mut obj = InMemDicomObject::new_empty();
        let mut put = |tag: Tag, vr: VR, v: PrimitiveValue| obj.put(DataElement::new(tag, vr, v));
        let sop = format!("{series_uid}.{}", k + 1);
        put(tags::SOP_CLASS_UID, VR::UI, uids::CT_IMAGE_STORAGE.into());
        put(tags::SOP_INSTANCE_UID, VR::UI, sop.as_str().into());
        put(tags::MODALITY, VR::CS, "CT".into());
        put(tags::SERIES_DESCRIPTION, VR::LO, "tomograf".into());
        put(tags::SERIES_INSTANCE_UID, VR::UI, series_uid.into());
        put(tags::INSTANCE_NUMBER, VR::IS, (k + 1).to_string().into());
        put(
            tags::IMAGE_POSITION_PATIENT,
            VR::DS,
            ds(&position.to_array()),
        );
        put(tags::IMAGE_ORIENTATION_PATIENT, VR::DS, ds(&iop));
        put(tags::SAMPLES_PER_PIXEL, VR::US, 1u16.into());
        put(
            tags::PHOTOMETRIC_INTERPRETATION,
            VR::CS,
            "MONOCHROME2".into(),
        );
        put(tags::ROWS, VR::US, (ny as u16).into());
        put(tags::COLUMNS, VR::US, (nx as u16).into());
        put(tags::PIXEL_SPACING, VR::DS, ds(&[s.y, s.x]));
        put(tags::SLICE_THICKNESS, VR::DS, ds(&[s.z]));
        put(tags::BITS_ALLOCATED, VR::US, 16u16.into());
        put(tags::BITS_STORED, VR::US, 16u16.into());
        put(tags::HIGH_BIT, VR::US, 15u16.into());
        put(tags::PIXEL_REPRESENTATION, VR::US, 1u16.into());
        put(tags::RESCALE_INTERCEPT, VR::DS, ds(&[INTERCEPT]));
        put(tags::RESCALE_SLOPE, VR::DS, "1".into());
        put(tags::PIXEL_DATA, VR::OW, PrimitiveValue::U16(words.into()));
        let file = obj
            .with_meta(
                FileMetaTableBuilder::new()
                    .transfer_syntax(uids::EXPLICIT_VR_LITTLE_ENDIAN)
                    .media_storage_sop_class_uid(uids::CT_IMAGE_STORAGE)
                    .media_storage_sop_instance_uid(sop.as_str()),
            )
            .map_err(|e| DatasetError::Series {
                folder: dir.to_owned(),
                reason: format!("cannot build the DICOM meta header: {e}"),
            })?;
        let path = dir.join(format!("slice_{k:04}.dcm"));
        write_atomic_to_path(&path, ".dcm", |tmp| {
            file.write_to_file(tmp).map_err(|e| DatasetError::Series {
                folder: dir.to_owned(),
                reason: format!("writing {}: {e}", tmp.display()),
            })
        })?;
    }
    Ok(())
}
