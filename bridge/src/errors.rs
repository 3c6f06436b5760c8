//! Rust errors → Python exceptions, with the Rust message unchanged.
//!
//! * [`SimError`] (impossible volume, geometry or parameter) → `ValueError`.
//! * [`DatasetError::Io`] → `OSError` (`FileNotFoundError` when the file is missing,
//!   `PermissionError` when access is refused); every other dataset error (corrupt,
//!   truncated or unsupported file, inconsistent DICOM series…) → `ValueError`.

use pyo3::PyErr;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError, PyValueError};
use std::io::ErrorKind;
use tomograf_datasets::DatasetError;
use tomograf_sim::SimError;

/// A physics-crate error as a Python `ValueError`.
pub fn sim(e: SimError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A file error as `OSError` (I/O) or `ValueError` (content).
pub fn dataset(e: DatasetError) -> PyErr {
    let msg = e.to_string();
    match &e {
        DatasetError::Io { source, .. } => match source.kind() {
            ErrorKind::NotFound => PyFileNotFoundError::new_err(msg),
            ErrorKind::PermissionDenied => PyPermissionError::new_err(msg),
            _ => PyOSError::new_err(msg),
        },
        _ => PyValueError::new_err(msg),
    }
}

/// A `ValueError` with `msg`.
pub fn value(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}
