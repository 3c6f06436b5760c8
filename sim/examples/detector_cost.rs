//! What the realistic detector adds to a render: times `DetectorModel::record` (one frame,
//! `kv_flat_panel` preset) and the flat/dark + −log correction of that frame for a 256²
//! image, against a mono exact-Siddon render of a 256³ thorax phantom, in one process.
//! Measurements alternate (render, record, correct) and the medians are compared, so a
//! load change on the machine hits all three alike. The detector's cost depends on the
//! pixel pitch through the blur kernel, so it is reported at the scene's pitch (the
//! phantom fills the panel) and at the preset's native 0.15 mm pitch (the longest
//! kernel). Calibration (16 + 16 frames) is once per scene, not per view: reported apart.
//!
//! `cargo run --release -p tomograf-sim --example detector_cost [-- REPEATS]`
use glam::DVec3;
use std::hint::black_box;
use std::time::Instant;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::detector::{DetectorModel, ExpectedImage, Output};
use tomograf_sim::phantom::Phantom;
use tomograf_sim::*;

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
        "threads: {}; {repeats} alternating repeats, medians",
        rayon::current_num_threads()
    );
    println!(
        "| pitch (mm) | render (ms) | record (ms) | record/render | correct −log (ms) | (record+correct)/render | calibrate 16+16 frames (ms) |"
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
        let t = Instant::now();
        let flat = model.calibrate(&open, 7).unwrap();
        let calibrate = t.elapsed().as_secs_f64() * 1e3;
        let (mut tr, mut td, mut tc) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..repeats + 1 {
            let t = Instant::now();
            black_box(renderer.render(&view).unwrap());
            let a = t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let raw = model.record(&object, i as u64).unwrap();
            let b = t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            black_box(flat.apply(&raw, Output::LogLineIntegral).unwrap());
            let c = t.elapsed().as_secs_f64() * 1e3;
            if i > 0 {
                tr.push(a);
                td.push(b);
                tc.push(c);
            }
        }
        let (r, d, c) = (median(tr), median(td), median(tc));
        println!(
            "| {pitch} | {r:.1} | {d:.2} | {:.1} % | {c:.2} | {:.1} % | {calibrate:.0} |",
            100.0 * d / r,
            100.0 * (d + c) / r
        );
    }
}
