//! Projections read back: a folder written by [`crate::project()`] (`drr.json` +
//! `drr.npy`) or a data-set item ([`crate::dataset`]: `views.json` + `projections.npy`),
//! as line integrals with each view's geometry — what classical reconstruction and
//! re-rendering start from.

use anyhow::{Context, Result, bail, ensure};
use std::path::Path;
use tomograf_datasets::sidecar::{PixelQuantity, Sidecar};
use tomograf_datasets::{item, nifti};
use tomograf_sim::{Geometry, Pose, Projection, Quantity, View, Volume};

/// A folder of projections and their geometry, with the grid of the volume they show.
#[derive(Debug, Clone)]
pub struct ProjectionSet {
    /// Per view, the line integrals (dimensionless: mu (mm⁻¹) × length (mm)), whatever
    /// quantity the files hold.
    pub images: Vec<Projection>,
    /// Per view, its rays.
    pub views: Vec<View>,
    /// Per view, its gantry pose, where every view has one.
    pub poses: Option<Vec<Pose>>,
    /// The set-up, where the files record one.
    pub geometry: Option<Geometry>,
    /// The grid of the projected volume (values 0), where the files record it.
    pub grid: Option<Volume>,
}

/// Reads a folder written by `tomograf project` (`drr.json` + `drr.npy`, ideal DRRs of
/// any [`Quantity`]) or a data-set item (`views.json` + `projections.npy`, line
/// integrals; the grid from its `ct.nii.gz`). Images of detector signals (real physics)
/// are refused: they are not line integrals.
pub fn read_projections(dir: &Path) -> Result<ProjectionSet> {
    let (views, poses, geometry, npy, quantity, grid) = if dir.join("drr.json").is_file() {
        let path = dir.join("drr.json");
        let sc = Sidecar::read(&path)?;
        let quantity = match &sc.quantity {
            PixelQuantity::Ideal(q) => *q,
            PixelQuantity::Described(what) => bail!(
                "{}: the images hold a {what}, which classical reconstruction does not \
                 read: it reconstructs ideal DRRs (line integrals, transmission or intensity)",
                path.display()
            ),
        };
        let grid = sc
            .grid()
            .with_context(|| format!("{}: the volume grid", path.display()))?;
        let poses: Option<Vec<Pose>> = sc.views.iter().map(|v| v.pose).collect();
        let views: Vec<View> = sc.views.iter().map(|v| v.view).collect();
        (
            views,
            poses,
            sc.geometry,
            dir.join("drr.npy"),
            quantity,
            Some(grid),
        )
    } else if dir.join("views.json").is_file() {
        let ct = dir.join("ct.nii.gz");
        let grid = if ct.is_file() {
            Some(nifti::read_nifti(&ct)?.map(|_| 0.0)?)
        } else {
            None
        };
        let (geometry, poses, views) = item::read_views(&dir.join("views.json"))?;
        let (poses, geometry) = (Some(poses), Some(geometry));
        let npy = dir.join("projections.npy");
        (views, poses, geometry, npy, Quantity::LineIntegral, grid)
    } else {
        bail!(
            "{} holds neither drr.json (tomograf project) nor views.json (tomograf dataset)",
            dir.display()
        );
    };
    let (data, shape) = tomograf_datasets::image::read_npy(&npy)?;
    ensure!(
        shape.len() == 3 && shape[0] == views.len(),
        "{} has shape {shape:?}, expected ({}, rows, cols)",
        npy.display(),
        views.len()
    );
    let px = shape[1] * shape[2];
    let images = data
        .chunks(px)
        .enumerate()
        .map(|(i, c)| {
            let data = c
                .iter()
                .map(|&x| to_line_integral(quantity, x))
                .collect::<Result<Vec<f32>>>()
                .with_context(|| format!("view {i}"))?;
            Ok(Projection {
                rows: shape[1],
                cols: shape[2],
                data,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(ProjectionSet {
        images,
        views,
        poses,
        geometry,
        grid,
    })
}

/// The line integral of a pixel holding `x` of quantity `q`.
fn to_line_integral(q: Quantity, x: f32) -> Result<f32> {
    let x = f64::from(x);
    Ok(match q {
        Quantity::LineIntegral => x,
        Quantity::Transmission => {
            ensure!(x > 0.0, "transmission {x} ≤ 0 has no line integral");
            -x.ln()
        }
        Quantity::Intensity { i0 } => {
            ensure!(x > 0.0, "intensity {x} ≤ 0 has no line integral");
            -(x / i0).ln()
        }
    } as f32)
}
