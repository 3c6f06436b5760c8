//! Baselines evaluated from the same views as the model: the mean training volume
//! (here) and analytic reconstructions such as FDK (plugged in through [`Baseline`]).

use crate::error::{ModelError, Result, ensure};
pub use crate::prior::MeanVolume;
use crate::reference::Reference;
use crate::render::DensityScale;
use serde::{Deserialize, Serialize};
use tomograf_recon::{FdkOptions, SartOptions, TvOptions, Window, fdk, sart_tv_from};
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

/// Feldkamp–Davis–Kress (`tomograf_recon::fdk`, automatic angular weighting) from
/// the reference views, on the ground-truth grid; the ramp filter's window is a setting
/// (default Ram-Lak).
#[derive(Debug, Clone, Copy, Default)]
pub struct Fdk {
    /// The ramp filter's apodisation window.
    pub window: Window,
}

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
        let options = FdkOptions {
            window: self.window,
            ..FdkOptions::default()
        };
        let mu = fdk(&projections(refs), &g, &poses, &options, grid)?;
        density_of(&mu, scale)
    }
}

/// The settings of SART-TV that a user would tune: how many sweeps, and how strongly TV
/// smooths between them. The rest is `tomograf_recon::SartOptions`' defaults
/// (relaxation 1, non-negative, `min(views, 10)` ordered subsets, 10 TV steps a sweep).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SartTvSettings {
    /// Full sweeps over the views (≥ 1).
    pub sweeps: usize,
    /// ASD-POCS TV step, relative to the preceding data update (Sidky & Pan's α; 0: plain
    /// SART, no TV).
    pub tv_step: f64,
}

impl Default for SartTvSettings {
    /// 20 sweeps, TV step 0.2: `SartOptions::default()`.
    fn default() -> Self {
        Self {
            sweeps: SartOptions::default().iterations,
            tv_step: TvOptions::default().step,
        }
    }
}

impl SartTvSettings {
    /// The sweeps' options for `views` reference views; errors naming a bad setting.
    pub fn options(&self, views: usize) -> Result<SartOptions> {
        ensure!(
            (1..=10_000).contains(&self.sweeps),
            "SART-TV sweeps {} must be 1…10000",
            self.sweeps
        );
        ensure!(
            self.tv_step.is_finite() && (0.0..=10.0).contains(&self.tv_step),
            "SART-TV's TV step {} must be 0…10 (0: no TV)",
            self.tv_step
        );
        Ok(SartOptions {
            iterations: self.sweeps,
            subsets: views.clamp(1, 10),
            tv: (self.tv_step > 0.0).then_some(TvOptions {
                step: self.tv_step,
                ..TvOptions::default()
            }),
            ..SartOptions::default()
        })
    }
}

/// SART with TV regularisation (`tomograf_recon::sart_tv_from`, non-negative, its
/// sweeps and TV step from [`SartTvSettings`]) from the reference views, started from zero,
/// or from the mean training volume when `start` holds it (a fair classical baseline for a
/// learned prior: the same population knowledge, then data consistency).
#[derive(Debug, Clone, Default)]
pub struct SartTv {
    /// The volume to start from (normalised density); `None` starts from zero.
    pub start: Option<MeanVolume>,
    /// Sweeps and TV step.
    pub settings: SartTvSettings,
}

impl SartTv {
    /// SART-TV from zero with the default settings.
    pub fn from_zero() -> Self {
        Self::default()
    }

    /// SART-TV started from `mean`, with the default settings.
    pub fn from_mean(mean: MeanVolume) -> Self {
        Self {
            start: Some(mean),
            settings: SartTvSettings::default(),
        }
    }

    /// The same start with `settings`.
    pub fn with(self, settings: SartTvSettings) -> Self {
        Self { settings, ..self }
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
        sart_tv_density(refs, grid, scale, &start, &self.settings)
    }
}

/// SART-TV (`tomograf_recon::sart_tv_from` with `settings`, `min(views, 10)` ordered
/// subsets) from the reference views, started from the sum over `start`'s `(density,
/// weight)` terms of weight times the attenuation of the normalised density on `grid`
/// (empty: zero attenuation; one term of weight 1: that volume itself); returns normalised
/// density.
pub fn sart_tv_density(
    refs: &[Reference],
    grid: &Volume,
    scale: &DensityScale,
    start: &[(&[f32], f64)],
    settings: &SartTvSettings,
) -> Result<Volume> {
    let views: Vec<View> = refs.iter().map(|r| r.view).collect();
    let options = settings.options(refs.len())?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sart_settings_map_to_options_and_refuse_bad_values() {
        let d = SartTvSettings::default();
        assert_eq!((d.sweeps, d.tv_step), (20, 0.2));
        let o = d.options(2).unwrap();
        assert_eq!((o.iterations, o.subsets), (20, 2));
        assert_eq!(o.tv.map(|t| t.step), Some(0.2));
        assert_eq!(d.options(36).unwrap().subsets, 10, "at most 10 subsets");
        let plain = SartTvSettings {
            sweeps: 5,
            tv_step: 0.0,
        };
        assert_eq!(
            plain.options(1).unwrap().tv,
            None,
            "TV step 0 is plain SART"
        );
        for (sweeps, tv_step) in [(0, 0.2), (20, -0.1), (20, f64::NAN), (20_000, 0.2)] {
            let e = SartTvSettings { sweeps, tv_step }
                .options(1)
                .unwrap_err()
                .to_string();
            assert!(e.contains("SART-TV"), "{e}");
        }
    }
}
