//! The model's differentiable renderer (rays from sim's geometry, Q midpoint samples,
//! trilinear field from `gather`, Σ mu·Δs) against sim's trilinear DRR of the same volume
//! (`Renderer` with `Projector::Trilinear`), an independent implementation of the same
//! integral.

use burn::tensor::{Tensor, TensorData};
use glam::DVec3;
use tomograf_model::rays::{full_image, sample_rays};
use tomograf_model::render::{DensityScale, line_integral};
use tomograf_model::trilinear::VolumeTensor;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Renderer, View, Volume};

fn model_drr(vol: &Volume, view: &View, q: usize) -> Vec<f32> {
    let dev = tomograf_model::backend::device("flex").unwrap();
    let pixels = full_image(view.rows, view.cols);
    let s = sample_rays(view, vol, &pixels, q, None).unwrap();
    let vt = VolumeTensor::new(vol.data().to_vec(), vol.dims(), &dev);
    let mu = DensityScale::IDENTITY
        .mu(vt.sample(&s.grid))
        .reshape([1, pixels.len(), q]);
    let step = Tensor::<2>::from_data(TensorData::new(s.step_mm, [1, pixels.len()]), &dev);
    line_integral(mu, step)
        .into_data()
        .try_to_vec::<f32>()
        .unwrap()
}

fn sim_drr(vol: &Volume, view: &View) -> Vec<f32> {
    Renderer::new(vol, Projector::Trilinear { step_voxels: 0.01 })
        .unwrap()
        .render(view)
        .unwrap()
        .data
}

fn geometry(centre: DVec3, beam: Beam) -> Geometry {
    Geometry {
        beam,
        detector: Detector {
            rows: 12,
            cols: 10,
            pitch_u_mm: 3.5,
            pitch_v_mm: 4.0,
            offset_u_mm: 2.0,
            offset_v_mm: -1.0,
        },
        isocentre: centre + DVec3::new(1.0, -2.0, 0.5),
    }
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn uniform_volume_gives_mu_times_chord_in_both() {
    // A uniform field: both renderers must give mu × (clipped chord), exactly up to f32
    // rounding (relative 1e-5), independent of the sample count.
    let centre = DVec3::new(3.0, -5.0, 20.0);
    let vol = Volume::centred(
        [9, 11, 13],
        DVec3::new(2.0, 2.5, 3.0),
        centre,
        vec![0.02; 9 * 11 * 13],
    )
    .unwrap();
    let g = geometry(
        centre,
        Beam::Cone {
            sad_mm: 300.0,
            sid_mm: 500.0,
        },
    );
    for pose in [Pose::AP, Pose::new(37.0, 21.0)] {
        let view = g.view(pose).unwrap();
        let m = model_drr(&vol, &view, 7);
        let s = sim_drr(&vol, &view);
        assert!(s.iter().any(|&v| v > 0.1), "the view must see the volume");
        for (a, b) in m.iter().zip(&s) {
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1e-3), "{a} vs {b}");
        }
    }
}

#[test]
fn random_volume_matches_sim_trilinear_and_converges_as_h_squared() {
    // A random field: both are midpoint rules of the same continuous, piecewise-polynomial
    // trilinear field, so they must agree to the quadrature error, which falls as h².
    // Stated tolerance: with Q = 512 samples (h ≤ 0.1 voxel) the model's rule errs by
    // ≤ 2e-4 of the largest integral here (measured 5e-6 … 5e-5), and the difference must
    // fall ≥ 8× when Q goes 64 → 512 (h² predicts 64×): a geometric disagreement (a shifted
    // ray, a flipped axis, a wrong step length) would not shrink with Q at all.
    let centre = DVec3::new(-4.0, 7.0, 1.0);
    let dims = [10, 12, 14];
    let n = dims.iter().product::<usize>();
    let data: Vec<f32> = (0..n)
        .map(|i| 0.03 * ((i as u64).wrapping_mul(2654435761) % 1000) as f32 / 1000.0)
        .collect();
    let vol = Volume::centred(dims, DVec3::new(2.0, 1.5, 2.5), centre, data).unwrap();
    for beam in [
        Beam::Cone {
            sad_mm: 250.0,
            sid_mm: 400.0,
        },
        Beam::Parallel,
    ] {
        let g = geometry(centre, beam);
        for pose in [Pose::new(30.0, 20.0), Pose::new(200.0, -10.0)] {
            let view = g.view(pose).unwrap();
            let s = sim_drr(&vol, &view);
            let max = s.iter().fold(0.0f32, |a, &b| a.max(b)) as f64;
            assert!(max > 0.1);
            let coarse = max_abs_diff(&model_drr(&vol, &view, 64), &s);
            let fine = max_abs_diff(&model_drr(&vol, &view, 512), &s);
            assert!(fine <= 2e-4 * max, "{beam:?} {pose:?}: {fine} vs max {max}");
            assert!(
                fine * 8.0 <= coarse || fine <= 1e-6 * max,
                "{beam:?} {pose:?}: no h² convergence: {coarse} → {fine}"
            );
        }
    }
}
