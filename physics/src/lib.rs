//! # tomograf-physics — what a real X-ray system adds to the projector
//!
//! The projector (`tomograf-sim`) gives path lengths and line integrals through a volume;
//! this crate turns them into what a detector records. Data flows one way:
//! [`spectrum`] (tube spectra, filtration, air kerma) → [`polychromatic`] (per-material
//! path lengths integrated over the spectrum) → [`scatter`] (the Monte Carlo and its fast
//! estimate, added to the primary) → [`detector`] (energy response, noise, blur, readout,
//! flat-field correction). [`acquisition`] joins them: a scene's physics as one value,
//! prepared once per volume and rendered view by view.
//!
//! The projector knows nothing of this crate: the compiler enforces that `tomograf-sim`
//! never imports a spectrum, a detector or scatter.
//!
//! Units: lengths in mm, attenuation in mm⁻¹, energies in keV, exposure in mA·s, CT values
//! in HU. World frame: DICOM LPS (+x patient left, +y posterior, +z head).

pub mod acquisition;
pub mod detector;
pub mod polychromatic;
pub mod scatter;
pub mod spectrum;
