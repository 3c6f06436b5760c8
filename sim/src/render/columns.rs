//! Detector columns traced as ray sheets, over a copy of the volume with k fastest.
//!
//! In a circular orbit about the grid's k axis without tilt, the source and the pixels of
//! one detector column lie in a plane that contains the k direction: seen along k, every ray
//! of the column follows the same line in the i–j plane, and the column is a ray sheet
//! fanning out along k ([`crate::trace::sheet`]), at every gantry angle. The sheet kernel
//! reads the voxels of each segment's line along the fan's axis, which must be contiguous
//! in memory to pay; k is the grid's slowest axis, so the columns are traced over a copy of
//! the volume stored k-fastest ([`KFastest`]). The copy costs a pass over the volume and as
//! much memory again, which a job rendering many views earns back (docs/projector.md,
//! "Column sheets"); a renderer makes it only when asked
//! ([`super::Renderer::with_column_sheets`]).

use super::{Renderer, Sums};
use crate::geometry::View;
use crate::grid_box::GridBox;
use crate::ray::GridRay;
use crate::trace::sheet::Sheet;
use crate::volume::Volume;
use rayon::prelude::*;
use std::sync::Arc;

/// The copy's axis n is the volume's axis `AXES[n]`: (k, i, j).
const AXES: [usize; 3] = [2, 0, 1];

fn permute<T: Copy>(v: [T; 3]) -> [T; 3] {
    AXES.map(|a| v[a])
}

/// A volume's voxels stored k-fastest: voxel (i, j, k) at `k + nz·(i + nx·j)`.
pub(super) struct KFastest {
    data: Vec<f32>,
    /// The copy's dimensions, `[nz, nx, ny]`.
    dims: [usize; 3],
    /// Where the copied volume's values lie (address and length), to tell whether a
    /// renderer is over that volume ([`ColumnCopy`]).
    source: (usize, usize),
}

/// A renderer's k-fastest copy of its volume ([`super::Renderer::column_copy`]), to hand to
/// other renderers over the same volume ([`super::Renderer::with_column_copy`]), so that a
/// job that makes a renderer per view pays for the copy once.
#[derive(Clone, Debug)]
pub struct ColumnCopy(pub(super) Arc<KFastest>);

impl ColumnCopy {
    /// Whether this is the copy of `volume`'s values (the same values in memory).
    pub(super) fn of(&self, volume: &Volume) -> bool {
        self.0.source == (volume.data().as_ptr() as usize, volume.data().len())
    }
}

impl KFastest {
    /// The copy of `volume`, made in parallel, one plane of constant j per task (each read
    /// runs along i, each write within the plane's 4·nx·nz bytes); `None` where the memory
    /// for it cannot be had (the copy only saves time, so the renderer goes without).
    pub(super) fn new(volume: &Volume) -> Option<Self> {
        let [nx, ny, nz] = volume.dims();
        let data = volume.data();
        let mut out = Vec::new();
        out.try_reserve_exact(data.len()).ok()?;
        out.resize(data.len(), 0.0f32);
        out.par_chunks_mut(nz * nx)
            .enumerate()
            .for_each(|(j, plane)| {
                for k in 0..nz {
                    let line = &data[nx * (j + ny * k)..][..nx];
                    for (i, &v) in line.iter().enumerate() {
                        plane[k + nz * i] = v;
                    }
                }
            });
        Some(Self {
            data: out,
            dims: permute(volume.dims()),
            source: (data.as_ptr() as usize, data.len()),
        })
    }

    /// The integrals of the rays of detector column `rays` (clipped to `bounds` in the
    /// volume's grid; `None` misses) into `out` — line integrals, or with `materials`
    /// (`Some(k)`, the copy of a composition's packed values) Σρ·ℓ of materials `0..k`, k
    /// per ray — if they form a sheet fanning out along k (or all miss): `false` otherwise.
    pub(super) fn column(
        &self,
        rays: &[Option<GridRay>],
        bounds: &GridBox,
        materials: Option<usize>,
        out: &mut [f64],
    ) -> bool {
        let (rays, bounds) = permuted(rays, bounds);
        match (Sheet::new(&rays, self.dims, &bounds), materials) {
            (Some(sheet), None) if sheet.axis() == 0 => {
                sheet.line_integrals(&self.data, self.dims, &bounds, out);
                true
            }
            (Some(sheet), Some(k)) if sheet.axis() == 0 => {
                sheet.material_sums(&self.data, self.dims, &bounds, k, out);
                true
            }
            (None, _) if rays.iter().all(Option::is_none) => {
                out.fill(0.0);
                true
            }
            _ => false,
        }
    }
}

/// `rays` and `bounds` in the grid of the k-fastest copy.
fn permuted(rays: &[Option<GridRay>], bounds: &GridBox) -> (Vec<Option<GridRay>>, GridBox) {
    let rays = rays
        .iter()
        .map(|g| {
            g.as_ref().map(|g| GridRay {
                g0: permute(g.g0),
                gd: permute(g.gd),
                inv: permute(g.inv),
                ..*g
            })
        })
        .collect();
    let bounds = GridBox {
        lo: permute(bounds.lo),
        hi: permute(bounds.hi),
    };
    (rays, bounds)
}

impl std::fmt::Debug for KFastest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "KFastest({:?} voxels)", self.dims)
    }
}

/// The clipped rays of one detector row or column (`None`: misses).
type LineRays = Vec<Option<GridRay>>;

/// A detector row or column.
#[derive(Clone, Copy)]
enum Line {
    Row,
    Column,
}

impl<S: Sums> Renderer<'_, S> {
    /// Whether `view`'s rows are traced as sheets (as in AP and PA views): the first and
    /// last rows that meet the volume form sheets along the grid's fastest axis. (Not the
    /// middle row: at the source's height, a row of any view lies in a plane of k, which
    /// makes a sheet along i of it too.)
    pub(super) fn rows_are_sheets(&self, view: &View) -> bool {
        let Some(bounds) = self.bounds.as_ref() else {
            return true;
        };
        let sheet = |rays: &[Option<GridRay>]| {
            Sheet::new(rays, self.mu.dims(), bounds).is_some_and(|s| s.axis() == 0)
        };
        let (first, last) = self.first_and_last_hits(view, Line::Row);
        first.is_none_or(|r| sheet(&r)) && last.is_none_or(|r| sheet(&r))
    }

    /// The clipped rays of `view`'s first and last rows (or columns) that meet the volume.
    fn first_and_last_hits(&self, view: &View, line: Line) -> (Option<LineRays>, Option<LineRays>) {
        let (lines, along) = match line {
            Line::Row => (view.rows, view.cols),
            Line::Column => (view.cols, view.rows),
        };
        let rays = |n: usize| -> LineRays {
            (0..along)
                .map(|m| {
                    let (r, c) = match line {
                        Line::Row => (n, m),
                        Line::Column => (m, n),
                    };
                    self.clip(&view.ray(r as f64, c as f64))
                })
                .collect()
        };
        let hit = |rays: &LineRays| rays.iter().any(Option::is_some);
        (
            (0..lines).map(rays).find(hit),
            (0..lines).rev().map(rays).find(hit),
        )
    }

    /// Whether column sheets would trace `view`: its rows are not sheets, and its first
    /// and last detector columns that meet the volume are sheets along k (as in any view
    /// of a circular orbit about k without tilt). A prediction from two columns, for
    /// deciding whether the k-fastest copy pays; tracing still checks every column.
    pub(super) fn columns_would_trace(&self, view: &View) -> bool {
        let Some(bounds) = self.bounds.as_ref() else {
            return false;
        };
        if self.rows_are_sheets(view) {
            return false;
        }
        let dims = permute(self.mu.dims());
        let sheet = |rays: &[Option<GridRay>]| {
            let (rays, bounds) = permuted(rays, bounds);
            Sheet::new(&rays, dims, &bounds).is_some_and(|s| s.axis() == 0)
        };
        let (first, last) = self.first_and_last_hits(view, Line::Column);
        first.is_some_and(|c| sheet(&c)) && last.is_some_and(|c| sheet(&c))
    }

    /// The sums of every pixel of `view` (pixel-major: the line integral, or Σρ·ℓ of
    /// each material for a renderer over a composition), each detector column traced as a
    /// sheet over `columns`, if every column forms one.
    pub(super) fn trace_columns(&self, columns: &KFastest, view: &View) -> Option<Vec<f64>> {
        let bounds = self.bounds.as_ref()?;
        let materials = S::PER_MATERIAL.then_some(self.materials);
        let per_pixel = materials.unwrap_or(1);
        let traced: Vec<Vec<f64>> = (0..view.cols)
            .into_par_iter()
            .map(|c| {
                let rays: Vec<Option<GridRay>> = (0..view.rows)
                    .map(|r| self.clip(&view.ray(r as f64, c as f64)))
                    .collect();
                let mut out = vec![0.0; view.rows * per_pixel];
                columns
                    .column(&rays, bounds, materials, &mut out)
                    .then_some(out)
            })
            .collect::<Option<_>>()?;
        let mut data = vec![0.0; view.rows * view.cols * per_pixel];
        for (p, px) in data.chunks_mut(per_pixel).enumerate() {
            let (r, c) = (p / view.cols, p % view.cols);
            px.copy_from_slice(&traced[c][r * per_pixel..(r + 1) * per_pixel]);
        }
        Some(data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Beam, Detector, Geometry, Pose};
    use crate::render::Projector;
    use glam::{DMat3, DVec3};

    /// A volume of pseudo-random mu (mm⁻¹) whose outer voxels are 0, so that rays are
    /// clipped to a box inside the grid.
    fn volume() -> Volume {
        let dims = [31, 26, 17];
        let mut state = 12345u64;
        let data = (0..dims.iter().product::<usize>())
            .map(|n| {
                let (i, j, k) = (n % 31, n / 31 % 26, n / (31 * 26));
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let inside = (2..29).contains(&i) && (3..24).contains(&j) && (1..16).contains(&k);
                if inside {
                    (state >> 40) as f32 / (1u64 << 24) as f32 * 0.05
                } else {
                    0.0
                }
            })
            .collect();
        let spacing = DVec3::new(0.9, 1.1, 2.3);
        Volume::new(
            dims,
            spacing,
            DVec3::new(-12.0, 7.0, 3.0),
            DMat3::IDENTITY,
            data,
        )
        .unwrap()
    }

    /// A small cone beam about `vol`, its isocentre off the centre: no ray runs within
    /// rounding of a grid plane (see the sheet module's documentation).
    fn geometry(vol: &Volume) -> Geometry {
        Geometry {
            beam: Beam::Cone {
                sad_mm: 250.0,
                sid_mm: 400.0,
            },
            detector: Detector::new(23, 29, 2.1),
            isocentre: vol.centre() + DVec3::new(0.0123, 0.0456, 0.0078),
        }
    }

    #[test]
    fn columns_are_traced_as_sheets_at_any_angle_and_agree_with_the_other_tracers() {
        let vol = volume();
        let geometry = geometry(&vol);
        let plain = Renderer::new(&vol, Projector::Siddon)
            .unwrap()
            .with_sheets(false);
        let with = Renderer::new(&vol, Projector::Siddon)
            .unwrap()
            .with_sheets(true)
            .with_column_sheets(true);
        let columns = with.columns.as_deref().expect("the k-fastest copy");
        // Jobs ask for the copy from `COLUMN_SHEET_VIEWS` views that would use it on:
        // views of an orbit about k, not AP or PA views (rows are sheets there) nor views
        // of a tilted orbit (columns are not sheets there).
        let for_views = |poses: &[Pose]| {
            let views: Vec<View> = poses.iter().map(|&p| geometry.view(p).unwrap()).collect();
            Renderer::new(&vol, Projector::Siddon)
                .unwrap()
                .with_sheets(true)
                .for_views(&views)
                .columns
                .is_some()
        };
        let n = super::super::COLUMN_SHEET_VIEWS;
        let orbit = |n: usize, tilt: f64| -> Vec<Pose> {
            (0..n)
                .map(|v| Pose::new(20.0 + 10.0 * v as f64, tilt))
                .collect()
        };
        assert!(!for_views(&orbit(n - 1, 0.0)));
        assert!(for_views(&orbit(n, 0.0)));
        assert!(!for_views(&orbit(n, 15.0)));
        let ap_pa: Vec<Pose> = (0..n)
            .map(|v| Pose::new(180.0 * (v % 2) as f64, 0.0))
            .collect();
        assert!(!for_views(&ap_pa));
        let mixed: Vec<Pose> = [orbit(n - 1, 0.0), vec![Pose::new(0.0, 0.0)]].concat();
        assert!(!for_views(&mixed));
        let mut traced = 0;
        for theta in [0.0, 17.0, 45.0, 90.0, 133.0, 200.0, 301.0] {
            let view = geometry.view(Pose::new(theta, 0.0)).unwrap();
            let expected = plain.trace(&view).unwrap();
            assert!(expected.iter().any(|&v| v > 0.0) && expected.contains(&0.0));
            let got = with
                .trace_columns(columns, &view)
                .expect("every column a sheet");
            for (n, (a, b)) in got.iter().zip(&expected).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs() + 1e-13,
                    "θ = {theta}°, pixel {n}: columns {a}, other tracers {b}"
                );
            }
            // The renderer takes the columns where the rows are not sheets (not at 0°).
            assert_eq!(with.rows_are_sheets(&view), theta == 0.0, "θ = {theta}°");
            let image = with.trace(&view).unwrap();
            assert_eq!(image.len(), expected.len());
            traced += 1;
        }
        assert_eq!(traced, 7);
        // A parallel beam's columns are sheets too (every ray of one at the same slope, 0).
        let parallel = Geometry {
            beam: Beam::Parallel,
            ..geometry
        };
        for theta in [0.0, 38.0, 90.0] {
            let view = parallel.view(Pose::new(theta, 0.0)).unwrap();
            let expected = plain.trace(&view).unwrap();
            let got = with
                .trace_columns(columns, &view)
                .expect("every column a sheet");
            for (a, b) in got.iter().zip(&expected) {
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs() + 1e-13,
                    "parallel, θ = {theta}°"
                );
            }
        }
        // A tilted orbit's columns are not sheets along k: the renderer falls back.
        let view = geometry.view(Pose::new(30.0, 15.0)).unwrap();
        assert!(with.trace_columns(columns, &view).is_none());
        let (a, b) = (with.trace(&view).unwrap(), plain.trace(&view).unwrap());
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-9 * y.abs() + 1e-13);
        }
    }

    #[test]
    fn compositions_take_row_and_column_sheets_and_agree_with_the_packets() {
        // Σρ·ℓ per material through sheets (rows at AP/PA, columns elsewhere) against the
        // packets and the scalar tracer (sheets off), to 1e-9 relative per material.
        use crate::composition::Composition;
        let vol = volume();
        let [nx, ny, _] = vol.dims();
        let labels: Vec<f32> = (0..vol.data().len())
            .map(|n| ((n % nx / 4 + n / nx % ny / 3) % 4) as f32)
            .collect();
        let grid = |data: Vec<f32>| {
            Volume::new(
                vol.dims(),
                vol.spacing(),
                vol.origin(),
                vol.direction(),
                data,
            )
            .unwrap()
        };
        let density: Vec<f32> = vol.data().iter().map(|v| v * 30.0).collect();
        let names: Vec<String> = (0..4).map(|m| format!("m{m}")).collect();
        let comp = Composition::from_labels(&grid(labels), &grid(density), names.clone()).unwrap();
        let geometry = geometry(&vol);
        let plain = Renderer::for_composition(&comp, Projector::Siddon)
            .unwrap()
            .with_sheets(false);
        let with = Renderer::for_composition(&comp, Projector::Siddon)
            .unwrap()
            .with_sheets(true)
            .with_column_sheets(true);
        let columns = with.columns.as_deref().expect("the k-fastest copy");
        for theta in [0.0, 45.0, 90.0, 180.0, 301.0] {
            let view = geometry.view(Pose::new(theta, 0.0)).unwrap();
            let expected = plain.mass_thickness(&view, &names).unwrap().data;
            assert!(expected.iter().any(|&v| v > 0.0) && expected.contains(&0.0));
            let rows = with.rows_are_sheets(&view);
            assert_eq!(rows, theta == 0.0 || theta == 180.0, "θ = {theta}°");
            if !rows {
                let got = with
                    .trace_columns(columns, &view)
                    .expect("every column a sheet");
                // g/cm³ · mm, as `mass_thickness` reports ×0.1 in g/cm².
                for (n, (a, b)) in got.iter().zip(&expected).enumerate() {
                    assert!(
                        (0.1 * a - b).abs() <= 1e-9 * b.abs() + 1e-14,
                        "θ = {theta}°, value {n}: columns {a}, other tracers {b}"
                    );
                }
            }
            let got = with.mass_thickness(&view, &names).unwrap().data;
            for (n, (a, b)) in got.iter().zip(&expected).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs() + 1e-14,
                    "θ = {theta}°, value {n}: sheets {a}, other tracers {b}"
                );
            }
        }
    }
}
