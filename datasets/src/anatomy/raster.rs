//! Rasterisation of primitives into label volumes.
//!
//! Every primitive has a world bounding box and is visited only over the voxels of that
//! box, slice by slice (z-slices in parallel). Shapes with an analytic row intersection
//! (sections, ellipsoids, z-cylinders) fill whole runs of a row at once; the others
//! (tapered tubes, rounded boxes, the couch) test each voxel centre. Later primitives
//! overwrite earlier ones, so the order of the primitive list is the priority order.

use super::shapes::Shape;
use glam::DVec3;
use rayon::prelude::*;

/// A shape with its material and structure labels.
#[derive(Debug, Clone)]
pub(crate) struct Prim {
    pub shape: Shape,
    pub mat: u8,
    pub st: u8,
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Prim {
    pub fn new(shape: Shape, mat: u8, st: u8) -> Self {
        let (lo, hi) = shape.bounds();
        Prim {
            shape,
            mat,
            st,
            lo,
            hi,
        }
    }
}

/// The voxel grid: dimensions, spacing and world position of voxel (0, 0, 0)'s centre
/// (identity direction).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Grid {
    pub dims: [usize; 3],
    pub spacing: DVec3,
    pub origin: DVec3,
}

impl Grid {
    /// Grid of `dims` voxels centred on the world origin.
    pub fn centred(dims: [usize; 3], spacing: DVec3) -> Self {
        let n = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
        Grid {
            dims,
            spacing,
            origin: -(n - 1.0) * 0.5 * spacing,
        }
    }
    pub fn coord(&self, axis: usize, i: usize) -> f64 {
        self.origin[axis] + i as f64 * self.spacing[axis]
    }
    /// Indices along `axis` whose voxel centres lie in `[lo, hi]`.
    pub fn range(&self, axis: usize, lo: f64, hi: f64) -> Option<(usize, usize)> {
        let (o, s, n) = (self.origin[axis], self.spacing[axis], self.dims[axis]);
        let a = ((lo - o) / s).ceil().max(0.0);
        let b = ((hi - o) / s).floor().min(n as f64 - 1.0);
        (a <= b).then_some((a as usize, b as usize))
    }
}

/// The LidcCropped field of view: slices outside `[z0, z1]` and voxels farther than
/// `radius` from the z axis are padding.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Crop {
    pub z0: f64,
    pub z1: f64,
    pub radius: f64,
}

/// Paints `prims` in order into material and structure label volumes (`i` fastest).
/// Voxels no primitive covers keep `background`; voxels outside `crop` get `padding`.
pub(crate) fn rasterize(
    grid: &Grid,
    prims: &[Prim],
    background: (u8, u8),
    crop: Option<(Crop, (u8, u8))>,
) -> (Vec<u8>, Vec<u8>) {
    let [nx, ny, nz] = grid.dims;
    let plane = nx * ny;
    let mut mats = vec![background.0; plane * nz];
    let mut sts = vec![background.1; plane * nz];
    mats.par_chunks_mut(plane)
        .zip(sts.par_chunks_mut(plane))
        .enumerate()
        .for_each(|(k, (pm, ps))| {
            let z = grid.coord(2, k);
            for prim in prims {
                if z < prim.lo.z || z > prim.hi.z {
                    continue;
                }
                paint(grid, prim, z, pm, ps);
            }
            if let Some((c, (m, s))) = crop {
                let outside_z = z < c.z0 || z > c.z1;
                for j in 0..ny {
                    let y = grid.coord(1, j);
                    for i in 0..nx {
                        let x = grid.coord(0, i);
                        if outside_z || x * x + y * y > c.radius * c.radius {
                            pm[i + nx * j] = m;
                            ps[i + nx * j] = s;
                        }
                    }
                }
            }
        });
    (mats, sts)
}

fn paint(grid: &Grid, prim: &Prim, z: f64, pm: &mut [u8], ps: &mut [u8]) {
    let nx = grid.dims[0];
    let Some((j0, j1)) = grid.range(1, prim.lo.y, prim.hi.y) else {
        return;
    };
    let Some((i0, i1)) = grid.range(0, prim.lo.x, prim.hi.x) else {
        return;
    };
    let mut fill = |j: usize, lo: f64, hi: f64| {
        if let Some((a, b)) = grid.range(0, lo, hi) {
            let row = nx * j;
            pm[row + a..=row + b].fill(prim.mat);
            ps[row + a..=row + b].fill(prim.st);
        }
    };
    match &prim.shape {
        Shape::Section(s) => {
            let Some(key) = s.at(z) else { return };
            for j in j0..=j1 {
                for (lo, hi) in s.spans(&key, grid.coord(1, j), z).iter() {
                    fill(j, lo, hi);
                }
            }
        }
        Shape::Solid(solid) => {
            for j in j0..=j1 {
                let row = DVec3::new(0.0, grid.coord(1, j), z);
                if let Some((lo, hi)) = solid.span(row, DVec3::X) {
                    fill(j, lo, hi);
                }
            }
        }
        Shape::Nothing => {}
        shape => {
            for j in j0..=j1 {
                let y = grid.coord(1, j);
                let row = nx * j;
                for i in i0..=i1 {
                    if shape.contains(DVec3::new(grid.coord(0, i), y, z)) {
                        pm[row + i] = prim.mat;
                        ps[row + i] = prim.st;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::shapes::{Dome, SecKey, Section};
    use glam::DMat3;

    fn count(grid: &Grid, shape: Shape) -> (usize, usize) {
        let (m, _) = rasterize(grid, &[Prim::new(shape.clone(), 1, 1)], (0, 0), None);
        let painted = m.iter().filter(|&&v| v == 1).count();
        // Brute force over every voxel centre.
        let mut brute = 0;
        for k in 0..grid.dims[2] {
            for j in 0..grid.dims[1] {
                for i in 0..grid.dims[0] {
                    let p = DVec3::new(grid.coord(0, i), grid.coord(1, j), grid.coord(2, k));
                    brute += shape.contains(p) as usize;
                }
            }
        }
        (painted, brute)
    }

    #[test]
    fn analytic_rows_match_point_tests() {
        let grid = Grid::centred([40, 36, 30], DVec3::new(1.3, 1.1, 1.7));
        let rot = DMat3::from_euler(glam::EulerRot::XYZ, 0.3, -0.5, 0.9);
        let shapes = [
            Shape::ellipsoid(DVec3::new(2.0, -1.0, 3.0), DVec3::new(14.0, 9.0, 6.0), rot),
            Shape::z_cylinder(1.0, 2.0, 12.0, 7.0, -10.0, 8.0),
            Shape::Section(Section {
                keys: vec![
                    SecKey {
                        z: -20.0,
                        cx: 0.0,
                        cy: 0.0,
                        a: 20.0,
                        ba: 15.0,
                        bp: 10.0,
                        xm: 2.0,
                    },
                    SecKey {
                        z: 20.0,
                        cx: 3.0,
                        cy: -2.0,
                        a: 8.0,
                        ba: 6.0,
                        bp: 12.0,
                        xm: 4.0,
                    },
                ],
                p_ant: 2.0,
                p_post: 3.0,
                side: 1.0,
                dome: Some(Dome {
                    zb: -15.0,
                    height: 12.0,
                    cx: 8.0,
                    cy: 0.0,
                    rx: 10.0,
                    ry: 12.0,
                }),
            }),
        ];
        for s in shapes {
            let (painted, brute) = count(&grid, s.clone());
            assert!(brute > 100, "{s:?}");
            // Rows are filled from the analytic interval: the same voxels up to round-off.
            assert!(
                painted.abs_diff(brute) <= brute / 200 + 2,
                "{painted} vs {brute}"
            );
        }
    }

    #[test]
    fn later_primitives_overwrite_earlier_ones() {
        let grid = Grid::centred([10, 10, 10], DVec3::ONE);
        let big = Prim::new(
            Shape::ellipsoid(DVec3::ZERO, DVec3::splat(4.0), DMat3::IDENTITY),
            1,
            1,
        );
        let small = Prim::new(
            Shape::ellipsoid(DVec3::ZERO, DVec3::splat(1.0), DMat3::IDENTITY),
            2,
            2,
        );
        let (m, _) = rasterize(&grid, &[big.clone(), small.clone()], (0, 0), None);
        assert!(m.contains(&2));
        let (m, _) = rasterize(&grid, &[small, big], (0, 0), None);
        assert!(!m.contains(&2));
    }
}
