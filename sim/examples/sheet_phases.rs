//! Where an AP view's time goes when its detector rows are traced as ray sheets: per view,
//! on one thread, back to back (warm caches), the milliseconds spent making the world rays,
//! clipping them, building each row's [`Sheet`], marking its zero blocks
//! ([`Sheet::skip_zeros`]) and integrating (the SIMD kernel); and how the kernel takes each
//! (group of eight rays, block of segments) pair ([`Sheet::passes`]). For profiling and
//! tuning (docs/projector.md, "Session 30"); not part of the test suite.
//!
//! The volume is the built-in thorax phantom on a chest-CT grid (512×512×133 voxels of
//! 0.7×0.7×2.5 mm) or, with a path, a float32 NIfTI-1 file of mu in mm⁻¹ on that grid with
//! the standard 352-byte header, as `scripts/compare_plastimatch.py` writes the real CT
//! (`ct_mu.nii` in its work folder). The geometry is that script's: SAD 1000 mm, SID
//! 1500 mm, a 256² detector of 2.6 mm pitch.
//!
//! `cargo run --release -p tomograf-sim --example sheet_phases [-- /tmp/tomograf-plastimatch/ct_mu.nii]`
use glam::{DMat3, DVec3};
use std::time::Instant;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::occupancy::RowExtents;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::trace::sheet::Sheet;
use tomograf_sim::*;

const DIMS: [usize; 3] = [512, 512, 133];
const REPEATS: usize = 20;

fn volume() -> Volume {
    let spacing = DVec3::new(0.7, 0.7, 2.5);
    match std::env::args().nth(1) {
        Some(path) => {
            let bytes = std::fs::read(&path).expect("the NIfTI file");
            let n = DIMS.iter().product::<usize>();
            assert_eq!(
                bytes.len(),
                352 + 4 * n,
                "{path}: not a float32 512×512×133 NIfTI-1"
            );
            let mut data: Vec<f32> = Vec::with_capacity(n);
            huge_pages(&mut data);
            data.extend(
                bytes[352..]
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes(c.try_into().unwrap())),
            );
            Volume::new(DIMS, spacing, DVec3::ZERO, DMat3::IDENTITY, data).unwrap()
        }
        None => {
            let hu = Phantom::thorax()
                .voxelize(DIMS, spacing, DVec3::ZERO)
                .unwrap();
            Attenuation::hounsfield_at_kev(60.0)
                .unwrap()
                .to_mu(hu)
                .unwrap()
        }
    }
}

/// Advises 2 MB pages for `v`'s capacity, as the command line's allocator does for large
/// blocks (src/allocator.rs): with 4 KB pages the kernel waits on the TLB, and measures
/// differently from `tomograf project`.
fn huge_pages(v: &mut Vec<f32>) {
    const HUGE: usize = 2 << 20;
    let (start, len) = (v.as_mut_ptr() as usize, v.capacity() * 4);
    let aligned = start.next_multiple_of(HUGE);
    if aligned < start + len {
        // SAFETY: advice on pages inside `v`'s own allocation.
        unsafe {
            libc::madvise(
                aligned as *mut libc::c_void,
                (start + len - aligned) / HUGE * HUGE,
                libc::MADV_HUGEPAGE,
            );
        }
    }
}

fn main() {
    let mu = volume();
    let geometry = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(256, 256, 2.6),
        isocentre: mu.centre() + DVec3::new(0.0123, 0.0456, 0.0078),
    };
    let view = geometry.view(Pose::AP).unwrap();
    let rows = RowExtents::of(&mu);
    let bounds = rows.bounding_box().expect("a volume with non-zero voxels");
    let mut ms = [0f64; 5];
    let mut passes = [0usize; 6];
    let mut lap = |slot: usize, since: &mut Instant| {
        let now = Instant::now();
        ms[slot] += (now - *since).as_secs_f64() * 1e3 / REPEATS as f64;
        *since = now;
    };
    for _ in 0..REPEATS {
        for r in 0..view.rows {
            let mut t = Instant::now();
            let world: Vec<Ray> = (0..view.cols)
                .map(|c| view.ray(r as f64, c as f64))
                .collect();
            lap(0, &mut t);
            let rays: Vec<Option<GridRay>> = world
                .iter()
                .map(|w| GridRay::clip_to(&mu, w, &bounds))
                .collect();
            lap(1, &mut t);
            let Some(mut sheet) = Sheet::new(&rays, mu.dims(), &bounds) else {
                continue;
            };
            lap(2, &mut t);
            sheet.skip_zeros(&rows, &bounds);
            lap(3, &mut t);
            let mut out = vec![0.0; view.cols];
            sheet.line_integrals(mu.data(), mu.dims(), &bounds, &mut out);
            lap(4, &mut t);
            std::hint::black_box(&out);
            let p = sheet.passes(8, &bounds);
            for (n, v) in [p.missed, p.zeros, p.rising, p.falling, p.inside, p.clipped]
                .into_iter()
                .enumerate()
            {
                passes[n] += v;
            }
        }
    }
    println!(
        "per view, one thread, ms: world rays {:.2}, clipping {:.2}, Sheet::new {:.2}, \
         skip_zeros {:.2}, kernel {:.2}",
        ms[0], ms[1], ms[2], ms[3], ms[4]
    );
    let p = passes.map(|n| n / REPEATS);
    println!(
        "(group of 8 rays, block) pairs per view: missed {}, zeros {}, rising {}, \
         falling {}, inside {}, clipped {}",
        p[0], p[1], p[2], p[3], p[4], p[5]
    );
}
