//! Errors of the model crate.

use thiserror::Error;

/// Everything that can go wrong in training, reconstruction and evaluation.
#[derive(Debug, Error)]
pub enum ModelError {
    /// Inputs that do not fit together or are out of range.
    #[error("{0}")]
    Invalid(String),
    /// Geometry or volume problems reported by sim.
    #[error(transparent)]
    Sim(#[from] tomograf_sim::SimError),
    /// Reading a data set's files failed (the error names the file).
    #[error(transparent)]
    Dataset(#[from] tomograf_datasets::DatasetError),
    /// Reading a data set, checkpoint or config failed.
    #[error("{path}: {message}")]
    File {
        /// The file concerned.
        path: String,
        /// What went wrong.
        message: String,
    },
}

/// Result with [`ModelError`].
pub type Result<T> = std::result::Result<T, ModelError>;

impl ModelError {
    /// A file error.
    pub fn file(path: &std::path::Path, message: impl std::fmt::Display) -> Self {
        Self::File {
            path: path.display().to_string(),
            message: message.to_string(),
        }
    }
}

/// `Err(Invalid)` with a formatted message unless the condition holds.
macro_rules! ensure {
    ($cond:expr, $($arg:tt)+) => {
        if !($cond) {
            return Err($crate::error::ModelError::Invalid(format!($($arg)+)));
        }
    };
}
pub(crate) use ensure;
