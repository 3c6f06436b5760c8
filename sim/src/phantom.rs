//! A built-in analytic phantom: quadric shapes with additive HU, so that both a voxel
//! volume *and* exact analytic line integrals exist for it.
//!
//! HU adds up: a point's value is `background_hu + Σ delta_hu` over the shapes holding it.
//! Because `mu = mu_water·(1 + HU/1000)` is affine in HU and the built-in phantoms never
//! go below −1000 HU, the line integral of mu is `Σ mu_water·delta_hu/1000 · chord` —
//! independent of any voxel grid. Shapes are given in world LPS mm.
//!
//! Procedural anatomy (ribs, vessels, variation between patients) belongs to the data-set
//! generator; this phantom exists to make the projector's default job and its tests need
//! no download.

use crate::error::Result;
use crate::ray::Ray;
use crate::solid::{PlacedSolid, Solid};
use crate::volume::Volume;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// A closed quadric region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Ellipsoid with semi-axes along its local x, y, z (mm), rotated about +z.
    Ellipsoid {
        /// Centre, world mm.
        centre: DVec3,
        /// Semi-axes, mm.
        semi_axes: DVec3,
        /// Rotation about +z, degrees.
        rotation_z_deg: f64,
    },
    /// Elliptic cylinder along +z with semi-axes `(a, b)` in its local xy plane.
    Cylinder {
        /// Centre, world mm.
        centre: DVec3,
        /// Semi-axes in the local x and y, mm.
        semi_axes: [f64; 2],
        /// Half the length along z, mm.
        half_height: f64,
        /// Rotation about +z, degrees.
        rotation_z_deg: f64,
    },
}

impl Shape {
    /// The shape as a placed [`Solid`]: its chords, containment and bounds.
    pub fn placed(&self) -> PlacedSolid {
        let (solid, centre, deg) = match *self {
            Shape::Ellipsoid {
                centre,
                semi_axes,
                rotation_z_deg,
            } => (
                Solid::Ellipsoid { radii: semi_axes },
                centre,
                rotation_z_deg,
            ),
            Shape::Cylinder {
                centre,
                semi_axes,
                half_height,
                rotation_z_deg,
            } => (
                Solid::Cylinder {
                    radii: semi_axes,
                    height: 2.0 * half_height,
                },
                centre,
                rotation_z_deg,
            ),
        };
        PlacedSolid::rotated(solid, centre, DMat3::from_rotation_z(deg.to_radians()))
            .expect("the built-in phantoms' shapes have finite, positive sizes")
    }

    /// True if world point `p` is inside (boundary included).
    pub fn contains(&self, p: DVec3) -> bool {
        self.placed().contains(p)
    }

    /// Axis-aligned world bounding box `(min, max)`, mm.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.placed().bounds()
    }

    /// Length (mm) of the part of `ray` inside the shape, within `[t_min, t_max]`.
    pub fn chord(&self, ray: &Ray) -> f64 {
        self.placed().chord(ray)
    }
}

/// One shape and the HU it adds.
#[derive(Debug, Clone, PartialEq)]
pub struct Component {
    /// Human-readable name ("left lung").
    pub name: &'static str,
    /// Its region.
    pub shape: Shape,
    /// HU added inside it.
    pub delta_hu: f64,
}

/// An additive analytic phantom in HU.
#[derive(Debug, Clone, PartialEq)]
pub struct Phantom {
    /// Value outside every shape, HU.
    pub background_hu: f64,
    /// The shapes.
    pub components: Vec<Component>,
}

impl Phantom {
    /// A simplified adult thorax, centred on the world origin, about 330 × 230 × 320 mm:
    /// fat and muscle layers, two lungs (−820 HU) with a nodule, heart, contrast-filled
    /// aorta, vertebral column (700 HU), sternum, and a small dense marker at the
    /// patient's left, anterior, superior side (+x, −y, +z) that shows orientation.
    pub fn thorax() -> Self {
        let e = |c: [f64; 3], s: [f64; 3], rot: f64| Shape::Ellipsoid {
            centre: DVec3::from(c),
            semi_axes: DVec3::from(s),
            rotation_z_deg: rot,
        };
        let cyl = |c: [f64; 3], s: [f64; 2], h: f64| Shape::Cylinder {
            centre: DVec3::from(c),
            semi_axes: s,
            half_height: h,
            rotation_z_deg: 0.0,
        };
        let comp = |name, shape, delta_hu| Component {
            name,
            shape,
            delta_hu,
        };
        Self {
            background_hu: -1000.0,
            components: vec![
                comp(
                    "subcutaneous fat",
                    cyl([0.0, 0.0, 0.0], [165.0, 115.0], 160.0),
                    900.0,
                ),
                comp(
                    "muscle and soft tissue",
                    cyl([0.0, 0.0, 0.0], [150.0, 100.0], 160.0),
                    140.0,
                ),
                comp(
                    "right lung",
                    e([-75.0, -5.0, 20.0], [55.0, 70.0, 120.0], -8.0),
                    -860.0,
                ),
                comp(
                    "left lung",
                    e([75.0, -5.0, 20.0], [55.0, 70.0, 120.0], 8.0),
                    -860.0,
                ),
                comp(
                    "nodule",
                    e([-70.0, -20.0, 40.0], [6.0, 6.0, 6.0], 0.0),
                    800.0,
                ),
                comp(
                    "heart",
                    e([15.0, -30.0, -50.0], [50.0, 45.0, 55.0], 30.0),
                    10.0,
                ),
                comp(
                    "aorta (contrast)",
                    cyl([-10.0, 30.0, 40.0], [14.0, 14.0], 60.0),
                    160.0,
                ),
                comp(
                    "vertebral column",
                    cyl([0.0, 60.0, 0.0], [20.0, 16.0], 160.0),
                    660.0,
                ),
                comp(
                    "sternum",
                    cyl([0.0, -92.0, -10.0], [14.0, 6.0], 70.0),
                    500.0,
                ),
                comp(
                    "orientation marker",
                    e([100.0, -60.0, 120.0], [5.0, 5.0, 5.0], 0.0),
                    1000.0,
                ),
            ],
        }
    }

    /// A seeded variant of [`Phantom::thorax`]: body size ±15 % in-plane and ±10 % in
    /// length, lung size (breathing) ±12 %, heart position ±10 mm, and 0–3 lung nodules of
    /// 3–12 mm radius (+800 HU over lung) at random places inside the lungs. The same seed
    /// always gives the same phantom. A stand-in for patient-to-patient variation until the
    /// procedural anatomy generator exists; it has no ribs, vessels or arms.
    pub fn thorax_variant(seed: u64) -> Self {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut p = Self::thorax();
        let (sxy, sz) = (rng.random_range(0.85..1.15), rng.random_range(0.9..1.1));
        let lung = rng.random_range(0.88..1.12);
        let heart = DVec3::new(
            rng.random_range(-10.0..10.0),
            rng.random_range(-10.0..10.0),
            rng.random_range(-10.0..10.0),
        );
        let scale = DVec3::new(sxy, sxy, sz);
        for c in &mut p.components {
            let extra = if c.name.contains("lung") { lung } else { 1.0 };
            match &mut c.shape {
                Shape::Ellipsoid {
                    centre, semi_axes, ..
                } => {
                    *centre *= scale;
                    *semi_axes *= scale * extra;
                    if c.name == "heart" {
                        *centre += heart;
                    }
                }
                Shape::Cylinder {
                    centre,
                    semi_axes,
                    half_height,
                    ..
                } => {
                    *centre *= scale;
                    semi_axes[0] *= sxy * extra;
                    semi_axes[1] *= sxy * extra;
                    *half_height *= sz;
                }
            }
        }
        p.components.retain(|c| c.name != "nodule");
        let lungs: Vec<(DVec3, DVec3)> = p
            .components
            .iter()
            .filter_map(|c| match c.shape {
                Shape::Ellipsoid {
                    centre, semi_axes, ..
                } if c.name.contains("lung") => Some((centre, semi_axes)),
                _ => None,
            })
            .collect();
        for _ in 0..rng.random_range(0..=3) {
            let (centre, semi) = lungs[rng.random_range(0..lungs.len())];
            let radius = rng.random_range(3.0..12.0);
            // A point well inside the lung: within 60 % of each semi-axis.
            let u = DVec3::new(
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
            );
            p.components.push(Component {
                name: "nodule",
                shape: Shape::Ellipsoid {
                    centre: centre + u * semi * 0.8,
                    semi_axes: DVec3::splat(radius),
                    rotation_z_deg: 0.0,
                },
                delta_hu: 800.0,
            });
        }
        p
    }

    /// HU at world point `p`.
    pub fn value_hu(&self, p: DVec3) -> f64 {
        self.background_hu
            + self
                .components
                .iter()
                .filter(|c| c.shape.contains(p))
                .map(|c| c.delta_hu)
                .sum::<f64>()
    }

    /// Samples the phantom at voxel centres of an axis-aligned grid centred on `centre`
    /// (HU volume). Each component only visits the voxels of its bounding box.
    pub fn voxelize(&self, dims: [usize; 3], spacing: DVec3, centre: DVec3) -> Result<Volume> {
        let count = crate::volume::checked_voxel_count(dims)?;
        let half = (DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) - 1.0) * 0.5;
        let origin = centre - half * spacing;
        let mut data = vec![self.background_hu as f32; count];
        let slice = dims[0] * dims[1];
        let ranges: Vec<_> = self
            .components
            .iter()
            .map(|c| {
                let solid = c.shape.placed();
                let (lo, hi) = solid.bounds();
                let lo = ((lo - origin) / spacing).ceil().max(DVec3::ZERO);
                let hi = ((hi - origin) / spacing).floor();
                (c, solid, lo, hi)
            })
            .collect();
        data.par_chunks_mut(slice)
            .enumerate()
            .for_each(|(k, plane)| {
                for (c, solid, lo, hi) in &ranges {
                    let kf = k as f64;
                    if kf < lo.z || kf > hi.z {
                        continue;
                    }
                    let (j0, j1) = (lo.y as usize, (hi.y.min((dims[1] - 1) as f64)) as usize);
                    let (i0, i1) = (lo.x as usize, (hi.x.min((dims[0] - 1) as f64)) as usize);
                    if hi.y < 0.0 || hi.x < 0.0 {
                        continue;
                    }
                    for j in j0..=j1 {
                        for i in i0..=i1 {
                            let p = origin + DVec3::new(i as f64, j as f64, kf) * spacing;
                            if solid.contains(p) {
                                plane[i + dims[0] * j] += c.delta_hu as f32;
                            }
                        }
                    }
                }
            });
        Volume::new(dims, spacing, origin, DMat3::IDENTITY, data)
    }

    /// Exact ∫mu ds (dimensionless) along `ray` for `mu = mu_water·(1 + HU/1000)`, valid
    /// because the phantom never goes below −1000 HU (and `background_hu` is −1000).
    pub fn line_integral(&self, ray: &Ray, mu_water_per_mm: f64) -> f64 {
        debug_assert_eq!(self.background_hu, -1000.0);
        self.components
            .iter()
            .map(|c| mu_water_per_mm * c.delta_hu / 1000.0 * c.shape.chord(ray))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chords_of_unit_shapes() {
        let sphere = Shape::Ellipsoid {
            centre: DVec3::ZERO,
            semi_axes: DVec3::splat(10.0),
            rotation_z_deg: 0.0,
        };
        let ray = Ray::segment(DVec3::new(-100.0, 6.0, 0.0), DVec3::new(100.0, 6.0, 0.0));
        assert!((sphere.chord(&ray) - 16.0).abs() < 1e-12); // 2·sqrt(100 − 36)
        let cyl = Shape::Cylinder {
            centre: DVec3::ZERO,
            semi_axes: [10.0, 5.0],
            half_height: 3.0,
            rotation_z_deg: 90.0,
        };
        // Rotated by 90°: the 10 mm semi-axis lies along y.
        let ray = Ray::segment(DVec3::new(0.0, -50.0, 0.0), DVec3::new(0.0, 50.0, 0.0));
        assert!((cyl.chord(&ray) - 20.0).abs() < 1e-12);
        let ray = Ray::segment(DVec3::new(0.0, 0.0, -50.0), DVec3::new(0.0, 0.0, 50.0));
        assert!((cyl.chord(&ray) - 6.0).abs() < 1e-12);
    }

    #[test]
    fn variants_are_seeded_and_differ() {
        assert_eq!(Phantom::thorax_variant(7), Phantom::thorax_variant(7));
        assert_ne!(Phantom::thorax_variant(7), Phantom::thorax_variant(8));
        for seed in 0..20 {
            let v = Phantom::thorax_variant(seed)
                .voxelize([48, 48, 40], DVec3::new(8.0, 8.0, 9.0), DVec3::ZERO)
                .unwrap();
            let (lo, hi) = v.min_max();
            assert!(lo >= -1000.0 && hi < 2100.0, "seed {seed}: {lo} {hi}");
        }
    }

    #[test]
    fn thorax_stays_above_air() {
        let p = Phantom::thorax();
        let v = p
            .voxelize([64, 64, 40], DVec3::new(5.6, 5.6, 8.3), DVec3::ZERO)
            .unwrap();
        let (lo, hi) = v.min_max();
        assert!(lo >= -1000.0 && hi < 2100.0, "{lo} {hi}");
        // Lung, soft tissue and bone are all present.
        assert!(v.data().iter().any(|&h| h < -700.0 && h > -900.0));
        assert!(v.data().iter().any(|&h| (h - 700.0).abs() < 1.0));
    }
}
