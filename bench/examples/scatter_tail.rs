//! Where the Monte Carlo's round-to-round error lives (issue 49: the orbit's rounds are
//! heavy-tailed, the worst of 8 up to 2.5× their mean). One view of `tomograf bench
//! --scatter`'s scene (the CT, 256², `kv-flat-panel-120kvp`, noise off) is scattered in
//! ROUNDS independent runs (seed 0x5ca7 + round, as the bench's rounds) with the orbit's
//! Monte Carlo setting (HISTORIES histories, 16² points, 8² for multiple scatter, 8 mm
//! detection cells); each component's image (single Compton, single Rayleigh, multiple) is
//! compared with its mean over the rounds. Printed per component: the RMS of its deviation
//! from that mean over the RMS of the mean total scatter, the mean over rounds and the worst
//! round, and the share of the total's squared deviation; then how much of each round's
//! deviation is a scale of the whole image. SAMPLING `analog` runs the engine's sampling
//! before 2026-12-01 (`ScatterEngine::with_analog_sampling`), `strata` (the default) today's.
//! SPLIT (default 1) splits every history into that many branches at its first collision
//! (the Monte Carlo's `split`). Not a test; one process.
//!
//! `cargo run --release -p tomograf-bench --example scatter_tail -- CT [VIEW] [HISTORIES] [ROUNDS] [SAMPLING] [SPLIT]`

use anyhow::{Context, Result};
use tomograf_physics::scatter::ScatterModel;
use tomograf_scene::job::resolve;
use tomograf_scene::physics::acquisition;
use tomograf_scene::volume::load_hu;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let ct = std::path::PathBuf::from(args.first().context("give a CT")?);
    let at: usize = args.get(1).map_or(Ok(0), |s| s.parse())?;
    let photons: u64 = args.get(2).map_or(Ok(3_500), |s| s.parse())?;
    let rounds: usize = args.get(3).map_or(Ok(16), |s| s.parse())?;
    let analog = match args.get(4).map_or("strata", String::as_str) {
        "strata" => false,
        "analog" => true,
        other => anyhow::bail!("SAMPLING {other:?}: strata or analog"),
    };
    let split: u32 = args.get(5).map_or(Ok(1), |s| s.parse())?;
    let scene = tomograf_bench::scatter::scene(&ct, false)?;
    let (mut acq, seed) = acquisition(&scene)?.context("the scene has no physics")?;
    acq.detector.quantum_noise = false;
    acq.detector.readout.electronic_noise_adu = 0.0;
    let (hu, _) = load_hu(&scene, acq.materials.calibration_kev)?;
    let views = resolve(&scene, &hu)?.views;
    let view = &views[at];
    let n = view.rows * view.cols;
    acq.scatter = ScatterModel::MonteCarlo {
        photons,
        grid: 16,
        multiple_grid: 8,
        max_order: 50,
        detection_cell_mm: 8.0,
        angular_window_deg: 0.0,
        split,
        sparse_multiple: false,
        sampler: Default::default(),
        cell_check: 0,
    };
    let model = acq.scatter.clone();
    let prepared = acq.prepare(&hu, seed)?;
    let engine = prepared
        .scatter_engine()
        .context("scatter is modelled")?
        .clone()
        .with_analog_sampling(analog);
    // [round][component] images, channel 0.
    let mut runs: Vec<[Vec<f64>; 3]> = Vec::new();
    let clock = std::time::Instant::now();
    for round in 0..rounds {
        let s = engine
            .run(&model, view, 0x5ca7 + round as u64)?
            .context("no scatter")?;
        runs.push([
            s.single_compton.mean[..n].to_vec(),
            s.single_rayleigh.mean[..n].to_vec(),
            s.multiple.mean[..n].to_vec(),
        ]);
    }
    let seconds = clock.elapsed().as_secs_f64() / rounds as f64;
    let mean: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            (0..n)
                .map(|i| runs.iter().map(|r| r[c][i]).sum::<f64>() / rounds as f64)
                .collect()
        })
        .collect();
    let total: Vec<f64> = (0..n)
        .map(|i| mean[0][i] + mean[1][i] + mean[2][i])
        .collect();
    let norm = (total.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
    println!(
        "CT {}, view {at}, {photons} histories × {rounds} rounds, {} sampling, split {split} \
         ({seconds:.2} s each, {} threads); mean components' share of the total: Compton {:.3}, Rayleigh {:.3}, multiple {:.3}",
        ct.display(),
        if analog {
            "analog"
        } else {
            "stratified, forced first collision"
        },
        rayon::current_num_threads(),
        mean[0].iter().sum::<f64>() / total.iter().sum::<f64>(),
        mean[1].iter().sum::<f64>() / total.iter().sum::<f64>(),
        mean[2].iter().sum::<f64>() / total.iter().sum::<f64>(),
    );
    // Each component's image total per round: the mean over the rounds and its standard
    // error (to compare settings that should agree, e.g. split against unsplit).
    let totals: Vec<String> = ["single Compton", "single Rayleigh", "multiple"]
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let t: Vec<f64> = runs.iter().map(|r| r[c].iter().sum::<f64>()).collect();
            let k = t.len() as f64;
            let m = t.iter().sum::<f64>() / k;
            let sd = (t.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0).max(1.0)).sqrt();
            format!("{name} {m:.5e} ± {:.2} %", 100.0 * sd / k.sqrt() / m)
        })
        .collect();
    println!(
        "image totals, mean of the rounds ± standard error: {}\n",
        totals.join(", ")
    );
    println!(
        "| component | deviation rms / total rms: mean of rounds | worst round | share of the total's squared deviation |"
    );
    println!("|---|---:|---:|---:|");
    let dev = |r: &[Vec<f64>; 3], comps: &[usize]| -> f64 {
        let s: f64 = (0..n)
            .map(|i| {
                let d: f64 = comps.iter().map(|&c| r[c][i] - mean[c][i]).sum();
                d * d
            })
            .sum();
        (s / n as f64).sqrt() / norm
    };
    let total_sq: f64 = runs.iter().map(|r| dev(r, &[0, 1, 2]).powi(2)).sum();
    for (name, comps) in [
        ("single Compton", vec![0]),
        ("single Rayleigh", vec![1]),
        ("multiple", vec![2]),
        ("total", vec![0, 1, 2]),
    ] {
        let d: Vec<f64> = runs.iter().map(|r| dev(r, &comps)).collect();
        let sq: f64 = d.iter().map(|x| x * x).sum();
        println!(
            "| {name} | {:.2} % | {:.2} % | {:.2} |",
            100.0 * d.iter().sum::<f64>() / rounds as f64,
            100.0 * d.iter().fold(0.0, |a: f64, &b| a.max(b)),
            sq / total_sq
        );
    }
    let per_round: Vec<String> = runs
        .iter()
        .map(|r| format!("{:.2}", 100.0 * dev(r, &[0, 1, 2])))
        .collect();
    println!("\ntotal deviation per round (%): {}", per_round.join(" "));
    // How much of it is a scale of the whole image: each round's total over the mean's, and
    // the deviation left once that scale is divided out.
    let sum_mean: f64 = total.iter().sum();
    let mut scales = Vec::new();
    let mut left = Vec::new();
    for r in &runs {
        let t: Vec<f64> = (0..n).map(|i| r[0][i] + r[1][i] + r[2][i]).collect();
        let k = t.iter().sum::<f64>() / sum_mean;
        let s: f64 = (0..n).map(|i| (t[i] / k - total[i]).powi(2)).sum();
        scales.push(format!("{:+.2}", 100.0 * (k - 1.0)));
        left.push(format!("{:.2}", 100.0 * (s / n as f64).sqrt() / norm));
    }
    println!("whole-image scale per round (%): {}", scales.join(" "));
    println!("deviation left after the scale (%): {}", left.join(" "));
    // Each component's scale per round.
    for (c, name) in ["Compton", "Rayleigh", "multiple"].iter().enumerate() {
        let m: f64 = mean[c].iter().sum();
        let v: Vec<String> = runs
            .iter()
            .map(|r| format!("{:+.2}", 100.0 * (r[c].iter().sum::<f64>() / m - 1.0)))
            .collect();
        println!("{name} scale per round (%): {}", v.join(" "));
    }
    Ok(())
}
