//! What the realistic detector adds to a render: times `DetectorModel::record` (one frame,
//! `kv_flat_panel` preset) and the flat/dark + −log correction of that frame for a 256²
//! image, against a mono exact-Siddon render of a 256³ thorax phantom, in one process.
//! Measurements alternate (render, record, correct) and the medians are compared, so a
//! load change on the machine hits all three alike. The detector's cost depends on the
//! pixel pitch through the blur kernel, so it is reported at the scene's pitch (the
//! phantom fills the panel) and at the preset's native 0.15 mm pitch (the longest
//! kernel). Calibration (16 + 16 frames) is once per scene, not per view: reported apart.
//! Both wall-clock and process CPU time (all threads) are measured: on a shared, loaded
//! machine the CPU-time ratio is the steadier measure of the work the detector adds.
//!
//! `cargo run --release -p tomograf-physics --example detector_cost [-- REPEATS]`
use glam::DVec3;
use std::hint::black_box;
use std::time::Instant;
use tomograf_physics::detector::{DetectorModel, ExpectedImage, Output};
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::*;

/// CPU time of the whole process (all threads), ms.
fn cpu_ms() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) };
    assert_eq!(rc, 0, "clock_gettime failed");
    t.tv_sec as f64 * 1e3 + t.tv_nsec as f64 * 1e-6
}

/// Runs `f`; returns ([wall ms, CPU ms], its result).
fn timed<T>(f: impl FnOnce() -> T) -> ([f64; 2], T) {
    let (t, c) = (Instant::now(), cpu_ms());
    let out = f();
    ([t.elapsed().as_secs_f64() * 1e3, cpu_ms() - c], out)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let repeats: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("REPEATS must be a whole number"))
        .unwrap_or(15);
    let energy = 60.0;
    let hu = Phantom::thorax()
        .voxelize([256, 256, 256], DVec3::new(1.4, 1.4, 1.3), DVec3::ZERO)
        .unwrap();
    let mu = Attenuation::hounsfield_at_kev(energy)
        .unwrap()
        .to_mu(hu)
        .unwrap();
    let renderer = Renderer::new(&mu, Projector::Siddon).unwrap();
    let model = DetectorModel::kv_flat_panel();
    // 1000 photons of 60 keV per pixel in the open beam, η = 0.8 (≈ 0.6 mm CsI at 60 keV).
    let weights = model.channel_weights(&[energy], &[0.8]).unwrap();
    println!(
        "threads: {}; {repeats} alternating repeats, medians; wall / CPU ms",
        rayon::current_num_threads()
    );
    println!(
        "| pitch (mm) | render | record | record ÷ render (wall, CPU) | correct + −log | \
         (record + correct) ÷ render (wall, CPU) | calibrate, 16 + 16 frames |"
    );
    println!("|---|---|---|---|---|---|---|");
    for pitch in [2.1, 0.15] {
        let detector = Detector::new(256, 256, pitch);
        let view = Geometry {
            beam: Beam::Cone {
                sad_mm: 1000.0,
                sid_mm: 1500.0,
            },
            detector,
            isocentre: DVec3::ZERO,
        }
        .view(Pose::new(0.0, 0.0))
        .unwrap();
        let lines = renderer.render(&view).unwrap();
        let photons: Vec<f64> = lines
            .data
            .iter()
            .map(|&l| 1000.0 * (-f64::from(l)).exp())
            .collect();
        let mut object = ExpectedImage::zeros(&detector, 1);
        object.accumulate_bin(&photons, &weights, 0).unwrap();
        let mut open = ExpectedImage::zeros(&detector, 1);
        open.accumulate_bin(&vec![1000.0; 256 * 256], &weights, 0)
            .unwrap();
        let (cal, flat) = timed(|| model.calibrate(&open, 7).unwrap());
        let mut t: [[Vec<f64>; 2]; 3] = Default::default();
        for i in 0..=repeats {
            let (a, _) = timed(|| black_box(renderer.render(&view).unwrap()));
            let (b, raw) = timed(|| model.record(&object, i as u64).unwrap());
            let (c, _) = timed(|| black_box(flat.apply(&raw, Output::LogLineIntegral).unwrap()));
            if i > 0 {
                for (k, x) in [a, b, c].into_iter().enumerate() {
                    t[k][0].push(x[0]);
                    t[k][1].push(x[1]);
                }
            }
        }
        let m = t.map(|[w, c]| [median(w), median(c)]);
        let pct = |extra: bool| {
            (0..2)
                .map(|j| {
                    let x = m[1][j] + if extra { m[2][j] } else { 0.0 };
                    format!("{:.1} %", 100.0 * x / m[0][j])
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        println!(
            "| {pitch} | {:.1} / {:.1} | {:.2} / {:.2} | {} | {:.2} / {:.2} | {} | {:.0} / {:.0} |",
            m[0][0],
            m[0][1],
            m[1][0],
            m[1][1],
            pct(false),
            m[2][0],
            m[2][1],
            pct(true),
            cal[0],
            cal[1],
        );
    }
}
