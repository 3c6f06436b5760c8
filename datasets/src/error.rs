//! Errors raised while reading or writing files. Every variant names the file and says
//! what is wrong with it, so a user can fix the input without reading code.

use std::path::{Path, PathBuf};
use thiserror::Error;
use tomograf_sim::SimError;

/// Everything that can go wrong when reading or writing a dataset file.
#[derive(Debug, Error)]
pub enum DatasetError {
    /// The operating system refused an operation (open, read, create, rename…).
    #[error("{path}: {action} failed: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What was being done, e.g. "opening", "writing".
        action: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file ends before all the data its header announces.
    #[error("{path}: file is truncated: {detail}")]
    Truncated {
        /// The file concerned.
        path: PathBuf,
        /// What was expected and what was found.
        detail: String,
    },
    /// The file is not in the expected format or its content is inconsistent.
    #[error("{path}: {reason}")]
    Corrupt {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The file is valid but uses a feature this crate does not support (4-D data,
    /// complex voxels, header/image pairs…).
    #[error("{path}: not supported: {reason}")]
    Unsupported {
        /// The file concerned.
        path: PathBuf,
        /// The unsupported feature.
        reason: String,
    },
    /// The header describes a volume with more voxels than
    /// [`tomograf_sim::volume::MAX_VOXELS`]; refused before allocating anything.
    #[error("{path}: volume too large for memory: {detail}")]
    TooLarge {
        /// The file concerned.
        path: PathBuf,
        /// The size requested and the limit.
        detail: String,
    },
    /// The file decoded, but its contents do not make a valid volume (non-finite voxel,
    /// bad spacing…).
    #[error("{path}: {source}")]
    Volume {
        /// The file concerned.
        path: PathBuf,
        /// The reason the volume was refused.
        #[source]
        source: SimError,
    },
    /// A folder of DICOM files does not make one usable series: no DICOM files, several
    /// series, slices that disagree (orientation, size, spacing), missing or duplicate
    /// slices, a tilted stack…
    #[error("{folder}: {reason}")]
    Series {
        /// The folder concerned.
        folder: PathBuf,
        /// What is wrong, naming the files involved.
        reason: String,
    },
    /// The caller asked to write something impossible (empty image, shape that does not
    /// match the data, empty display window…). Nothing was written.
    #[error("cannot write {path}: {reason}")]
    InvalidOutput {
        /// The file that was not written.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// An in-memory operation (preprocessing: cropping, resampling, padding, windowing)
    /// was given arguments it cannot honour; the message names the operation and says
    /// what is wrong.
    #[error("{0}")]
    Invalid(String),
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, DatasetError>;

impl DatasetError {
    /// An [`DatasetError::Io`] for `path`.
    pub(crate) fn io(path: &Path, action: &'static str, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_owned(),
            action,
            source,
        }
    }
    /// A [`DatasetError::Corrupt`] for `path`.
    pub(crate) fn corrupt(path: &Path, reason: impl Into<String>) -> Self {
        Self::Corrupt {
            path: path.to_owned(),
            reason: reason.into(),
        }
    }
    /// A [`DatasetError::Truncated`] for `path`.
    pub(crate) fn truncated(path: &Path, detail: impl Into<String>) -> Self {
        Self::Truncated {
            path: path.to_owned(),
            detail: detail.into(),
        }
    }
    /// A [`DatasetError::Unsupported`] for `path`.
    pub(crate) fn unsupported(path: &Path, reason: impl Into<String>) -> Self {
        Self::Unsupported {
            path: path.to_owned(),
            reason: reason.into(),
        }
    }
    /// A [`DatasetError::Series`] for `folder`.
    pub(crate) fn series(folder: &Path, reason: impl Into<String>) -> Self {
        Self::Series {
            folder: folder.to_owned(),
            reason: reason.into(),
        }
    }
    /// A [`DatasetError::InvalidOutput`] for `path`.
    pub(crate) fn invalid_output(path: &Path, reason: impl Into<String>) -> Self {
        Self::InvalidOutput {
            path: path.to_owned(),
            reason: reason.into(),
        }
    }
}

/// Refuses reading the `dims` volume of `path` when its stored samples (`stored_bytes`) and
/// their f32 copy exceed the memory available ([`tomograf_sim::memory::check`]), as
/// [`DatasetError::TooLarge`]; checked before anything is allocated.
pub(crate) fn check_read_memory(path: &Path, dims: [usize; 3], stored_bytes: u128) -> Result<()> {
    let count = dims.iter().map(|&n| n as u128).product::<u128>();
    tomograf_sim::memory::check(
        stored_bytes + 4 * count,
        &format!(
            "reading {} ({}×{}×{} voxels)",
            path.display(),
            dims[0],
            dims[1],
            dims[2]
        ),
    )
    .map_err(|e| DatasetError::TooLarge {
        path: path.to_owned(),
        detail: e.to_string(),
    })
}
