//! # tomograf-datasets — file formats for tomograf
//!
//! * [`nifti`]: CT volumes from/to NIfTI-1 (`.nii`, `.nii.gz`) through the `nifti` crate,
//!   converted between NIfTI's RAS frame and tomograf's LPS world frame (mm).
//! * [`dicom`]: CT series (a folder of single-frame DICOM slices, uncompressed) to
//!   [`tomograf_sim::Volume`]; DICOM's patient frame is LPS already. [`dicom::scan_dicom_tree`]
//!   lists the series of a patient/study/series folder tree.
//! * [`image`]: projection images to OpenEXR, TIFF (32-bit float), NPY (`<f4`) and 8-bit
//!   PNG (windowed, for viewing). Images are `rows × cols`, row 0 at the top.
//! * [`item`]: the data-set item (`item.json`, `views.json`, `projections.npy`, `ct.nii.gz`)
//!   and `manifest.jsonl`, written by `tomograf dataset` and read by the model.
//! * [`frame`]: every CT brought into one patient frame (LPS, `i` left, `j` posterior, `k`
//!   superior) before it is cropped; [`body`]: the body alone (couch, padding and stray
//!   voxels set to air) and its tissue fractions; [`population`]: their range over a data
//!   set, to name an input far from a model's training population.
//! * [`sidecar`]: the projection sidecar (`<prefix>.json`) of `tomograf project`, read back
//!   by `reconstruct-classical`.
//! * [`atomic`]: every file is written atomically (through [`atomic::write_atomic`], or
//!   its path-based variant for the NIfTI writer), so a failed or interrupted write never
//!   leaves a half-written file behind.
//!
//! Errors ([`DatasetError`]) always name the file and say what is wrong with it; bad
//! input never panics.

#![warn(missing_docs)]

pub mod anatomy;
pub mod atomic;
pub mod augment;
pub mod body;
pub mod dicom;
pub mod error;
pub mod frame;
pub mod image;
pub mod item;
pub mod nifti;
pub mod nrrd;
pub mod population;
pub mod preprocess;
pub mod scan_range;
pub mod sidecar;

pub use error::{DatasetError, Result};
