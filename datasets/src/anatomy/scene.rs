//! The primitive list under construction, and geometric helpers for building it.

use super::raster::Prim;
use super::shapes::Shape;
use super::tissue::Material;
use super::{Structure, Tissue};
use glam::{DMat3, DVec3};

/// Primitives and materials under construction.
pub(crate) struct Scene {
    pub prims: Vec<Prim>,
    pub materials: Vec<Material>,
}

impl Scene {
    pub fn new() -> Self {
        Scene {
            prims: Vec::new(),
            materials: Tissue::ALL.iter().map(|&t| Material::of(t)).collect(),
        }
    }
    /// Registers a material and returns its index.
    pub fn material(&mut self, m: Material) -> u8 {
        assert!(self.materials.len() < 255, "too many materials");
        self.materials.push(m);
        (self.materials.len() - 1) as u8
    }
    /// Adds a shape with the default material of `tissue`.
    pub fn add(&mut self, shape: Shape, tissue: Tissue, st: Structure) {
        self.prims.push(Prim::new(shape, tissue as u8, st as u8));
    }
    /// Adds a shape with a registered material.
    pub fn add_mat(&mut self, shape: Shape, mat: u8, st: Structure) {
        self.prims.push(Prim::new(shape, mat, st as u8));
    }
    /// Adds a tube along a polyline with per-point radii.
    pub fn path(&mut self, pts: &[DVec3], radii: &[f64], tissue: Tissue, st: Structure) {
        for (w, r) in pts.windows(2).zip(radii.windows(2)) {
            self.add(
                Shape::Tube {
                    a: w[0],
                    b: w[1],
                    ra: r[0],
                    rb: r[1],
                },
                tissue,
                st,
            );
        }
    }
}

/// Catmull–Rom spline through `ctrl`, sampled about every `step` mm; radii interpolated
/// linearly per control interval.
pub(crate) fn spline(ctrl: &[(DVec3, f64)], step: f64) -> (Vec<DVec3>, Vec<f64>) {
    let n = ctrl.len();
    let (mut pts, mut rs) = (vec![ctrl[0].0], vec![ctrl[0].1]);
    for i in 0..n.saturating_sub(1) {
        let p0 = ctrl[i.saturating_sub(1)].0;
        let (p1, p2) = (ctrl[i].0, ctrl[i + 1].0);
        let p3 = ctrl[(i + 2).min(n - 1)].0;
        let m = ((p2 - p1).length() / step).ceil().max(1.0) as usize;
        for k in 1..=m {
            let t = k as f64 / m as f64;
            let (t2, t3) = (t * t, t * t * t);
            let p = 0.5
                * (2.0 * p1
                    + (p2 - p0) * t
                    + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2
                    + (3.0 * p1 - p0 - 3.0 * p2 + p3) * t3);
            pts.push(p);
            rs.push(ctrl[i].1 + (ctrl[i + 1].1 - ctrl[i].1) * t);
        }
    }
    (pts, rs)
}

/// Rotation whose columns are `x` (normalised), a perpendicular, and their cross product.
pub(crate) fn frame(x: DVec3, hint: DVec3) -> DMat3 {
    let x = x.normalize();
    let y = hint.cross(x).normalize_or(x.any_orthonormal_vector());
    let z = x.cross(y);
    DMat3::from_cols(x, y, z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spline_passes_through_control_points() {
        let ctrl = [
            (DVec3::ZERO, 1.0),
            (DVec3::new(10.0, 0.0, 0.0), 2.0),
            (DVec3::new(10.0, 10.0, 0.0), 3.0),
        ];
        let (pts, rs) = spline(&ctrl, 2.0);
        assert_eq!(pts.len(), rs.len());
        assert!(pts.iter().any(|p| (*p - ctrl[1].0).length() < 1e-9));
        assert!((pts.last().unwrap().distance(ctrl[2].0)) < 1e-9);
        assert_eq!(*rs.last().unwrap(), 3.0);
    }

    #[test]
    fn frames_are_orthonormal() {
        for (x, hint) in [(DVec3::new(1.0, 2.0, 3.0), DVec3::Z), (DVec3::Z, DVec3::Z)] {
            let f = frame(x, hint);
            assert!((f.transpose() * f).abs_diff_eq(DMat3::IDENTITY, 1e-12));
            assert!(f.x_axis.dot(x.normalize()) > 1.0 - 1e-12);
        }
    }
}
