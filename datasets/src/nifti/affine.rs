//! NIfTI voxel-to-world transforms and their conversion to tomograf's LPS grid
//! description (spacing, direction, origin).
//!
//! NIfTI maps voxel indices `(i, j, k)` to RAS millimetres (+x Right, +y Anterior, +z
//! Superior) by one of three methods, chosen in this order:
//! 1. `sform_code > 0`: the general affine in `srow_x/y/z`;
//! 2. `qform_code > 0`: rotation from the quaternion `(b, c, d)`, voxel size `pixdim[1..=3]`,
//!    the third axis flipped when `qfac = pixdim[0] < 0`, translation `quatern_x/y/z`;
//! 3. otherwise: `diag(pixdim[1..=3])`, zero translation.
//!
//! LPS is RAS with x and y negated, so the LPS affine is the RAS one with its first two
//! rows negated.

use glam::{DMat3, DQuat, DVec3};
use nifti::NiftiHeader;

/// `world = linear · (i, j, k) + translation`, in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Affine {
    /// Columns are the world displacement of one voxel step along `i`, `j`, `k`.
    pub linear: DMat3,
    /// World position of the centre of voxel `(0, 0, 0)`.
    pub translation: DVec3,
}

/// Largest |cos| allowed between two index axes before the grid counts as sheared.
pub(crate) const SHEAR_TOLERANCE: f64 = 1e-4;

/// RAS ↔ LPS: negate x and y (its own inverse).
const FLIP_XY: DVec3 = DVec3::new(-1.0, -1.0, 1.0);

impl Affine {
    /// The same map expressed in the other of RAS/LPS (negates the first two rows).
    pub fn flip_xy(self) -> Self {
        Self {
            linear: DMat3::from_diagonal(FLIP_XY) * self.linear,
            translation: self.translation * FLIP_XY,
        }
    }
}

/// The voxel-to-RAS affine of a header, and the name of the method used. Errors are
/// descriptions of what is wrong (the caller adds the file name).
pub(crate) fn ras_affine(h: &NiftiHeader) -> Result<(Affine, &'static str), String> {
    if h.sform_code > 0 {
        let col = |c: usize| {
            DVec3::new(
                f64::from(h.srow_x[c]),
                f64::from(h.srow_y[c]),
                f64::from(h.srow_z[c]),
            )
        };
        let a = Affine {
            linear: DMat3::from_cols(col(0), col(1), col(2)),
            translation: col(3),
        };
        if !(a.linear.is_finite() && a.translation.is_finite()) {
            return Err("the sform affine (srow_x/y/z) contains NaN or infinite values".into());
        }
        Ok((a, "sform"))
    } else if h.qform_code > 0 {
        let d = voxel_size(h, "qform")?;
        let [b, c, dq] = [h.quatern_b, h.quatern_c, h.quatern_d].map(f64::from);
        let t = DVec3::new(
            f64::from(h.quatern_x),
            f64::from(h.quatern_y),
            f64::from(h.quatern_z),
        );
        if !([b, c, dq].iter().all(|v| v.is_finite()) && t.is_finite()) {
            return Err("the qform quaternion or offset contains NaN or infinite values".into());
        }
        let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
        let r = quaternion_matrix(b, c, dq);
        let linear = r * DMat3::from_diagonal(DVec3::new(d.x, d.y, d.z * qfac));
        Ok((
            Affine {
                linear,
                translation: t,
            },
            "qform",
        ))
    } else {
        let d = voxel_size(h, "pixdim-only (no sform or qform)")?;
        Ok((
            Affine {
                linear: DMat3::from_diagonal(d),
                translation: DVec3::ZERO,
            },
            "pixdim-only",
        ))
    }
}

/// `pixdim[1..=3]`, which must be finite and > 0 for the qform and pixdim-only methods.
fn voxel_size(h: &NiftiHeader, method: &str) -> Result<DVec3, String> {
    for i in 1..=3 {
        let p = f64::from(h.pixdim[i]);
        if !(p.is_finite() && p > 0.0) {
            return Err(format!(
                "pixdim[{i}] = {p}: the voxel size must be finite and > 0 for the {method} transform"
            ));
        }
    }
    Ok(DVec3::new(
        f64::from(h.pixdim[1]),
        f64::from(h.pixdim[2]),
        f64::from(h.pixdim[3]),
    ))
}

/// Rotation matrix of the unit quaternion `(a, b, c, d)` with `a` implied, exactly as in
/// the NIfTI-1 standard (`a = sqrt(1 − b² − c² − d²)`, or `a = 0` with `(b, c, d)`
/// renormalised when that is not positive).
pub(crate) fn quaternion_matrix(b: f64, c: f64, d: f64) -> DMat3 {
    let s = b * b + c * c + d * d;
    let (a, b, c, d) = if 1.0 - s < 1e-7 {
        let n = s.sqrt();
        (0.0, b / n, c / n, d / n)
    } else {
        ((1.0 - s).sqrt(), b, c, d)
    };
    // Rows of the standard's R, transposed into glam's column-major constructor.
    DMat3::from_cols(
        DVec3::new(
            a * a + b * b - c * c - d * d,
            2.0 * (b * c + a * d),
            2.0 * (b * d - a * c),
        ),
        DVec3::new(
            2.0 * (b * c - a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d + a * b),
        ),
        DVec3::new(
            2.0 * (b * d + a * c),
            2.0 * (c * d - a * b),
            a * a + d * d - c * c - b * b,
        ),
    )
}

/// Splits a linear part into voxel size (column norms, mm) and an orthonormal direction
/// matrix, refusing degenerate or sheared grids.
pub(crate) fn decompose(linear: DMat3, method: &str) -> Result<(DVec3, DMat3), String> {
    let cols = [linear.x_axis, linear.y_axis, linear.z_axis];
    let mut unit = [DVec3::ZERO; 3];
    let mut spacing = [0.0; 3];
    for (a, c) in cols.iter().enumerate() {
        let n = c.length();
        if !(n.is_finite() && n > 0.0) {
            return Err(format!(
                "the {method} affine is degenerate: index axis {a} has length {n} mm"
            ));
        }
        spacing[a] = n;
        unit[a] = *c / n;
    }
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let cos = unit[a].dot(unit[b]);
        if cos.abs() > SHEAR_TOLERANCE {
            return Err(format!(
                "the {method} affine is sheared: index axes {a} and {b} are not orthogonal \
                 (cos of their angle = {cos:.3e}, tolerance {SHEAR_TOLERANCE:e}); \
                 sheared voxel grids are not supported"
            ));
        }
    }
    Ok((
        DVec3::from_array(spacing),
        DMat3::from_cols(unit[0], unit[1], unit[2]),
    ))
}

/// Quaternion form of an orthonormal RAS direction matrix: `(b, c, d)` and `qfac`.
///
/// A reflection (determinant −1) is stored as `qfac = −1` with the third column negated,
/// as the standard prescribes; the quaternion is chosen with `a ≥ 0`.
pub(crate) fn quaternion_of(direction_ras: DMat3) -> ([f64; 3], f64) {
    let (rot, qfac) = if direction_ras.determinant() < 0.0 {
        let mut m = direction_ras;
        m.z_axis = -m.z_axis;
        (m, -1.0)
    } else {
        (direction_ras, 1.0)
    };
    let mut q = DQuat::from_mat3(&rot).normalize();
    if q.w < 0.0 {
        q = -q;
    }
    ([q.x, q.y, q.z], qfac)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_round_trip_including_near_half_turns() {
        let cases = [
            DMat3::IDENTITY,
            DMat3::from_diagonal(FLIP_XY),
            DMat3::from_rotation_z(0.3) * DMat3::from_rotation_x(-1.1),
            DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 3.1),
            DMat3::from_rotation_y(0.7) * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0)),
        ];
        for m in cases {
            let (bcd, qfac) = quaternion_of(m);
            let mut r = quaternion_matrix(bcd[0], bcd[1], bcd[2]);
            r.z_axis *= qfac;
            assert!(r.abs_diff_eq(m, 1e-7), "{m} -> {r}");
        }
    }

    #[test]
    fn shear_and_degenerate_are_refused() {
        let sheared = DMat3::from_cols(DVec3::X, DVec3::new(0.01, 1.0, 0.0), DVec3::Z);
        assert!(decompose(sheared, "sform").unwrap_err().contains("sheared"));
        let flat = DMat3::from_cols(DVec3::X, DVec3::ZERO, DVec3::Z);
        assert!(decompose(flat, "sform").unwrap_err().contains("degenerate"));
    }
}
