//! The TOML scene file of `tomograf project`, and how command-line flags override it.
//!
//! Every field is optional; anything left out takes the default documented on the flag
//! of the same name (`tomograf project --help`). Example:
//!
//! ```toml
//! [volume]
//! path = "ct.nii.gz"          # or a DICOM series folder; omit for the built-in phantom
//! units = "hu"                # "hu" or "mu" (mm⁻¹)
//! energy_kev = 60.0           # effective energy for HU → mu
//!
//! [geometry]
//! beam = "cone"               # "cone" or "parallel"
//! sad_mm = 1000.0
//! sid_mm = 1500.0
//! isocentre_mm = [0.0, 0.0, 0.0]   # default: the volume's centre
//!
//! [detector]
//! rows = 256
//! cols = 256
//! pitch_mm = [1.5, 1.5]       # [column, row]; default: fit the volume on the panel
//! offset_mm = [0.0, 0.0]      # [along columns, along rows]
//!
//! [views]
//! poses = ["ap", "lateral", "30,10"]   # named or "θ,φ" in degrees
//! arc = "0:5:72"                       # START:STEP:COUNT, added after poses
//!
//! [projector]
//! kind = "siddon"             # or "trilinear"
//! step_voxels = 0.5           # trilinear only
//!
//! [output]
//! dir = "out"
//! prefix = "drr"
//! formats = ["exr", "tiff", "npy", "png"]
//! quantity = "line-integral"  # or "transmission", "intensity"
//! i0 = 1.0                    # intensity only
//! window = [0.0, 8.0]         # PNG grey window; default: each image's min..max
//! ```
//!
//! Views may also be given in the general form, one table each:
//!
//! ```toml
//! [[views.explicit]]
//! source_mm = [0.0, -1000.0, 0.0]       # or direction = [...] for a parallel beam
//! detector_origin_mm = [-191.25, 500.0, 191.25]
//! u_mm = [1.5, 0.0, 0.0]
//! v_mm = [0.0, 0.0, -1.5]
//! rows = 256
//! cols = 256
//! ```

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A scene file: every section optional.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    #[serde(default)]
    pub volume: VolumeSection,
    #[serde(default)]
    pub geometry: GeometrySection,
    #[serde(default)]
    pub detector: DetectorSection,
    #[serde(default)]
    pub views: ViewsSection,
    #[serde(default)]
    pub projector: ProjectorSection,
    #[serde(default)]
    pub output: OutputSection,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VolumeSection {
    pub path: Option<PathBuf>,
    pub allow_non_ct: Option<bool>,
    pub units: Option<String>,
    pub energy_kev: Option<f64>,
    pub phantom_dims: Option<[usize; 3]>,
    pub phantom_spacing_mm: Option<[f64; 3]>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometrySection {
    pub beam: Option<String>,
    pub sad_mm: Option<f64>,
    pub sid_mm: Option<f64>,
    pub isocentre_mm: Option<[f64; 3]>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorSection {
    pub rows: Option<usize>,
    pub cols: Option<usize>,
    pub pitch_mm: Option<[f64; 2]>,
    pub offset_mm: Option<[f64; 2]>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewsSection {
    pub poses: Option<Vec<String>>,
    pub arc: Option<String>,
    #[serde(default)]
    pub explicit: Vec<ExplicitView>,
}

/// A view in the general form (world LPS mm).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExplicitView {
    pub source_mm: Option<[f64; 3]>,
    pub direction: Option<[f64; 3]>,
    pub detector_origin_mm: [f64; 3],
    pub u_mm: [f64; 3],
    pub v_mm: [f64; 3],
    pub rows: usize,
    pub cols: usize,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectorSection {
    pub kind: Option<String>,
    pub step_voxels: Option<f64>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    pub dir: Option<PathBuf>,
    pub prefix: Option<String>,
    pub formats: Option<Vec<String>>,
    pub quantity: Option<String>,
    pub i0: Option<f64>,
    pub window: Option<[f32; 2]>,
}

impl Scene {
    /// Reads a scene file. Relative volume paths are resolved against the file's folder.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read scene file {}", path.display()))?;
        let mut scene: Scene = toml::from_str(&text)
            .with_context(|| format!("scene file {} is not valid", path.display()))?;
        if let (Some(p), Some(dir)) = (&scene.volume.path, path.parent())
            && p.is_relative()
        {
            scene.volume.path = Some(dir.join(p));
        }
        Ok(scene)
    }
}
