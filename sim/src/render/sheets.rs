//! Detector rows traced as ray sheets ([`crate::trace::sheet`]): where a view's rows are
//! sheets along the grid's fastest axis (AP and PA views of an axial CT), each row is traced
//! at once, line integrals or, over a composition, mass thickness per material.

use super::{Renderer, Sums};
use crate::ray::GridRay;
use crate::trace::packet;
use crate::trace::sheet::Sheet;

impl<S: Sums> Renderer<'_, S> {
    /// The line integrals of `rays` (detector rows of `cols` rays, clipped), one row of
    /// `out` each, or with `materials` (`Some(k)`) their Σρ·ℓ of materials `0..k` (k per
    /// pixel), if every row's rays form a [`Sheet`] along the grid's fastest axis (or all
    /// miss); `false` (with `out` partly written) otherwise. Sheets along the other axes read
    /// their voxel lines a row or a slice apart, and measured slower than the packets
    /// (lateral views on an Intel Xeon with AVX2: 0.65–0.82×), so they are left to them.
    pub(super) fn trace_sheets(
        &self,
        rays: &[Option<GridRay>],
        cols: usize,
        materials: Option<usize>,
        out: &mut [f64],
    ) -> bool {
        let Some(bounds) = self.bounds.as_ref() else {
            return false;
        };
        let (field, dims) = (self.mu.data(), self.mu.dims());
        let per_pixel = materials.unwrap_or(1);
        for (rays, px) in rays.chunks(cols).zip(out.chunks_mut(cols * per_pixel)) {
            match Sheet::new(rays, dims, bounds) {
                Some(mut sheet) if sheet.axis() == 0 => {
                    if let Some(rows) = self.rows.as_deref() {
                        sheet.skip_zeros(rows, bounds);
                    }
                    match materials {
                        None => sheet.line_integrals(field, dims, bounds, px),
                        Some(k) => sheet.material_sums(field, dims, bounds, k, px),
                    }
                }
                None if rays.iter().all(Option::is_none) => px.fill(0.0),
                _ => return false,
            }
        }
        true
    }
}

/// Whether renderers trace ray sheets ([`Renderer::with_sheets`]) unless told otherwise:
/// where the CPU has a SIMD kernel (AVX2 or AVX-512). Measured (docs/projector.md, "Ray
/// sheets" and "Session 27"): with AVX2 the sheets render a chest CT's AP view 1.4–2.1×
/// faster than the packets (AMD EPYC; an Intel Xeon held to AVX2); with AVX-512, eight rays
/// at a time, 1.18× (Intel Xeon, 2 threads), and column sheets 1.3–2.4× at other angles;
/// the portable kernel is 4.7× slower than the scalar tracer (the same Xeon held to no
/// SIMD), so without SIMD they stay off. `TG_SHEETS=on` or `=off` (read once) overrides it,
/// for measuring.
pub(super) fn sheets_by_default() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| match std::env::var("TG_SHEETS").as_deref() {
        Ok("on") => true,
        Ok("off") => false,
        _ => packet::kernel().is_some(),
    })
}
