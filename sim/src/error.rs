//! Errors raised by the physics crate. Every variant names the offending quantity so a
//! user can fix the input without reading code.

use thiserror::Error;

/// Everything that can go wrong when building or rendering a scene.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SimError {
    /// The volume description is impossible (zero size, bad spacing, non-orthonormal axes…).
    #[error("invalid volume: {0}")]
    InvalidVolume(String),
    /// A voxel holds NaN or ±Inf.
    #[error("volume has a non-finite value ({value}) at voxel (i={i}, j={j}, k={k})")]
    NonFiniteVoxel {
        /// Voxel index along the first (fastest) axis.
        i: usize,
        /// Voxel index along the second axis.
        j: usize,
        /// Voxel index along the third (slowest) axis.
        k: usize,
        /// The offending value, printed as text (NaN, inf, -inf).
        value: String,
    },
    /// The projection geometry is impossible (SID < SAD, zero pixel pitch, empty detector…).
    #[error("invalid geometry: {0}")]
    InvalidGeometry(String),
    /// Projection images that cannot be reconstructed from (wrong count or size, NaN).
    #[error("invalid projections: {0}")]
    InvalidProjections(String),
    /// A physical parameter is outside the range the model or its data tables cover.
    #[error("out of range: {0}")]
    OutOfRange(String),
    /// A material name that the library does not know (the message lists the known ones).
    #[error("unknown material: {0}")]
    UnknownMaterial(String),
    /// A material definition is impossible (bad element, mass fractions or density).
    #[error("invalid material: {0}")]
    InvalidMaterial(String),
    /// An X-ray spectrum is impossible or a spectrum file is malformed.
    #[error("invalid spectrum: {0}")]
    InvalidSpectrum(String),
    /// A data table shipped with the crate failed to parse (a build or packaging fault).
    #[error("corrupt built-in data table: {0}")]
    DataTable(String),
    /// A name (of a projector, quantity, signal …) that is not one of `choices`.
    #[error("unknown {what} '{name}': use {choices}")]
    UnknownName {
        /// What was named (`projector`, `quantity`, `signal`).
        what: &'static str,
        /// The name given.
        name: String,
        /// The names there are, in words.
        choices: &'static str,
    },
}

impl SimError {
    /// An [`SimError::UnknownName`].
    pub fn unknown_name(what: &'static str, name: &str, choices: &'static str) -> Self {
        Self::UnknownName {
            what,
            name: name.to_string(),
            choices,
        }
    }
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, SimError>;
