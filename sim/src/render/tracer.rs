//! Which exact Siddon tracer renders a view: a named setting of the scene (`[projector]
//! tracer`, `--tracer`), so that a reader can tell from the scene (and its sidecar) which
//! path an image took. Every tracer integrates the same exact path lengths; they differ only
//! in how many rays they take at once, so images agree to rounding (docs/projector.md,
//! "Which tracer").

use crate::error::{Result, SimError};
use serde::{Deserialize, Serialize};

/// An exact Siddon tracer ([`crate::render::Renderer::with_tracer`]). The trilinear
/// projector has one marcher and ignores it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Tracer {
    /// The measured best for this CPU and view: ray packets where the CPU has a SIMD kernel,
    /// ray sheets for detector rows that form one (AP and PA views of an axial CT), and
    /// column sheets over a k-fastest copy of the volume for jobs of 8 views or more of a
    /// circular orbit; the scalar tracer for the rays left over.
    #[default]
    Auto,
    /// One ray at a time (`trace/siddon.rs`): the reference the others are tested against.
    Scalar,
    /// Packets of rays through whole voxel layers with the CPU's SIMD kernel
    /// (`trace/packet/`; the scalar tracer without SIMD or for rays a packet cannot take).
    Packets,
    /// [`Tracer::Packets`], and a detector row whose rays form a ray sheet along the grid's
    /// fastest axis traced as one (`trace/sheet/`).
    Sheets,
    /// [`Tracer::Sheets`], and the detector columns of views whose rows are not sheets
    /// traced as sheets along k over a k-fastest copy of the volume made for any number of
    /// views (`render/columns.rs`; as much memory again as the volume).
    Columns,
}

impl Tracer {
    /// The tracer names scenes, the command line and Python accept.
    pub const NAMES: &'static str = "auto, scalar, packets, sheets or columns";

    /// The tracer called `name` (any case). The one name table of the scene files, the
    /// CLI and the Python module.
    pub fn from_name(name: &str) -> Result<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(Self::Auto),
            "scalar" => Ok(Self::Scalar),
            "packets" => Ok(Self::Packets),
            "sheets" => Ok(Self::Sheets),
            "columns" => Ok(Self::Columns),
            _ => Err(SimError::unknown_name("tracer", name, Self::NAMES)),
        }
    }

    /// The tracer's name, as [`Tracer::from_name`] reads it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Scalar => "scalar",
            Self::Packets => "packets",
            Self::Sheets => "sheets",
            Self::Columns => "columns",
        }
    }

    /// Whether this is [`Tracer::Auto`] (for skipping it in sidecars, where absent means
    /// auto).
    pub fn is_auto(&self) -> bool {
        *self == Self::Auto
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_choices() {
        for t in [
            Tracer::Auto,
            Tracer::Scalar,
            Tracer::Packets,
            Tracer::Sheets,
            Tracer::Columns,
        ] {
            assert_eq!(Tracer::from_name(t.name()).unwrap(), t);
            assert_eq!(Tracer::from_name(&t.name().to_uppercase()).unwrap(), t);
        }
        let e = Tracer::from_name("fast").unwrap_err().to_string();
        assert!(e.contains("fast") && e.contains(Tracer::NAMES), "{e}");
    }
}
