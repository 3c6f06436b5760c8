//! What the projector examples share: a CT read as mu, and the view geometry of
//! `scripts/compare_plastimatch.py` (cone beam, SAD 1000 mm, SID 1500 mm, 256² detector of
//! 2.6 mm pitch, isocentre at the volume's centre).

use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::{Beam, Detector, Geometry, Volume};

/// The CT at `path` (HU) as mu at 60 keV (mm⁻¹).
pub fn mu(path: &str) -> Volume {
    let hu = tomograf_datasets::nifti::read_nifti(std::path::Path::new(path)).expect("reads");
    Attenuation::hounsfield_at_kev(60.0)
        .unwrap()
        .to_mu(hu)
        .unwrap()
}

/// The comparison's geometry over `mu`.
pub fn geometry(mu: &Volume) -> Geometry {
    Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(256, 256, 2.6),
        isocentre: mu.centre(),
    }
}

/// `N` from the environment (how many timed repeats), or `default`; at least 1.
pub fn repeats(default: usize) -> usize {
    std::env::var("N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
        .max(1)
}
