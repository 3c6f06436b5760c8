//! Classical reconstruction of a projection folder (`tomograf reconstruct-classical`):
//! FDK, SART, SART-TV or SIRT ([`tomograf_recon`]) from the images of
//! [`tomograf_scene::projections::read_projections`], to a NIfTI volume in HU (or mu).

use anyhow::{Context, Result, bail};
use glam::DVec3;
use std::path::PathBuf;
use tomograf_datasets::nifti;
use tomograf_recon::{self as recon, FdkOptions, SartOptions, TvOptions};
use tomograf_scene::Progress;
use tomograf_scene::projections::read_projections;
use tomograf_sim::{Pose, Projection, View, Volume};

/// A classical reconstruction method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Feldkamp–Davis–Kress filtered backprojection (circular cone-beam orbits).
    Fdk,
    /// SART with ordered subsets.
    Sart,
    /// SART followed by TV steps each iteration (ASD-POCS style).
    SartTv,
    /// SIRT (one subset holding every view).
    Sirt,
}

impl Method {
    /// The method's name in reports.
    pub fn label(self) -> &'static str {
        match self {
            Self::Fdk => "FDK",
            Self::Sart => "SART",
            Self::SartTv => "SART-TV",
            Self::Sirt => "SIRT",
        }
    }
}

/// The output grid.
#[derive(Debug, Clone, PartialEq)]
pub enum Grid {
    /// The projected volume's grid, as the input folder records it.
    Recorded,
    /// The grid of this NIfTI file (dims, spacing, origin, direction).
    Like(PathBuf),
    /// `dims` voxels of `spacing` mm, centred on the set-up's isocentre.
    Centred { dims: [usize; 3], spacing_mm: f64 },
}

/// What to reconstruct, how, and where to write it.
#[derive(Debug, Clone)]
pub struct Classical {
    /// A projection folder ([`read_projections`]).
    pub input: PathBuf,
    /// The NIfTI volume to write.
    pub output: PathBuf,
    pub method: Method,
    /// The view indices to use (empty: all).
    pub views: Vec<usize>,
    pub grid: Grid,
    /// Ramp-filter window and angular weighting (FDK).
    pub fdk: FdkOptions,
    /// Iteration cap, ordered subsets, relaxation λ in (0, 2), and the relative residual
    /// improvement per iteration under which to stop (SART, SART-TV, SIRT; SIRT uses one
    /// subset whatever `subsets` says).
    pub iterations: usize,
    pub subsets: usize,
    pub relaxation: f64,
    pub tolerance: f64,
    /// TV steps per iteration and their size relative to the data update (SART-TV).
    pub tv: TvOptions,
    /// Effective energy (keV) whose water attenuation converts mu to HU.
    pub energy_kev: f64,
    /// Write linear attenuation (mm⁻¹) instead of HU.
    pub mu: bool,
}

/// The largest voxel a reconstruction grid may have, mm (10 m: beyond any scanner, and far
/// inside what a NIfTI header and f32 coordinates hold); every volume has the same bound.
pub use tomograf_sim::volume::MAX_SPACING_MM;

/// Peak resident memory of a reconstruction (bytes) onto a grid of `voxels` from views of
/// `pixels` in all: `base + a · 4·voxels + b · 4·pixels` (the f32 volume and images), with
/// the factors of each method fitted to `/usr/bin/time -v` peaks at 96³ and 192³ from 36
/// and 144 views of 128², and checked at other sizes (docs/reliability.md, "Memory
/// budget": within 25 %).
pub fn peak_bytes(method: Method, voxels: usize, pixels: usize) -> u128 {
    let (base_mib, a, b) = match method {
        Method::Fdk => (19.0, 1.7, 4.4),
        Method::Sart => (46.0, 6.3, 8.8),
        Method::Sirt => (45.0, 6.6, 8.8),
        Method::SartTv => (41.0, 7.7, 8.3),
    };
    (base_mib * (1u64 << 20) as f64 + a * 4.0 * voxels as f64 + b * 4.0 * pixels as f64) as u128
}

/// Reconstructs and writes `c.output` (iterative methods: stage "iteration" of
/// `progress`, the relative residual as its message).
pub fn reconstruct_classical(c: &Classical, progress: &dyn Progress) -> Result<()> {
    // The output is checked before the work, not after it.
    let text = c.output.to_string_lossy();
    if c.output.is_dir() || text.ends_with('/') {
        bail!(
            "-o {text}: that is a folder; give the NIfTI file to write, e.g. {}",
            c.output.join("recon.nii.gz").display()
        );
    }
    // So is the energy that turns μ into HU.
    if !c.mu {
        tomograf_sim::attenuation::mu_water_per_mm(c.energy_kev).context("--energy-kev")?;
    }
    if let Some(dir) = c.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the output folder {}", dir.display()))?;
    }
    let input = read_projections(&c.input)?;
    let pick: Vec<usize> = if c.views.is_empty() {
        (0..input.views.len()).collect()
    } else {
        c.views.clone()
    };
    if let Some(&i) = pick.iter().find(|&&i| i >= input.views.len()) {
        bail!(
            "--views: view {i} does not exist (the input has {})",
            input.views.len()
        );
    }
    if let Some(i) = pick
        .iter()
        .enumerate()
        .find_map(|(k, i)| pick[..k].contains(i).then_some(i))
    {
        bail!("--views: view {i} is listed more than once; each view counts once");
    }
    let images: Vec<Projection> = pick.iter().map(|&i| input.images[i].clone()).collect();
    let views: Vec<View> = pick.iter().map(|&i| input.views[i]).collect();
    let template = match (&c.grid, input.grid) {
        (Grid::Like(p), _) => nifti::read_nifti(p)?.map(|_| 0.0)?,
        (&Grid::Centred { dims, spacing_mm }, _) => {
            if !(spacing_mm.is_finite() && spacing_mm > 0.0 && spacing_mm <= MAX_SPACING_MM) {
                let shown = if spacing_mm.abs() < 1e6 {
                    spacing_mm.to_string()
                } else {
                    format!("{spacing_mm:e}")
                };
                bail!("--spacing {shown}: give a voxel size in (0, {MAX_SPACING_MM}] mm");
            }
            let count = tomograf_sim::volume::checked_voxel_count(dims)
                .context("--dims: the output grid")?;
            let centre = input.geometry.map_or(DVec3::ZERO, |g| g.isocentre);
            Volume::centred(dims, DVec3::splat(spacing_mm), centre, vec![0.0; count])?
        }
        (Grid::Recorded, Some(g)) => g,
        (Grid::Recorded, None) => bail!(
            "no output grid: {} records none; give --like ct.nii.gz or --dims",
            c.input.display()
        ),
    };
    let pixels: usize = images.iter().map(|p| p.data.len()).sum();
    let d = template.dims();
    let peak = peak_bytes(c.method, d[0] * d[1] * d[2], pixels);
    tomograf_sim::memory::check(
        peak,
        &format!(
            "{} onto a {}×{}×{} grid from {} views (--dims, --like or --views set both)",
            c.method.label(),
            d[0],
            d[1],
            d[2],
            views.len()
        ),
    )?;
    progress.note(&format!(
        "estimated peak memory {:.0} MiB",
        peak as f64 / (1u64 << 20) as f64
    ));
    let volume = match c.method {
        Method::Fdk => {
            let (Some(g), Some(poses)) = (input.geometry, &input.poses) else {
                bail!(
                    "FDK needs the set-up's geometry and every view's pose, which {} does not hold; use --method sart",
                    c.input.display()
                );
            };
            let poses: Vec<Pose> = pick.iter().map(|&i| poses[i]).collect();
            recon::fdk(&images, &g, &poses, &c.fdk, &template)?
        }
        m => {
            let opts = SartOptions {
                iterations: c.iterations,
                subsets: if m == Method::Sirt { 1 } else { c.subsets },
                relaxation: c.relaxation,
                nonnegative: true,
                tolerance: c.tolerance,
                tv: (m == Method::SartTv).then_some(c.tv),
            };
            progress.start("iteration", c.iterations as u64, 0);
            let rec = recon::sart_tv_with_progress(&images, &views, &opts, &template, |r| {
                progress.set(r.iteration as u64);
                progress.set_message(&format!("residual {:.4}", r.residual));
            });
            progress.finish();
            let rec = rec?;
            if let Some(r) = rec.history.last() {
                progress.note(&format!(
                    "{} iterations, relative residual {:.4}",
                    r.iteration, r.residual
                ));
            }
            rec.volume
        }
    };
    let out = if c.mu {
        volume
    } else {
        recon::mu_to_hu_at_kev(&volume, c.energy_kev)?
    };
    nifti::write_nifti(&c.output, &out)?;
    progress.note(&format!(
        "wrote {} ({} from {} views, {})",
        c.output.display(),
        c.method.label(),
        views.len(),
        if c.mu { "mm⁻¹" } else { "HU" }
    ));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use tomograf_sim::phantom::{Component, Phantom, Shape};
    use tomograf_sim::{Beam, Detector, Geometry};

    /// A dataset-style folder (views.json + projections.npy written by the data-set
    /// writer) of a water ball, reconstructed by FDK and SIRT: the NIfTI
    /// read back holds ≈ 0 HU at the centre and −1000 HU in the corners. Tolerance
    /// 60 HU (6 % of the water–air step): 16³ voxels of 10 mm and 36 or 8 views. (SIRT,
    /// not ordered-subset SART: with 8 views of analytic, hence voxel-inconsistent, data
    /// SART at λ = 1 drifts in its null space as iterations go on — −90 HU at the centre
    /// after 20 — while SIRT stays within 10 HU.)
    #[test]
    fn reconstructs_a_dataset_folder() {
        let dir = tempfile::tempdir().unwrap();
        let mu_w = tomograf_sim::attenuation::mu_water_per_mm(60.0).unwrap();
        let geometry = Geometry {
            beam: Beam::Cone {
                sad_mm: 1000.0,
                sid_mm: 1500.0,
            },
            detector: Detector::new(32, 32, 8.0),
            isocentre: DVec3::ZERO,
        };
        let poses: Vec<Pose> = (0..36).map(|i| Pose::new(10.0 * i as f64, 0.0)).collect();
        let views = geometry.views(&poses).unwrap();
        let ball = Phantom {
            background_hu: -1000.0,
            components: vec![Component {
                name: "water",
                shape: Shape::Ellipsoid {
                    centre: DVec3::ZERO,
                    semi_axes: DVec3::splat(50.0),
                    rotation_z_deg: 0.0,
                },
                delta_hu: 1000.0,
            }],
        };
        let mut stack = Vec::new();
        for v in &views {
            for i in 0..v.rows * v.cols {
                let ray = v.ray((i / v.cols) as f64, (i % v.cols) as f64);
                stack.push(ball.line_integral(&ray, mu_w) as f32);
            }
        }
        tomograf_datasets::image::write_npy(
            &dir.path().join("projections.npy"),
            &stack,
            &[36, 32, 32],
        )
        .unwrap();
        let json = serde_json::json!({"geometry": geometry, "poses": poses, "views": views});
        std::fs::write(dir.path().join("views.json"), json.to_string()).unwrap();
        for (method, picks) in [
            (Method::Fdk, vec![]),
            (Method::Sirt, vec![0, 4, 9, 13, 18, 22, 27, 31]),
        ] {
            let out = dir.path().join(format!("{method:?}.nii.gz"));
            let c = Classical {
                input: dir.path().to_path_buf(),
                output: out.clone(),
                method,
                views: picks,
                grid: Grid::Centred {
                    dims: [16; 3],
                    spacing_mm: 10.0,
                },
                fdk: FdkOptions::default(),
                iterations: 20,
                subsets: 10,
                relaxation: 1.0,
                tolerance: 0.0,
                tv: TvOptions {
                    iterations: 10,
                    step: 0.2,
                },
                energy_kev: 60.0,
                mu: false,
            };
            reconstruct_classical(&c, &tomograf_scene::Silent).unwrap();
            let v = nifti::read_nifti(&out).unwrap();
            let centre = v.get(8, 8, 8);
            let corner = v.get(0, 0, 0);
            assert!(centre.abs() < 60.0, "{method:?}: centre {centre} HU");
            assert!(
                (corner + 1000.0).abs() < 60.0,
                "{method:?}: corner {corner} HU"
            );
        }
    }
}
