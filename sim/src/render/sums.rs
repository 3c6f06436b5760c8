//! What a [`Renderer`](super::Renderer) sums along each ray — its type parameter.
//!
//! * [`LineIntegrals`]: ∫mu ds over an attenuation volume (mu in mm⁻¹, so the sum is
//!   dimensionless), one value per pixel; [`Renderer::render`](super::Renderer::render).
//! * [`MassThicknesses`]: Σρ·ℓ per material over a packed
//!   [`Composition`](crate::composition::Composition) (g/cm³ · mm while tracing, g/cm² in
//!   the image), `materials` values per pixel;
//!   [`Renderer::mass_thickness`](super::Renderer::mass_thickness).
//!
//! The tracers are shared; the type decides how the field is read (mu, or material index
//! and density) and which image the renderer can make, so that asking a composition for
//! line integrals is a compile error rather than a run-time one.

/// What is summed along a ray: [`LineIntegrals`] or [`MassThicknesses`] (sealed).
pub trait Sums: sealed::Sealed + std::fmt::Debug + Clone + Send + Sync + 'static {
    /// Whether the field holds packed per-voxel materials (one sum per material) rather
    /// than mu (one sum).
    const PER_MATERIAL: bool;
}

/// ∫mu ds per pixel over an attenuation volume.
#[derive(Debug, Clone, Copy)]
pub enum LineIntegrals {}

/// Σρ·ℓ per material per pixel over a composition.
#[derive(Debug, Clone, Copy)]
pub enum MassThicknesses {}

impl Sums for LineIntegrals {
    const PER_MATERIAL: bool = false;
}

impl Sums for MassThicknesses {
    const PER_MATERIAL: bool = true;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::LineIntegrals {}
    impl Sealed for super::MassThicknesses {}
}
