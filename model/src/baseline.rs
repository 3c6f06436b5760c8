//! Baselines evaluated from the same views as the model: the mean training volume
//! (here) and analytic reconstructions such as FDK (plugged in through [`Baseline`]).

use crate::error::{ModelError, Result, ensure};
pub use crate::prior::MeanVolume;
use crate::reconstruct::Reference;
use crate::render::DensityScale;
use tomograf_sim::recon::{FdkOptions, SartOptions, fdk, sart_tv_from};
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projection, View, ViewBeam, Volume};

/// A reconstruction method to compare with.
pub trait Baseline {
    /// Name for tables.
    fn name(&self) -> &str;
    /// The normalised density on `grid`'s geometry from `refs` (line integrals;
    /// `scale` maps normalised density to mu).
    fn reconstruct(
        &self,
        refs: &[Reference],
        grid: &Volume,
        scale: &DensityScale,
    ) -> Result<Volume>;
}

impl Baseline for MeanVolume {
    fn name(&self) -> &str {
        "mean training volume"
    }

    fn reconstruct(&self, _: &[Reference], grid: &Volume, _: &DensityScale) -> Result<Volume> {
        ensure!(
            grid.dims() == self.dims,
            "mean volume is {:?} but the test grid is {:?}",
            self.dims,
            grid.dims()
        );
        Ok(Volume::new(
            self.dims,
            grid.spacing(),
            grid.origin(),
            grid.direction(),
            self.data.clone(),
        )?)
    }
}

/// The normalised density whose attenuation is `mu` (mm⁻¹): the inverse of
/// [`DensityScale::mu_scalar`] above the threshold.
fn density_of(mu: &Volume, scale: &DensityScale) -> Result<Volume> {
    let (k, t) = (scale.mu_per_unit, scale.threshold);
    Ok(mu.map(|m| (f64::from(m) / k + t) as f32)?)
}

/// The set-up (SAD, SID, panel) the reference views were taken with, on a circular orbit
/// about `grid`'s centre; every view is checked to be reproduced by it.
fn setup_of(refs: &[Reference], grid: &Volume) -> Result<Geometry> {
    ensure!(!refs.is_empty(), "no reference views");
    let v = refs[0].view;
    let ViewBeam::Cone { source } = v.beam else {
        return Err(ModelError::Invalid(
            "FDK needs cone-beam views; these are parallel".into(),
        ));
    };
    let iso = grid.centre();
    let normal = v.u.cross(v.v).normalize();
    let centre = v.pixel_centre((v.rows as f64 - 1.0) / 2.0, (v.cols as f64 - 1.0) / 2.0);
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: (source - iso).length(),
            sid_mm: (centre - source).dot(normal).abs(),
        },
        detector: Detector {
            rows: v.rows,
            cols: v.cols,
            pitch_u_mm: v.u.length(),
            pitch_v_mm: v.v.length(),
            offset_u_mm: 0.0,
            offset_v_mm: 0.0,
        },
        isocentre: iso,
    };
    for r in refs {
        let w = g.view(r.pose)?;
        let off = |a: glam::DVec3, b: glam::DVec3| (a - b).length();
        let ViewBeam::Cone { source: s } = w.beam else {
            unreachable!("a cone set-up gives cone views")
        };
        let ViewBeam::Cone { source: s0 } = r.view.beam else {
            return Err(ModelError::Invalid(
                "views mix cone and parallel beams".into(),
            ));
        };
        ensure!(
            off(s, s0) < 1e-3 && off(w.detector_origin, r.view.detector_origin) < 1e-3,
            "view at θ = {}° is not on a circular orbit about the volume's centre with \
             centred panels; FDK needs one",
            r.pose.theta_deg
        );
    }
    Ok(g)
}

fn projections(refs: &[Reference]) -> Vec<Projection> {
    refs.iter()
        .map(|r| Projection {
            rows: r.view.rows,
            cols: r.view.cols,
            data: r.image.clone(),
        })
        .collect()
}

/// Feldkamp–Davis–Kress (`tomograf_sim::recon::fdk`, Ram-Lak, automatic angular
/// weighting) from the reference views, on the ground-truth grid.
#[derive(Debug, Clone, Copy, Default)]
pub struct Fdk;

impl Baseline for Fdk {
    fn name(&self) -> &str {
        "FDK"
    }

    fn reconstruct(
        &self,
        refs: &[Reference],
        grid: &Volume,
        scale: &DensityScale,
    ) -> Result<Volume> {
        let g = setup_of(refs, grid)?;
        let poses: Vec<Pose> = refs.iter().map(|r| r.pose).collect();
        let mu = fdk(&projections(refs), &g, &poses, &FdkOptions::default(), grid)?;
        density_of(&mu, scale)
    }
}

/// SART with TV regularisation (`tomograf_sim::recon::sart_tv_from`, its defaults: 20
/// iterations, ASD-POCS TV steps, non-negative) from the reference views, started from
/// zero, or from the mean training volume when `start` holds it (a fair classical
/// baseline for a learned prior: the same population knowledge, then data consistency).
#[derive(Debug, Clone, Default)]
pub struct SartTv {
    /// The volume to start from (normalised density); `None` starts from zero.
    pub start: Option<MeanVolume>,
}

impl SartTv {
    /// SART-TV from zero.
    pub const FROM_ZERO: Self = Self { start: None };

    /// SART-TV started from `mean`.
    pub fn from_mean(mean: MeanVolume) -> Self {
        Self { start: Some(mean) }
    }
}

impl Baseline for SartTv {
    fn name(&self) -> &str {
        match self.start {
            None => "SART-TV",
            Some(_) => "SART-TV from the mean",
        }
    }

    fn reconstruct(
        &self,
        refs: &[Reference],
        grid: &Volume,
        scale: &DensityScale,
    ) -> Result<Volume> {
        let start = match &self.start {
            None => vec![],
            Some(m) => {
                ensure!(
                    m.dims == grid.dims(),
                    "mean volume is {:?} but the test grid is {:?}",
                    m.dims,
                    grid.dims()
                );
                vec![(m.data.as_slice(), 1.0)]
            }
        };
        sart_tv_density(refs, grid, scale, &start, SartOptions::default().iterations)
    }
}

/// SART-TV (`tomograf_sim::recon::sart_tv_from` with its defaults, `iterations` sweeps,
/// `min(views, 10)` ordered subsets) from the reference views, started from the sum over
/// `start`'s `(density, weight)` terms of weight times the attenuation of the normalised
/// density on `grid` (empty: zero attenuation; one term of weight 1: that volume itself);
/// returns normalised density.
pub fn sart_tv_density(
    refs: &[Reference],
    grid: &Volume,
    scale: &DensityScale,
    start: &[(&[f32], f64)],
    iterations: usize,
) -> Result<Volume> {
    let views: Vec<View> = refs.iter().map(|r| r.view).collect();
    let options = SartOptions {
        iterations,
        subsets: refs.len().min(10),
        ..SartOptions::default()
    };
    let voxels = grid.data().len();
    for (d, _) in start {
        ensure!(
            d.len() == voxels,
            "a SART-TV start holds {} voxels but the grid {:?} has {voxels}",
            d.len(),
            grid.dims()
        );
    }
    let start: Option<Vec<f32>> = (!start.is_empty()).then(|| {
        (0..voxels)
            .map(|n| {
                start
                    .iter()
                    .map(|(d, w)| w * scale.mu_scalar(f64::from(d[n])))
                    .sum::<f64>() as f32
            })
            .collect()
    });
    let r = sart_tv_from(
        &projections(refs),
        &views,
        &options,
        grid,
        start.as_deref(),
        |_| {},
    )?;
    density_of(&r.volume, scale)
}
