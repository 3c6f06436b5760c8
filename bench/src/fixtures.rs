//! What the projector and acceleration benchmarks render: the analytic thorax as μ at
//! 60 keV, and a cone-beam view whose panel covers a 360 mm field.

use anyhow::Result;
use glam::DVec3;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::{Beam, Detector, Geometry, Pose, View, Volume};

/// The analytic thorax voxelised on `dims` voxels of `spacing` (mm), as μ (mm⁻¹) at 60 keV.
pub fn thorax_mu(dims: [usize; 3], spacing: [f64; 3]) -> Result<Volume> {
    let hu = Phantom::thorax().voxelize(dims, DVec3::from(spacing), DVec3::ZERO)?;
    Ok(Attenuation::hounsfield_at_kev(60.0)?.to_mu(hu)?)
}

/// A cone-beam view (SAD 1000, SID 1500) whose panel just covers a 360 mm field.
pub fn view(n: usize, pose: Pose) -> Result<View> {
    let pitch = 360.0 * 1.5 * 1.1 / n as f64;
    Ok(Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(n, n, pitch),
        isocentre: DVec3::ZERO,
    }
    .view(pose)?)
}
