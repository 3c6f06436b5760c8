//! Renders the chest-sized AP view repeatedly, for profiling. Not part of the test suite.
use glam::DVec3;
use std::time::Instant;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::*;
fn main() {
    let hu = Phantom::thorax()
        .voxelize([512, 512, 133], DVec3::new(0.7, 0.7, 2.5), DVec3::ZERO)
        .unwrap();
    let mu = Attenuation::hounsfield_at_kev(60.0)
        .unwrap()
        .to_mu(hu)
        .unwrap();
    let theta: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(0.0);
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(256, 256, 2.6),
        isocentre: DVec3::ZERO,
    };
    let v = g.view(Pose::new(theta, 0.0)).unwrap();
    let mut r = Renderer::new(&mu, Projector::Siddon).unwrap();
    if let Some(t) = std::env::var("TG_PACKET_THRESHOLD")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        r = r.with_packet_threshold(t);
    }
    let _ = r.render(&v).unwrap();
    let t = Instant::now();
    let n = 20;
    for _ in 0..n {
        std::hint::black_box(r.render(&v).unwrap());
    }
    println!(
        "θ={theta}: {:.2} ms",
        t.elapsed().as_secs_f64() * 1e3 / n as f64
    );
    if let Ok(p) = std::env::var("PAD") {
        let [x, y]: [usize; 2] = p
            .split(',')
            .map(|v| v.parse().unwrap())
            .collect::<Vec<_>>()
            .try_into()
            .unwrap();
        println!(
            "θ={theta} scalar through a copy padded to {x}×{y}: {:.2} ms",
            padded(&mu, &v, x, y)
        );
    }
    if std::env::var_os("COUNT").is_some() {
        count(&mu, &v);
    }
    if std::env::var_os("TRANSPOSED").is_some() {
        println!(
            "θ={theta} through a y-fastest copy: {:.2} ms",
            transposed(&mu, &v)
        );
    }
}

/// Experiment: the same view traced through a y-fastest copy of the volume.
#[allow(dead_code)]
pub fn transposed(mu: &Volume, v: &View) -> f64 {
    use rayon::prelude::*;
    use tomograf_sim::trace::{LineIntegral, siddon};
    let [nx, ny, nz] = mu.dims();
    let mut t = vec![0f32; mu.len()];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                t[j + ny * (i + nx * k)] = mu.get(i, j, k);
            }
        }
    }
    let strides = [ny, 1, nx * ny];
    let run = || -> Vec<f32> {
        (0..v.rows)
            .into_par_iter()
            .flat_map_iter(|r| (0..v.cols).map(move |c| (r, c)))
            .map(|(r, c)| {
                let Some(g) = GridRay::clip(mu, &v.ray(r as f64, c as f64)) else {
                    return 0.0;
                };
                let mut acc = LineIntegral::new(&t);
                siddon::trace_strided(mu.dims(), strides, &g, &mut acc);
                acc.value() as f32
            })
            .collect()
    };
    let _ = run();
    let t0 = Instant::now();
    for _ in 0..20 {
        std::hint::black_box(run());
    }
    t0.elapsed().as_secs_f64() * 1e3 / 20.0
}

/// Counts what the tracer reports per ray.
#[derive(Default)]
pub struct Counts {
    pub segments: u64,
    pub triples: u64,
    pub runs: u64,
    pub run_voxels: u64,
}
impl tomograf_sim::trace::PathAccumulator for Counts {
    fn segment(&mut self, _: usize, _: f64) {
        self.segments += 1;
    }
    fn segments3(&mut self, _: [usize; 3], _: [f64; 3]) {
        self.triples += 1;
    }
    fn run(&mut self, _: usize, _: usize, count: usize, _: f64) {
        self.runs += 1;
        self.run_voxels += count as u64;
    }
}

#[allow(dead_code)]
pub fn count(mu: &Volume, v: &View) {
    let mut c = Counts::default();
    let mut rays = 0;
    for r in 0..v.rows {
        for col in 0..v.cols {
            if let Some(g) = GridRay::clip(mu, &v.ray(r as f64, col as f64)) {
                tomograf_sim::trace::siddon::trace(mu.dims(), &g, &mut c);
                rays += 1;
            }
        }
    }
    let f = |x: u64| x as f64 / rays as f64;
    println!(
        "per ray ({rays} rays): single segments {:.1}, slab triples {:.1}, runs {:.1}, voxels in runs {:.1}",
        f(c.segments),
        f(c.triples),
        f(c.runs),
        f(c.run_voxels)
    );
}

/// Experiment: the same view traced (scalar) through a copy whose rows are padded to
/// `pad_x` voxels and slices to `pad_y` rows, so strides are not powers of two.
#[allow(dead_code)]
pub fn padded(mu: &Volume, v: &View, pad_x: usize, pad_y: usize) -> f64 {
    use rayon::prelude::*;
    use tomograf_sim::trace::{LineIntegral, siddon};
    let [nx, ny, nz] = mu.dims();
    let strides = [1, pad_x, pad_x * pad_y];
    let mut t = vec![0f32; pad_x * pad_y * nz];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                t[i + pad_x * j + pad_x * pad_y * k] = mu.get(i, j, k);
            }
        }
    }
    let run = || -> Vec<f32> {
        let mut out = vec![0f32; v.rows * v.cols];
        out.par_chunks_mut(v.cols).enumerate().for_each(|(r, row)| {
            for (c, px) in row.iter_mut().enumerate() {
                *px = GridRay::clip(mu, &v.ray(r as f64, c as f64)).map_or(0.0, |g| {
                    let mut acc = LineIntegral::new(&t);
                    siddon::trace_strided(mu.dims(), strides, &g, &mut acc);
                    acc.value() as f32
                });
            }
        });
        out
    };
    let _ = run();
    let t0 = Instant::now();
    for _ in 0..20 {
        std::hint::black_box(run());
    }
    t0.elapsed().as_secs_f64() * 1e3 / 20.0
}
