//! The TOML scene file of `tomograf project`, and how command-line flags override it.
//!
//! Every field is optional; anything left out takes the default documented on the flag
//! of the same name (`tomograf project --help`). docs/scene.md is the reference of every
//! section and key (tested against these types by `src/doc_examples.rs`). Example:
//!
//! ```toml
//! [volume]
//! path = "ct.nii.gz"          # or .nrrd, or a DICOM series folder; omit for the built-in phantom
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
//! tracer = "auto"             # exact Siddon: auto, scalar, packets, sheets or columns
//! empty_below_per_mm = 1e-4   # skip |mu| ≤ this (noisy air); default: no skipping
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
//! Real detector physics (polychromatic beam, tissues, detector; `docs/physics.md`):
//!
//! ```toml
//! [acquisition]
//! preset = "kv-flat-panel-120kvp"   # or "cbct-100kvp"; "ideal-drr" = the DRR above
//! seed = 7                          # detector noise
//! signal = "log-line-integral"      # or "raw", "flat-field"
//!
//! [spectrum]                        # replaces the preset's beam
//! kvp = 120                         # or energy_kev = 60 (photons_per_mas_mm2 = 1e6), or
//!                                   # file = "spectrum.csv" (fluence_unit = "per-mm2")
//! filtration = [{ material = "al", thickness_mm = 2.5 }, { material = "cu", thickness_mm = 0.1 }]
//! bins = 20                         # rebin (default: 1 keV)
//! mas = 2.0
//!
//! [scatter]                         # docs/scatter.md; default model = "none"
//! model = "monte-carlo"             # or "estimate" (photons, grid, smoothing)
//! photons = 100000
//! grid = 16                         # scoring points per side (not the anti-scatter grid)
//! images = ["primary", "compton", "rayleigh", "multiple", "scatter", "total"]
//!                                   # expected-signal images written beside the output
//!
//! [scatter.anti_scatter_grid]       # a focused linear grid in front of the detector
//! ratio = 10.0
//! lines_per_cm = 40.0
//! strip_um = 36.0                   # lead strip thickness (default 36)
//! interspace = "aluminium"          # or "air" (default aluminium)
//!
//! [dose]                            # absorbed dose, Gy: {prefix}_dose.nii.gz and .json
//! photons = 1000000                 # Monte Carlo histories per view (default 1e6)
//!
//! [materials]
//! model = "schneider"               # or "five-tissue", "water"
//! calibration_kev = 70.0
//! blend_hu = 40.0                   # optional partial volume: ±20 HU about each bound
//!                                   # is the 50/50 mixture of the neighbours (default 0)
//!
//! [detector]                        # besides rows/cols/pitch_mm/offset_mm
//! model = "kv-flat-panel"           # or "perfect-absorber" (alias "ideal"), "noiseless-csi",
//!                                   # "cbct", "photon-counting"
//! # thresholds_kev = [20.0, 50.0]   # with model = "photon-counting" only
//! ```
//!
//! Mesh objects (closed triangle meshes, or exact analytic solids; inside one its material
//! replaces the voxels'), one table each; later meshes win where meshes overlap:
//!
//! ```toml
//! [[mesh]]
//! name = "screw"
//! path = "screw.stl"          # .obj, .ply or .stl; or kind = "box" | "sphere" |
//!                             # "ellipsoid" | "cylinder" (exact analytic solids) |
//!                             # "pacemaker" | "table" (triangle meshes generated in code)
//! material = "titanium"       # a material of the library (tomograf_sim::material::by_name)
//! density_g_cm3 = 4.5         # optional; default: the material's nominal density
//! mu_per_mm = 0.08            # ideal DRR only, optional: mu inside (mm⁻¹); default: the
//!                             # material's mu at the HU → mu energy (energy_kev)
//! translation_mm = [0.0, 0.0, 0.0]
//! rotation_deg = [0.0, 0.0, 0.0]   # about x, then y, then z
//! scale = [1.0, 1.0, 1.0]          # file units → mm
//! # matrix = [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]   # instead of the three above
//! repair_epsilon_mm = 1e-6    # optional: merge close vertices, fix orientation
//! # kind parameters: size_mm = [x, y, z] (box, table: [width, thickness, length]),
//! # radius_mm, radii_mm = [a, b, c] (ellipsoid), height_mm (cylinder, along local z),
//! # exact = false or resolution (sphere/ellipsoid subdivisions, cylinder sides): the solid
//! # as a triangle mesh instead
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
use tomograf_physics::acquisition::SpectrumSpec;
use tomograf_physics::detector::DetectorModel;
use tomograf_sim::tissue::TissueBin;

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
    #[serde(default)]
    pub acquisition: AcquisitionSection,
    pub spectrum: Option<SpectrumSpec>,
    pub materials: Option<MaterialsSection>,
    #[serde(default)]
    pub mesh: Vec<MeshEntry>,
    /// Scattered radiation (docs/scatter.md); absent = none.
    pub scatter: Option<crate::scatter::ScatterSection>,
    /// Absorbed dose (docs/scatter.md, "Dose"); absent = not computed.
    pub dose: Option<crate::dose::DoseSection>,
}

/// Which physics between the traced paths and the image (see `crate::physics`).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AcquisitionSection {
    /// "ideal-drr" (the monochromatic projector; the default), or a preset of
    /// `tomograf_physics::acquisition::PRESETS`.
    pub preset: Option<String>,
    /// Seed of the detector noise (view i uses a seed derived from it and i).
    pub seed: Option<u64>,
    /// raw, flat-field or log-line-integral.
    pub signal: Option<String>,
}

/// HU → materials: a named model, or explicit HU intervals.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialsSection {
    /// schneider, five-tissue or water.
    pub model: Option<String>,
    /// Effective energy of the CT scan, keV (where densities are calibrated).
    pub calibration_kev: Option<f64>,
    /// Explicit HU intervals (replace the model's).
    pub bins: Option<Vec<TissueBin>>,
    /// Partial volume: CT numbers within ±blend_hu/2 of each inner bound are the 50/50
    /// mass mixture of the two neighbouring materials (HU; default 0 = none).
    pub blend_hu: Option<f64>,
}

/// One `[[mesh]]` table.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshEntry {
    pub name: Option<String>,
    pub path: Option<PathBuf>,
    pub kind: Option<String>,
    pub material: Option<String>,
    pub density_g_cm3: Option<f64>,
    pub mu_per_mm: Option<f64>,
    pub translation_mm: Option<[f64; 3]>,
    pub rotation_deg: Option<[f64; 3]>,
    pub scale: Option<[f64; 3]>,
    pub matrix: Option<[[f64; 4]; 4]>,
    pub repair_epsilon_mm: Option<f64>,
    pub size_mm: Option<[f64; 3]>,
    pub radius_mm: Option<f64>,
    pub radii_mm: Option<[f64; 3]>,
    pub height_mm: Option<f64>,
    pub resolution: Option<u32>,
    pub exact: Option<bool>,
}

/// Which quantity a mesh must carry: a linear attenuation (the ideal DRR) or a material
/// and density (real detector physics).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MeshPhysics {
    /// The monochromatic DRR; `energy_kev` is the HU → mu energy when the volume is in HU
    /// (`None` for a volume in mu: then each mesh needs `mu_per_mm`).
    Monochromatic { energy_kev: Option<f64> },
    /// Real detector physics: the mesh's material and density enter the spectrum sums.
    Polychromatic,
}

impl MeshEntry {
    /// The mesh(es) this entry describes, checked and placed (a pacemaker gives three).
    pub fn build(
        &self,
        index: usize,
        physics: MeshPhysics,
    ) -> Result<Vec<tomograf_sim::mesh::MeshObject>> {
        use tomograf_sim::mesh::{MeshObject, TriMesh, io, shapes, topology};
        let name = self.name.clone().unwrap_or_else(|| format!("mesh{index}"));
        let what = || format!("[[mesh]] {name}");
        if self.path.is_some() == self.kind.is_some() {
            anyhow::bail!("{}: give exactly one of path and kind", what());
        }
        let placement = self.placement().with_context(what)?;
        let (material, density, mu) = self.resolve(physics).with_context(what)?;
        let with_density = |object: MeshObject| match density {
            Some(d) => object.with_density(d).with_context(what),
            None => Ok(object),
        };
        if let Some(primitive) = self.primitive().with_context(what)? {
            let object = MeshObject::analytic(&name, primitive, &placement, &material, mu)
                .with_context(what)?;
            return Ok(vec![with_density(object)?]);
        }
        let parts: Vec<(String, TriMesh)> = match (&self.path, self.kind.as_deref()) {
            (Some(p), None) => vec![(name.clone(), io::load(p).with_context(what)?)],
            (None, Some(kind)) => {
                let n = self.resolution;
                let r = self.radius_mm.unwrap_or(10.0);
                let h = self.height_mm.unwrap_or(2.0 * r);
                match kind {
                    "box" => vec![(
                        name.clone(),
                        shapes::cuboid(glam::DVec3::from(self.size_mm.unwrap_or([20.0; 3])))?,
                    )],
                    "sphere" => vec![(name.clone(), shapes::icosphere(r, n.unwrap_or(4))?)],
                    "ellipsoid" => {
                        let radii = glam::DVec3::from(self.ellipsoid_radii());
                        let mut m = shapes::icosphere(1.0, n.unwrap_or(4))?;
                        m.vertices.iter_mut().for_each(|v| *v *= radii);
                        vec![(name.clone(), m)]
                    }
                    "cylinder" => {
                        vec![(name.clone(), shapes::cylinder(r, h, n.unwrap_or(64))?)]
                    }
                    "pacemaker" => shapes::pacemaker(n.unwrap_or(32))?
                        .into_iter()
                        .map(|(part, m)| (format!("{name}/{part}"), m))
                        .collect(),
                    "table" => {
                        let [w, t, l] = self.size_mm.unwrap_or([450.0, 40.0, 1900.0]);
                        vec![(name.clone(), shapes::table_top(w, l, t)?)]
                    }
                    other => anyhow::bail!(
                        "{}: unknown kind '{other}'; expected box, sphere, ellipsoid, cylinder, \
                         pacemaker or table",
                        what()
                    ),
                }
            }
            _ => anyhow::bail!("{}: give exactly one of path and kind", what()),
        };
        // A file may cross itself; the built-in tessellations do not (by construction, and an
        // invertible placement keeps it so), and on their fans — a 2²⁰-sided cylinder's caps —
        // the check cost over a minute for nothing.
        let check_self_intersection = self.path.is_some();
        parts
            .into_iter()
            .map(|(part, mesh)| {
                let mesh = match self.repair_epsilon_mm {
                    Some(eps) => topology::repair(&mesh, eps).with_context(what)?.0,
                    None => mesh,
                };
                with_density(
                    MeshObject::new(
                        &part,
                        &mesh,
                        &placement,
                        &material,
                        mu,
                        check_self_intersection,
                    )
                    .with_context(what)?,
                )
            })
            .collect()
    }

    /// Where the entry's object sits: `matrix`, or translation/rotation/scale.
    fn placement(&self) -> Result<tomograf_sim::mesh::Placement> {
        use tomograf_sim::mesh::Placement;
        Ok(match self.matrix {
            Some(matrix) => {
                if self.translation_mm.is_some()
                    || self.rotation_deg.is_some()
                    || self.scale.is_some()
                {
                    anyhow::bail!("give matrix or translation/rotation/scale, not both");
                }
                Placement::Matrix { matrix }
            }
            None => Placement::Pose {
                rotation_deg: self.rotation_deg.unwrap_or([0.0; 3]),
                scale: self.scale.unwrap_or([1.0; 3]),
                translation_mm: self.translation_mm.unwrap_or([0.0; 3]),
            },
        })
    }

    /// An ellipsoid's semi-axes (mm): `radii_mm`, else `radius_mm` on every axis.
    fn ellipsoid_radii(&self) -> [f64; 3] {
        self.radii_mm.unwrap_or([self.radius_mm.unwrap_or(10.0); 3])
    }

    /// The analytic solid this entry is (`None`: a triangle mesh). Box, sphere, ellipsoid
    /// and cylinder are exact solids unless `exact = false` or a `resolution` (facets)
    /// asks for a triangle mesh.
    fn primitive(&self) -> Result<Option<tomograf_sim::mesh::Solid>> {
        use tomograf_sim::mesh::Solid;
        let kind = self.kind.as_deref();
        let solid = matches!(kind, Some("box" | "sphere" | "ellipsoid" | "cylinder"));
        if !solid {
            if self.exact == Some(true) {
                anyhow::bail!(
                    "exact = true is for kind = \"box\", \"sphere\", \"ellipsoid\" or \
                     \"cylinder\" (analytic solids); a file or a generated device is triangles"
                );
            }
            if self.radii_mm.is_some() {
                anyhow::bail!("radii_mm is for kind = \"ellipsoid\"");
            }
            return Ok(None);
        }
        let exact = self.exact.unwrap_or(self.resolution.is_none());
        if !exact {
            return Ok(None);
        }
        if let Some(n) = self.resolution {
            anyhow::bail!(
                "resolution = {n} tessellates the {} into triangles, but exact = true asks for \
                 the analytic solid; drop one of them",
                kind.unwrap_or_default()
            );
        }
        if self.repair_epsilon_mm.is_some() {
            anyhow::bail!("repair_epsilon_mm is for triangle meshes, not an exact solid");
        }
        if self.radii_mm.is_some() && kind != Some("ellipsoid") {
            anyhow::bail!("radii_mm is for kind = \"ellipsoid\"");
        }
        let r = self.radius_mm.unwrap_or(10.0);
        Ok(Some(match kind {
            Some("box") => Solid::Box {
                size: glam::DVec3::from(self.size_mm.unwrap_or([20.0; 3])),
            },
            Some("sphere") => Solid::Ellipsoid {
                radii: glam::DVec3::splat(r),
            },
            Some("ellipsoid") => Solid::Ellipsoid {
                radii: glam::DVec3::from(self.ellipsoid_radii()),
            },
            _ => Solid::circular_cylinder(r, self.height_mm.unwrap_or(2.0 * r)),
        }))
    }

    /// The material name, density (g/cm³, when known) and mu (mm⁻¹, monochromatic only).
    fn resolve(&self, physics: MeshPhysics) -> Result<(String, Option<f64>, Option<f64>)> {
        use tomograf_sim::material::by_name;
        if let Some(d) = self.density_g_cm3
            && !(d.is_finite() && d > 0.0)
        {
            anyhow::bail!("density_g_cm3 = {d}; it must be finite and > 0");
        }
        match physics {
            MeshPhysics::Polychromatic => {
                if self.mu_per_mm.is_some() {
                    anyhow::bail!(
                        "mu_per_mm is for the ideal DRR; with real detector physics a mesh is \
                         its material and density (give material, and density_g_cm3 if not \
                         the nominal one)"
                    );
                }
                let Some(name) = &self.material else {
                    anyhow::bail!(
                        "real detector physics needs the mesh's material (e.g. material = \
                         \"titanium\")"
                    );
                };
                let m = by_name(name)?;
                let rho = self.density_g_cm3.unwrap_or(m.density());
                Ok((name.clone(), Some(rho), None))
            }
            MeshPhysics::Monochromatic { energy_kev } => {
                let name = self.material.clone().unwrap_or_else(|| "unknown".into());
                if let Some(mu) = self.mu_per_mm {
                    return Ok((name, self.density_g_cm3, Some(mu)));
                }
                let (Some(material), Some(e)) = (&self.material, energy_kev) else {
                    anyhow::bail!(
                        "give mu_per_mm (linear attenuation inside, mm⁻¹), or a material with \
                         an HU volume (its mu is then taken at the volume's energy_kev)"
                    );
                };
                let m = by_name(material)?;
                let rho = self.density_g_cm3.unwrap_or(m.density());
                Ok((name, Some(rho), Some(m.mu_per_mm(e, rho)?)))
            }
        }
    }
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
    /// Detector physics preset: ideal, kv-flat-panel, cbct or photon-counting.
    pub model: Option<String>,
    /// Energy thresholds (keV) of the photon-counting model.
    pub thresholds_kev: Option<Vec<f64>>,
    /// The detector physics in full (replaces `model`).
    pub response: Option<DetectorModel>,
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
    /// The exact Siddon tracer (`--tracer`): auto (default), scalar, packets, sheets or
    /// columns (docs/projector.md, "Which tracer").
    pub tracer: Option<String>,
    /// Empty-space skipping threshold, mm⁻¹ (`--empty-below`).
    pub empty_below_per_mm: Option<f32>,
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
    /// Reads a scene file. Relative volume, spectrum and mesh paths are resolved against
    /// the file's folder.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read scene file {}", path.display()))?;
        Self::from_toml(&text, path.parent())
            .with_context(|| format!("scene file {} is not valid", path.display()))
    }

    /// Parses a scene from TOML text; relative paths in it are resolved against `dir`
    /// when given (as [`Scene::load`] does with the file's folder).
    pub fn from_toml(text: &str, dir: Option<&Path>) -> Result<Self> {
        let mut scene: Scene = toml::from_str(text)?;
        if let Some(dir) = dir {
            for p in [
                scene.volume.path.as_mut(),
                scene.spectrum.as_mut().and_then(|s| s.file.as_mut()),
            ]
            .into_iter()
            .flatten()
            {
                if p.is_relative() {
                    *p = dir.join(&*p);
                }
            }
            for m in &mut scene.mesh {
                if let Some(p) = &m.path
                    && p.is_relative()
                {
                    m.path = Some(dir.join(p));
                }
            }
        }
        Ok(scene)
    }
}
