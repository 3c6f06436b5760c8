//! `[infer] mean_sweeps_weight`: the final volume shrunk towards SART-TV from the mean.

mod common;

use tomograf_model::baseline::{Baseline, MeanVolume, SartTv, SartTvSettings};
use tomograf_model::checkpoint;
use tomograf_model::config::TrainConfig;
use tomograf_model::reconstruct::{Reference, projection_psnr, reconstruct};
use tomograf_model::train::{Trainer, projection_scale};

/// w = 1 gives the baseline "SART-TV from the mean" (made by the baseline's own code), w = 0
/// the network's volume, w = ½ their voxel-wise midpoint; the recorded projection PSNR is
/// the blend's; a weight outside [0, 1] is refused by name.
#[test]
fn the_blend_runs_from_the_network_to_sart_tv_from_the_mean() {
    let item = common::item(16, 4, 16, 0.0);
    let other = common::item(16, 4, 16, -0.5);
    let items = std::slice::from_ref(&item);
    let config = TrainConfig::load("tiny").unwrap();
    let scale = projection_scale(items).unwrap();
    let dev = tomograf_model::backend::device("flex").unwrap();
    let mean = MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref())).unwrap();
    let t = Trainer::new(config.clone(), scale, mean, vec![item.id.clone()], &dev).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("ck");
    checkpoint::save(&t, item.scale, &ck).unwrap();
    let refs: Vec<Reference> = [0, 1]
        .iter()
        .map(|&i| Reference {
            view: other.views[i],
            pose: other.poses[i],
            image: other.projection(i).to_vec(),
        })
        .collect();
    let grid = item.ct.as_ref().unwrap();
    let settings = SartTvSettings::default();
    let run = |w: f64| {
        let mut infer = config.infer.clone();
        infer.iterations = 6;
        infer.code_iterations = 3;
        infer.psnr_threshold = 99.0;
        infer.refine_iterations = settings.sweeps;
        infer.refine_tv_step = settings.tv_step;
        infer.refine_below_db = 200.0; // the sweeps from the network run too
        infer.mean_sweeps_weight = w;
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        reconstruct(generator, &refs, grid, &infer, 5, &dev, |_, _| {}).unwrap()
    };
    let (r0, r1, half) = (run(0.0), run(1.0), run(0.5));
    let generator = checkpoint::load_generator(&ck, &dev).unwrap();
    let state = &generator.state;
    let baseline = SartTv::from_mean(generator.prior.clone())
        .reconstruct(&refs, grid, &state.density_scale)
        .unwrap();
    let max_diff = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f32, f32::max)
    };
    assert!(max_diff(r1.volume.data(), baseline.data()) < 1e-6);
    // The network's volume (after its own sweeps) differs from the classical one here.
    assert!(max_diff(r0.volume.data(), baseline.data()) > 1e-3);
    for ((&h, &a), &b) in half
        .volume
        .data()
        .iter()
        .zip(r0.volume.data())
        .zip(r1.volume.data())
    {
        assert!(
            (h - 0.5 * (a + b)).abs() < 1e-6,
            "{h} against ({a} + {b}) / 2"
        );
    }
    let psnr =
        projection_psnr(&half.volume, &state.density_scale, &refs, state.proj_scale).unwrap();
    assert_eq!(half.psnr, psnr);
    // The network-only volume reported beside it is the network's, not the blend.
    let net = half.network.as_ref().unwrap();
    assert_eq!(
        net.volume.data(),
        r0.network.as_ref().unwrap().volume.data()
    );

    let mut bad = config.clone();
    bad.infer.mean_sweeps_weight = 1.5;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("infer.mean_sweeps_weight = 1.5"), "{e}");
    let mut bad = config.clone();
    bad.infer.mean_sweeps_weight = 0.3;
    bad.infer.refine_iterations = 0;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("needs refine_iterations ≥ 1"), "{e}");
}
