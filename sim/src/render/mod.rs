//! Rendering a view: one ray per pixel, traced in parallel (rayon), then turned into the
//! requested quantity.
//!
//! Each pixel is computed independently from the same inputs, so images are bit-identical
//! whatever the number of threads.

mod columns;
mod image;
mod mass_thickness;
mod meshes;
mod projector;
mod quantity;
mod sheets;
mod sums;
mod tracer;

pub use columns::ColumnCopy;
pub use image::Projection;
pub use mass_thickness::MassThickness;
pub use projector::{MIN_TRILINEAR_STEP, Projector};
pub use quantity::Quantity;
pub use sums::{LineIntegrals, MassThicknesses, Sums};
pub use tracer::Tracer;

use crate::accel::{EmptySpace, SkipOptions};
use crate::error::{Result, SimError};
use crate::geometry::View;
use crate::grid_box::GridBox;
use crate::mesh::MeshScene;
use crate::occupancy::RowExtents;
use crate::ray::{GridRay, Ray};
use crate::trace::{LineIntegral, MaterialPaths, packet, siddon, trilinear};
use crate::volume::Volume;
use columns::KFastest;

/// From how many views of one volume [`Renderer::for_views`] traces detector columns as
/// ray sheets.
pub const COLUMN_SHEET_VIEWS: usize = 8;
use rayon::prelude::*;
use std::marker::PhantomData;
use std::sync::Arc;

/// Renders line integrals of an attenuation volume (mm⁻¹; `Renderer<LineIntegrals>`, made
/// by [`Renderer::new`]), or per-material mass thicknesses of a [`Composition`](crate::composition::Composition)
/// (`Renderer<MassThicknesses>`, made by [`Renderer::for_composition`]): what is summed
/// along a ray is the type parameter `S` ([`Sums`]), so each renderer offers only the
/// images it can make.
#[derive(Debug, Clone)]
pub struct Renderer<'a, S: Sums = LineIntegrals> {
    /// mu (mm⁻¹), or a packed composition ([`MassThicknesses`]).
    mu: &'a Volume,
    /// Number of materials of a composition; 0 for an attenuation volume.
    materials: usize,
    projector: Projector,
    /// The exact Siddon tracer asked for ([`Renderer::with_tracer`]).
    tracer: Tracer,
    packet_threshold: f64,
    /// Whether exact Siddon traces detector rows that form a [`crate::trace::sheet::Sheet`] as one.
    sheets: bool,
    /// The volume stored k-fastest, for tracing detector columns as sheets
    /// ([`Renderer::with_column_sheets`]); `None`: columns are not traced as sheets.
    columns: Option<Arc<KFastest>>,
    /// Where rays are clipped: for Siddon the box of non-zero mu (air adds exactly
    /// nothing), for the trilinear field the whole grid (it is non-zero half a voxel
    /// beyond). `None`: nothing to integrate.
    bounds: Option<GridBox>,
    /// Where each row of voxels along i is non-zero (exact Siddon), for the ray sheets to
    /// skip zeros ([`crate::trace::sheet::Sheet::skip_zeros`]); `None` for the trilinear marcher.
    rows: Option<Arc<RowExtents>>,
    /// Empty-space skipping (see [`crate::accel`]); `None`: off.
    skip: Option<Arc<EmptySpace>>,
    /// Mesh objects in the same rays (see [`crate::mesh`]); `None`: voxels only.
    meshes: Option<Arc<MeshScene>>,
    /// Over a composition: per mesh, its mass-thickness column (after the voxel
    /// materials) and its density (g/cm³).
    mesh_columns: Vec<(usize, f64)>,
    /// Over a composition: number of mesh material columns.
    mesh_materials: usize,
    sums: PhantomData<S>,
}

impl<'a> Renderer<'a, LineIntegrals> {
    /// A renderer over `mu` (linear attenuation, mm⁻¹, see [`crate::attenuation`]).
    pub fn new(mu: &'a Volume, projector: Projector) -> Result<Self> {
        let renderer = Self::build(mu, projector)?;
        // Empty-space skipping is on by default where it was measured faster (trilinear:
        // docs/benchmarks.md, "Empty-space skipping"); exact Siddon's row packets gain
        // nothing from it, so it stays opt-in there.
        match projector {
            Projector::Trilinear { .. } => renderer.with_skipping(Some(SkipOptions::default())),
            Projector::Siddon => Ok(renderer),
        }
    }

    /// A renderer over `field` with no skipping and no meshes.
    fn build(mu: &'a Volume, projector: Projector) -> Result<Self> {
        let rows = (projector == Projector::Siddon).then(|| Arc::new(RowExtents::of(mu)));
        let mut renderer = Self::build_with(mu, projector, || {
            rows.as_deref().and_then(RowExtents::bounding_box)
        })?;
        renderer.rows = rows;
        Ok(renderer)
    }

    /// Turns empty-space skipping on (`Some`, building the brick map now) or off
    /// (`None`). Results are unchanged: see [`crate::accel`] for how exact that is.
    pub fn with_skipping(mut self, options: Option<SkipOptions>) -> Result<Self> {
        self.skip = match options {
            None => None,
            Some(o) => Some(Arc::new(match self.projector {
                Projector::Siddon => EmptySpace::for_siddon(self.mu, o)?,
                Projector::Trilinear { .. } => EmptySpace::for_trilinear(self.mu, o)?,
            })),
        };
        if self.projector == Projector::Siddon {
            // Rays are clipped to the non-zero voxels' box and, with skipping, to the
            // occupied bricks' box too: with a threshold above 0 that is where a real CT's
            // noisy air stops counting.
            let bricks = self.skip.as_deref().map(|s| s.map().occupied_box());
            let occupied = match self.rows.as_deref() {
                Some(rows) => rows.bounding_box(),
                None => crate::occupancy::occupied(self.mu),
            };
            self.bounds = match (occupied, bricks) {
                (b, None) => b,
                (Some(v), Some(Some(b))) => v.intersect(&b),
                _ => None,
            };
        }
        Ok(self)
    }

    /// ∫mu ds along one ray (f64; 0 when the ray misses the volume).
    pub fn line_integral(&self, ray: &Ray) -> f64 {
        let g = self.clip(ray);
        let mut iv = Vec::new();
        if let Some(m) = self.meshes.as_deref() {
            m.intervals(ray, &mut iv);
        }
        self.pixel(None, None, g.as_ref(), &iv)
    }

    /// Line-integral image of one view.
    pub fn render(&self, view: &View) -> Result<Projection> {
        let sums = self.trace(view)?;
        Ok(Projection {
            rows: view.rows,
            cols: view.cols,
            data: sums.into_iter().map(|v| v as f32).collect(),
        })
    }
}

impl<'a, S: Sums> Renderer<'a, S> {
    /// As [`Renderer::build`], with the box of non-zero voxels from `occupied` (called only
    /// for Siddon).
    fn build_with(
        mu: &'a Volume,
        projector: Projector,
        occupied: impl FnOnce() -> Option<GridBox>,
    ) -> Result<Self> {
        if let Projector::Trilinear { step_voxels } = projector
            && !(step_voxels.is_finite() && step_voxels >= MIN_TRILINEAR_STEP)
        {
            return Err(SimError::OutOfRange(format!(
                "trilinear step is {step_voxels} voxels; it must be finite and ≥ \
                 {MIN_TRILINEAR_STEP} ({} samples per voxel; exact Siddon is faster than any \
                 step that small)",
                1.0 / MIN_TRILINEAR_STEP
            )));
        }
        let bounds = match projector {
            Projector::Siddon => occupied(),
            Projector::Trilinear { .. } => Some(GridBox::whole(mu.dims())),
        };
        Ok(Self {
            mu,
            materials: 0,
            sums: PhantomData,
            projector,
            tracer: Tracer::Auto,
            packet_threshold: packet::default_threshold(),
            sheets: sheets::sheets_by_default(),
            columns: None,
            bounds,
            rows: None,
            skip: None,
            meshes: None,
            mesh_columns: Vec::new(),
            mesh_materials: 0,
        })
    }

    /// Adds mesh objects; inside a mesh the mesh replaces the voxels (an implant displaces
    /// tissue).
    ///
    /// * Over an attenuation volume every mesh needs `mu_per_mm`, added as `mu × length`.
    /// * Over a composition ([`Renderer::for_composition`]) every mesh needs a density:
    ///   each distinct mesh material ([`MeshScene::materials`]) gets its own mass-thickness
    ///   column after the voxel materials, and a mesh adds `density × length` to it;
    ///   [`Renderer::mass_thickness`] then takes the voxel material names followed by the
    ///   mesh material names.
    pub fn with_meshes(mut self, meshes: Arc<MeshScene>) -> Result<Self> {
        if S::PER_MATERIAL {
            let (names, index) = meshes.materials();
            self.mesh_columns = meshes
                .objects
                .iter()
                .zip(index)
                .map(|(o, i)| match o.density_g_cm3 {
                    Some(d) => Ok((self.materials + i, d)),
                    None => Err(SimError::OutOfRange(format!(
                        "mesh {} (material '{}') has no density: name a material of the \
                         library or give density_g_cm3",
                        o.name, o.material
                    ))),
                })
                .collect::<Result<_>>()?;
            self.mesh_materials = names.len();
        } else {
            meshes
                .require_mu()
                .map_err(|e| SimError::OutOfRange(e.to_string()))?;
        }
        self.meshes = (!meshes.is_empty()).then_some(meshes);
        if self.meshes.is_none() {
            self.mesh_columns.clear();
            self.mesh_materials = 0;
        }
        Ok(self)
    }

    /// Chooses the exact Siddon tracer ([`Tracer`]; default [`Tracer::Auto`], the measured
    /// best). `Scalar` traces one ray at a time, `Packets` adds the SIMD ray packets,
    /// `Sheets` the row sheets, `Columns` the column sheets over a k-fastest copy of the
    /// volume made now (unless one was given, [`Renderer::with_column_copy`]); where a
    /// tracer cannot take a ray (meshes or empty-space skipping for the sheets, a packet of
    /// mixed directions) the next simpler one does. Set it after skipping and meshes.
    /// Images agree with the scalar tracer's to rounding (tests/tracers.rs).
    pub fn with_tracer(mut self, tracer: Tracer) -> Self {
        self.tracer = tracer;
        let (packets, sheets) = match tracer {
            Tracer::Auto => (true, sheets::sheets_by_default()),
            Tracer::Scalar => (false, false),
            Tracer::Packets => (true, false),
            Tracer::Sheets | Tracer::Columns => (true, true),
        };
        self.packet_threshold = if packets {
            packet::default_threshold()
        } else {
            f64::INFINITY
        };
        self.sheets = sheets;
        match tracer {
            Tracer::Auto => self,
            Tracer::Columns if self.columns.is_some() => self,
            Tracer::Columns => self.with_column_sheets(true),
            Tracer::Scalar | Tracer::Packets | Tracer::Sheets => {
                self.columns = None;
                self
            }
        }
    }

    /// The exact Siddon tracer asked for ([`Renderer::with_tracer`]).
    pub fn tracer(&self) -> Tracer {
        self.tracer
    }

    /// Sets the crossings per voxel layer from which exact Siddon traces a packet of rays
    /// with the SIMD tracer (default [`packet::default_threshold`]; `f64::INFINITY`
    /// never does). Results agree either way to ~1e-12 relative; this is for tuning.
    pub fn with_packet_threshold(mut self, crossings_per_layer: f64) -> Self {
        self.packet_threshold = crossings_per_layer;
        self
    }

    /// Whether exact Siddon traces each detector row whose rays form a ray sheet along the
    /// grid's fastest axis (AP and PA views of an axial CT, [`crate::trace::sheet`]) as one
    /// (default: where it was measured faster, see `sheets_by_default`). Results agree either
    /// way to rounding (both tracers match the brute-force reference to 1e-9); this is for
    /// measuring.
    pub fn with_sheets(mut self, on: bool) -> Self {
        self.sheets = on;
        self
    }

    /// Whether exact Siddon traces the detector columns of views whose rows are not sheets
    /// as sheets along k (any gantry angle of a circular orbit about the grid's k axis
    /// without tilt; see [`crate::trace::sheet`]), over a k-fastest copy of the volume made
    /// now (`true`: a pass over the volume and as much memory again; skipped where that
    /// memory cannot be had) or dropped (`false`, the default).
    /// Made only where row sheets are on ([`Renderer::with_sheets`]) and the renderer has no
    /// skipping and no meshes (set those first); `TG_COLUMN_SHEETS=off` (read once) turns it
    /// off everywhere, for measuring. Worth it for jobs of many
    /// views of one volume (docs/projector.md, "Column sheets"); results agree with the
    /// other tracers to rounding.
    pub fn with_column_sheets(mut self, on: bool) -> Self {
        self.columns = (on && self.column_sheets_possible())
            .then(|| KFastest::new(self.mu).map(Arc::new))
            .flatten();
        self
    }

    /// The k-fastest copy this renderer traces columns over, if it made one
    /// ([`Renderer::with_column_sheets`], [`Renderer::for_views`]), for other renderers over
    /// the same volume ([`Renderer::with_column_copy`]; e.g. tomograf-physics, where the copy's
    /// holder also owns the volume: `tomograf_physics::acquisition::Prepared`).
    ///
    /// Contract: the copy knows its volume by the address and length of its values, so a
    /// holder must keep that volume alive and unchanged for as long as it hands the copy out
    /// (a volume dropped and another allocated in its place would pass the check).
    pub fn column_copy(&self) -> Option<ColumnCopy> {
        self.columns.clone().map(ColumnCopy)
    }

    /// Traces columns as sheets over `copy`, another renderer's k-fastest copy of this
    /// renderer's volume ([`Renderer::column_copy`]), instead of making one; a copy of
    /// another volume, or `None`, leaves the renderer as it is, as does a renderer that
    /// cannot take column sheets ([`Renderer::with_column_sheets`]).
    pub fn with_column_copy(mut self, copy: Option<&ColumnCopy>) -> Self {
        if let Some(c) = copy.filter(|c| c.of(self.mu) && self.column_sheets_possible()) {
            self.columns = Some(c.0.clone());
        }
        self
    }

    /// Prepares for rendering `views` with this renderer (its tracer [`Tracer::Auto`]; a
    /// tracer chosen by name keeps its own choice): column sheets
    /// ([`Renderer::with_column_sheets`]) where [`COLUMN_SHEET_VIEWS`] of the views or more
    /// would be traced by them (rows not sheets, columns sheets along k: views of a
    /// circular orbit about k without tilt, other than AP and PA), as judged from each
    /// view's first and last columns. The copy took about as long as 6 views at 30° gain,
    /// and less than one lateral view gains (chest CT, 256² views, AMD EPYC with AVX2;
    /// docs/projector.md, "Column sheets"); views that cannot use it (a tilted orbit) do
    /// not pay for it.
    pub fn for_views(self, views: &[View]) -> Self {
        // Only `auto` decides by the views; another tracer was chosen by name.
        if self.tracer != Tracer::Auto
            || views.len() < COLUMN_SHEET_VIEWS
            || !self.column_sheets_possible()
        {
            return self;
        }
        let users = views
            .iter()
            .filter(|v| self.columns_would_trace(v))
            .take(COLUMN_SHEET_VIEWS)
            .count();
        if users >= COLUMN_SHEET_VIEWS {
            self.with_column_sheets(true)
        } else {
            self
        }
    }

    /// Whether this renderer can take column sheets (see [`Renderer::with_column_sheets`]).
    fn column_sheets_possible(&self) -> bool {
        self.sheets
            && column_sheets_allowed()
            && self.projector == Projector::Siddon
            && self.skip.is_none()
            && self.meshes.is_none()
    }

    /// The projector in use.
    pub fn projector(&self) -> Projector {
        self.projector
    }

    /// `ray` clipped to the part of the grid this projector integrates.
    fn clip(&self, ray: &Ray) -> Option<GridRay> {
        GridRay::clip_to(self.mu, ray, self.bounds.as_ref()?)
    }

    /// ∫mu ds along a ray already clipped to the grid (`None`: it misses).
    fn clipped_integral(&self, g: Option<&GridRay>) -> f64 {
        let Some(g) = g else {
            return 0.0;
        };
        match (self.projector, self.skip.as_deref()) {
            (Projector::Siddon, skip) => {
                let mut acc = LineIntegral::new(self.mu.data());
                match skip {
                    Some(s) => s.siddon(self.mu.dims(), g, &mut acc),
                    None => siddon::trace(self.mu.dims(), g, &mut acc),
                }
                acc.value()
            }
            (Projector::Trilinear { step_voxels }, Some(s)) => {
                s.trilinear(self.mu.data(), self.mu.dims(), g, step_voxels)
            }
            (Projector::Trilinear { step_voxels }, None) => {
                trilinear::march(self.mu.data(), self.mu.dims(), g, step_voxels)
            }
        }
    }

    /// The sums of every pixel (pixel-major): the line integral (one per pixel, over an
    /// attenuation volume) or Σρ·ℓ per material, voxel materials then mesh materials
    /// (g/cm³ · mm, over a composition).
    fn trace(&self, view: &View) -> Result<Vec<f64>> {
        view.validate()?;
        let packed = S::PER_MATERIAL;
        let k = self.materials.max(1);
        let stride = k + self.mesh_materials;
        let packets = self.projector == Projector::Siddon && packet::available();
        // The packet tracer takes tiles of rows (see `packet::trace_rows_with`).
        let rows_per_task = if packets { packet::TILE_ROWS } else { 1 };
        // Ray sheets: exact Siddon over the voxels alone, nothing trimmed by skipping.
        let sheets = self.sheets
            && self.projector == Projector::Siddon
            && self.skip.is_none()
            && self.meshes.is_none();
        if let Some(columns) = self.columns.as_deref().filter(|_| sheets)
            && !self.rows_are_sheets(view)
            && let Some(data) = self.trace_columns(columns, view)
        {
            return Ok(data);
        }
        let mut data = vec![0.0f64; view.rows * view.cols * stride];
        data.par_chunks_mut(view.cols * stride * rows_per_task)
            .enumerate()
            .for_each(|(task, row)| {
                let first = task * rows_per_task;
                let rows = row.len() / (view.cols * stride);
                // One exact-sized vector (collecting a `flat_map` grows it step by step).
                let mut world: Vec<Ray> = Vec::with_capacity(rows * view.cols);
                for r in first..first + rows {
                    world.extend((0..view.cols).map(|c| view.ray(r as f64, c as f64)));
                }
                let rays: Vec<Option<GridRay>> = world.iter().map(|w| self.clip(w)).collect();
                if sheets && self.trace_sheets(&rays, view.cols, packed.then_some(k), row) {
                    return;
                }
                // Each ray's intervals inside meshes (empty without meshes).
                let meshed = match self.meshes.as_deref() {
                    Some(m) => m.row_intervals(&world),
                    None => meshes::RowIntervals::empty(world.len()),
                };
                // Voxel sums of the rays the SIMD tracer takes whole (it walks whole
                // layers: of empty-space skipping it sees only the occupied bricks' box,
                // `self.bounds`; trimming its rays further measured slower).
                let mut voxels = vec![0.0f64; world.len() * k];
                let mut handled = vec![false; world.len()];
                if let (true, Some(kernel)) = (packets, packet::kernel()) {
                    let (field, dims, t) = (self.mu.data(), self.mu.dims(), self.packet_threshold);
                    packet::trace_rows_with(
                        kernel,
                        field,
                        dims,
                        &rays,
                        view.cols,
                        t,
                        if packed { k } else { 0 },
                        &mut voxels,
                        &mut handled,
                    );
                }
                // Rays the packets took whole that run through one mesh inside the grid:
                // the voxels inside that mesh, also by packets (to be subtracted).
                let mut inner_sums = Vec::new();
                let mut inner_handled = vec![false; world.len()];
                if let (true, Some(kernel)) = (packets, packet::kernel()) {
                    let inner: Vec<Option<GridRay>> = (0..world.len())
                        .map(|c| {
                            let g = rays[c].as_ref().filter(|_| handled[c])?;
                            meshes::single_inside(g, meshed.ray(c))
                        })
                        .collect();
                    if inner.iter().any(Option::is_some) {
                        inner_sums = vec![0.0f64; world.len() * k];
                        let (field, dims, t) =
                            (self.mu.data(), self.mu.dims(), self.packet_threshold);
                        packet::trace_rows_with(
                            kernel,
                            field,
                            dims,
                            &inner,
                            view.cols,
                            t,
                            if packed { k } else { 0 },
                            &mut inner_sums,
                            &mut inner_handled,
                        );
                    }
                }
                for (c, px) in row.chunks_mut(stride).enumerate() {
                    let packet = handled[c].then_some(&voxels[c * k..(c + 1) * k]);
                    let inside = inner_handled[c].then(|| &inner_sums[c * k..(c + 1) * k]);
                    let (g, iv) = (rays[c].as_ref(), meshed.ray(c));
                    if packed {
                        self.pixel_materials(packet, inside, g, iv, px);
                    } else {
                        px[0] = self.pixel(packet.map(|v| v[0]), inside.map(|v| v[0]), g, iv);
                    }
                }
            });
        Ok(data)
    }

    /// Σρ·ℓ per material (g/cm³ · mm) along a clipped ray into `out` (zeros when it misses).
    fn clipped_materials(&self, g: Option<&GridRay>, out: &mut [f64]) {
        out.fill(0.0);
        let Some(g) = g else {
            return;
        };
        let (field, dims) = (self.mu.data(), self.mu.dims());
        match self.projector {
            Projector::Siddon => {
                let mut acc = MaterialPaths::new(field);
                siddon::trace(dims, g, &mut acc);
                out.copy_from_slice(&acc.sums()[..out.len()]);
            }
            Projector::Trilinear { step_voxels } => {
                trilinear::march_materials(field, dims, g, step_voxels, out);
            }
        }
    }
}

/// Whether [`Renderer::with_column_sheets`] may make its copy: unless `TG_COLUMN_SHEETS=off`
/// (read once; for measuring a job with and without).
fn column_sheets_allowed() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("TG_COLUMN_SHEETS").as_deref() != Ok("off"))
}
