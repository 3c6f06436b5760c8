//! Packet shape A/B on the chest-sized case (512×512×133 voxels of 0.7×0.7×2.5 mm, 256²
//! detector, SAD 1000 / SID 1500): the SIMD tracer fed one detector row at a time (packets of
//! 1 row × LANES pixels) against tiles of `packet::TILE_ROWS` rows (what the renderer does),
//! same rays, same process, alternating; prints the median time of each and their ratio per
//! gantry angle. Not part of the test suite.
//!
//! `cargo run --release -p tomograf-sim --example packet_tiles`
use glam::DVec3;
use rayon::prelude::*;
use std::time::Instant;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::trace::packet;
use tomograf_sim::*;

fn main() {
    let Some(kernel) = packet::kernel() else {
        println!("no SIMD kernel on this CPU");
        return;
    };
    let hu = Phantom::thorax()
        .voxelize([512, 512, 133], DVec3::new(0.7, 0.7, 2.5), DVec3::ZERO)
        .unwrap();
    let mu = Attenuation::hounsfield_at_kev(60.0)
        .unwrap()
        .to_mu(hu)
        .unwrap();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(256, 256, 2.6),
        isocentre: DVec3::ZERO,
    };
    println!(
        "kernel {kernel:?}, {} threads",
        rayon::current_num_threads()
    );
    println!(
        "| gantry θ | 1 row × lanes ms | {} rows tile ms | ratio |",
        packet::TILE_ROWS
    );
    println!("|---:|---:|---:|---:|");
    for theta in [0.0, 30.0, 60.0, 90.0] {
        let view = g.view(Pose::new(theta, 0.0)).unwrap();
        let rays: Vec<Option<GridRay>> = (0..view.rows)
            .flat_map(|r| (0..view.cols).map(move |c| (r, c)))
            .map(|(r, c)| GridRay::clip(&mu, &view.ray(r as f64, c as f64)))
            .collect();
        let run = |rows: usize| {
            let mut out = vec![0.0; rays.len()];
            let t = Instant::now();
            out.par_chunks_mut(view.cols * rows)
                .zip(rays.par_chunks(view.cols * rows))
                .for_each(|(o, r)| {
                    let mut handled = vec![false; r.len()];
                    packet::trace_rows_with(
                        kernel,
                        mu.data(),
                        mu.dims(),
                        r,
                        view.cols,
                        0.0,
                        0,
                        o,
                        &mut handled,
                    );
                });
            (t.elapsed().as_secs_f64() * 1e3, out)
        };
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for _ in 0..15 {
            let (ta, oa) = run(1);
            let (tb, ob) = run(packet::TILE_ROWS);
            assert!(
                oa.iter()
                    .zip(&ob)
                    .all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs() + 1e-12)
            );
            a.push(ta);
            b.push(tb);
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (ma, mb) = (median(&mut a), median(&mut b));
        println!("| {theta} | {ma:.2} | {mb:.2} | {:.2}× |", ma / mb);
    }
}
