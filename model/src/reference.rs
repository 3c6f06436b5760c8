//! The views a reconstruction is fitted to: each projection with its geometry, and the
//! checks every method runs on them first.

use crate::error::{Result, ensure};
use tomograf_sim::{Pose, View};
#[cfg(test)]
use tomograf_sim::{Projector, Renderer, Volume};

/// One reference projection with its geometry.
#[derive(Debug, Clone)]
pub struct Reference {
    /// Where it was taken from.
    pub view: View,
    /// Its pose ξ.
    pub pose: Pose,
    /// Line integrals, `view.rows × view.cols`, row-major.
    pub image: Vec<f32>,
}

/// Checks references against each other and the grid: at least one, sizes consistent.
pub fn check_references(refs: &[Reference]) -> Result<()> {
    ensure!(
        !refs.is_empty(),
        "no reference projections (view count 0): give at least one"
    );
    for (i, r) in refs.iter().enumerate() {
        r.view.validate()?;
        ensure!(
            r.image.len() == r.view.rows * r.view.cols,
            "reference {i}: image has {} values but its view's detector is {}×{}",
            r.image.len(),
            r.view.rows,
            r.view.cols
        );
        ensure!(
            r.image.iter().all(|v| v.is_finite()),
            "reference {i}: image has non-finite values"
        );
    }
    Ok(())
}

/// AP and lateral references of attenuation `mu` (mm⁻¹) with sim's Siddon projector: a
/// 16 × 16 cone-beam detector of 6 mm pixels, source 400 mm and detector 600 mm from the
/// origin (for the tests of the methods that reconstruct from them).
#[cfg(test)]
pub(crate) fn test_references(mu: &Volume) -> Vec<Reference> {
    use tomograf_sim::{Beam, Detector, Geometry};
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 400.0,
            sid_mm: 600.0,
        },
        detector: Detector::new(16, 16, 6.0),
        isocentre: glam::DVec3::ZERO,
    };
    let r = Renderer::new(mu, Projector::Siddon).expect("a renderer");
    [Pose::AP, Pose::LATERAL]
        .iter()
        .map(|&p| {
            let view = g.view(p).expect("a view");
            Reference {
                view,
                pose: p,
                image: r.render(&view).expect("a projection").data,
            }
        })
        .collect()
}
