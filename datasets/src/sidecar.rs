//! The projection sidecar: `<prefix>.json` beside the images of `tomograf project`,
//! defined once, in both directions (written by `project`, read by
//! `reconstruct-classical`).
//!
//! It records how every view was made, so that any image can be reproduced or
//! reconstructed: the volume's grid and source, the projector, what a pixel holds, the
//! set-up and every view's pose and detector (DICOM LPS world frame, mm), the acquisition
//! (spectrum, detector, scatter and the noise seeds) for real detector physics, and the
//! files written. Keys are written in alphabetical order at every level (through a JSON
//! value), as the sidecar has always had them.

use crate::atomic::write_json;
use crate::error::{DatasetError, Result};
use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use tomograf_sim::accel::SkipOptions;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::{Geometry, Pose, Projector, Quantity, Tracer, View, Volume};

/// How pixel (row r, col c) and the rays are laid out; written into every sidecar.
pub const CONVENTIONS: &str = "World frame DICOM LPS, mm. Pixel (row r, col c) centre = \
    detector_origin + c*u + r*v; pixel (0,0) is top-left in the beam's-eye view; images \
    row-major. Cone rays run from source to pixel centre; parallel rays are whole lines along \
    direction.";

/// What `<prefix>.json` holds.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sidecar {
    /// The version of tomograf that wrote it.
    pub tomograf_version: String,
    /// [`CONVENTIONS`].
    pub conventions: String,
    /// The projected volume: its source and grid.
    pub volume: VolumeRecord,
    /// How rays were integrated.
    pub projector: Projector,
    /// The exact Siddon tracer asked for (`[projector] tracer`); absent: `auto`.
    #[serde(default, skip_serializing_if = "Tracer::is_auto")]
    pub tracer: Tracer,
    /// Empty-space skipping (`null`: off).
    pub skipping: Option<SkipOptions>,
    /// What a pixel holds.
    pub quantity: PixelQuantity,
    /// The set-up the views were made from (`null` for explicit views only).
    pub geometry: Option<Geometry>,
    /// Every view, in image order.
    pub views: Vec<ViewRecord>,
    /// Real detector physics: the acquisition's settings (as [`acquisition_record`] writes
    /// them), absent for ideal DRRs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acquisition: Option<serde_json::Value>,
    /// Pixels clipped at zero signal before the log (real detector physics only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clipped_pixels: Option<u64>,
    /// Pixels at the detector's saturation (real detector physics only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saturated_pixels: Option<u64>,
    /// The detector channel of these images, when the detector has several.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub channel: Option<usize>,
    /// The files written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub files: Option<FilesRecord>,
}

/// What a pixel holds: an ideal quantity, or a detector signal described in words (the
/// acquisition says which).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PixelQuantity {
    /// Line integrals, transmission or intensity of an ideal DRR.
    Ideal(Quantity),
    /// A detector signal (e.g. "detector signal (see acquisition)").
    Described(String),
}

/// The projected volume: where it came from and its grid.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct VolumeRecord {
    /// The input file or folder (`null` for the built-in phantom).
    pub path: Option<PathBuf>,
    /// The built-in phantom's name (`null` for a file).
    pub phantom: Option<String>,
    /// The units of the input's values (e.g. `HU`).
    pub units: String,
    /// How values became attenuation coefficients.
    pub attenuation: Attenuation,
    /// Voxels along i, j, k.
    pub dims: [usize; 3],
    /// Voxel size along i, j, k, mm.
    pub spacing_mm: [f64; 3],
    /// Centre of voxel (0, 0, 0), LPS, mm.
    pub origin_mm: [f64; 3],
    /// Direction cosines: columns are the i, j, k axes in LPS.
    pub direction: [[f64; 3]; 3],
}

/// One view: its index, the pose it was made from (`null` for an explicit view) and the
/// view itself (source, detector origin, u, v, size; flattened into the record).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ViewRecord {
    /// Position in the image stack.
    pub index: usize,
    /// Gantry pose (θ, φ in degrees), if the view came from one.
    pub pose: Option<Pose>,
    /// Source and detector of the view.
    #[serde(flatten)]
    pub view: View,
}

/// The files a `project` run wrote.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FilesRecord {
    /// Formats (`exr`, `tiff`, `npy`, `png`).
    pub formats: Vec<String>,
    /// The per-view file pattern.
    pub per_view: String,
    /// The NPY stack, if written.
    pub npy_stack: Option<String>,
    /// The PNG previews' grey window.
    pub png_window: String,
}

impl Sidecar {
    /// The sidecar of an ideal DRR written by this version of tomograf; the real-physics
    /// fields (`acquisition`, pixel counts, `channel`) and `files` start empty.
    pub fn new(
        volume: VolumeRecord,
        projector: Projector,
        skipping: Option<SkipOptions>,
        quantity: Quantity,
        geometry: Option<Geometry>,
        views: Vec<ViewRecord>,
    ) -> Self {
        Self {
            tomograf_version: env!("CARGO_PKG_VERSION").into(),
            conventions: CONVENTIONS.into(),
            volume,
            projector,
            tracer: Tracer::Auto,
            skipping,
            quantity: PixelQuantity::Ideal(quantity),
            geometry,
            views,
            acquisition: None,
            clipped_pixels: None,
            saturated_pixels: None,
            channel: None,
            files: None,
        }
    }

    /// Writes the sidecar atomically, keys in alphabetical order.
    pub fn write(&self, path: &Path) -> Result<()> {
        let value = serde_json::to_value(self)
            .map_err(|e| DatasetError::corrupt(path, format!("the sidecar: {e}")))?;
        write_json(path, &value)
    }

    /// Reads and parses a sidecar; errors name the file.
    pub fn read(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, "reading", e))?;
        serde_json::from_slice(&bytes).map_err(|e| DatasetError::corrupt(path, e.to_string()))
    }

    /// The projected volume's grid (values zero), checked like any volume.
    pub fn grid(&self) -> std::result::Result<Volume, tomograf_sim::SimError> {
        let g = &self.volume;
        let count = tomograf_sim::volume::checked_voxel_count(g.dims)?;
        Volume::new(
            g.dims,
            DVec3::from(g.spacing_mm),
            DVec3::from(g.origin_mm),
            DMat3::from_cols_array_2d(&g.direction),
            vec![0.0; count],
        )
    }
}

/// The sidecar's `acquisition` for real detector physics: the settings (any serialisable
/// acquisition), the noise `seed`, and how each view's noise seed follows from it.
pub fn acquisition_record(
    settings: &impl Serialize,
    seed: u64,
) -> serde_json::Result<serde_json::Value> {
    let mut a = serde_json::to_value(settings)?;
    if let serde_json::Value::Object(map) = &mut a {
        map.insert("seed".into(), seed.into());
        map.insert(
            "frame_seeds".into(),
            "view i: SplitMix64(seed ^ (i+1)·0x9E3779B97F4A7C15); calibration: frame 0".into(),
        );
    }
    Ok(a)
}
