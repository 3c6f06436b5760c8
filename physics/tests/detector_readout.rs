//! Readout (saturation, ADC), gain/offset maps against flat/dark correction, units of the
//! energy response, configuration and validation.

use tomograf_physics::detector::*;
use tomograf_sim::geometry::Detector;

fn image(rows: usize, cols: usize, mean: &[f64]) -> ExpectedImage {
    let mut e = ExpectedImage::zeros(&Detector::new(rows, cols, 0.2), 1);
    e.mean.copy_from_slice(mean);
    e.second_moment = mean.iter().map(|m| m * 60.0).collect();
    e
}

fn noiseless(readout: Readout) -> DetectorModel {
    DetectorModel {
        readout,
        ..DetectorModel::ideal()
    }
}

#[test]
fn ideal_record_is_the_mean() {
    let mean: Vec<f64> = (0..30).map(|i| f64::from(i) * 12.345).collect();
    let raw = DetectorModel::ideal()
        .record(&image(5, 6, &mean), 9)
        .unwrap();
    let want: Vec<f32> = mean.iter().map(|&m| m as f32).collect();
    assert_eq!(raw[0].data, want);
}

#[test]
fn saturation_and_adc_clip_and_quantise() {
    let mean = [0.0, 0.4, 0.6, 100.5, 150.2, 250.0, 1000.0, 3.0];
    let e = image(1, 8, &mean);
    // 8-bit ADC: round half away from zero, clip to [0, 255].
    let adc = noiseless(Readout {
        bits: Some(8),
        ..Readout::ideal()
    });
    assert_eq!(
        adc.record(&e, 0).unwrap()[0].data,
        [0.0, 0.0, 1.0, 101.0, 150.0, 250.0, 255.0, 3.0]
    );
    // Analogue saturation at 200 ADU below the ADC's 255, and an offset of −10 ADU
    // pushing small signals below code 0.
    let sat = noiseless(Readout {
        bits: Some(8),
        saturation_adu: Some(200.0),
        offset_adu: -10.0,
        ..Readout::ideal()
    });
    assert_eq!(
        sat.record(&e, 0).unwrap()[0].data,
        [0.0, 0.0, 0.0, 91.0, 140.0, 200.0, 200.0, 0.0]
    );
    // Without an ADC the saturation clip alone, no rounding.
    let analogue = noiseless(Readout {
        saturation_adu: Some(200.0),
        ..Readout::ideal()
    });
    let got = analogue.record(&e, 0).unwrap();
    assert_eq!(
        got[0].data,
        [0.0, 0.4, 0.6, 100.5, 150.2, 200.0, 200.0, 3.0]
    );
    // 32 bits: 2³² − 1 is the top code.
    let wide = noiseless(Readout {
        bits: Some(32),
        ..Readout::ideal()
    });
    assert_eq!(wide.readout.max_code(), Some(4_294_967_295.0));
}

#[test]
fn flat_dark_correction_recovers_the_transmission_exactly_without_noise() {
    let (rows, cols) = (40, 50);
    let model = noiseless(Readout {
        gain_nonuniformity: 0.3,
        offset_adu: 500.0,
        offset_nonuniformity_adu: 50.0,
        map_seed: 77,
        ..Readout::ideal()
    });
    let open_level = 10_000.0;
    let t: Vec<f64> = (0..rows * cols)
        .map(|i| 0.01 + 0.99 * ((i * 7919) % 1000) as f64 / 1000.0)
        .collect();
    let object = image(
        rows,
        cols,
        &t.iter().map(|x| x * open_level).collect::<Vec<_>>(),
    );
    let open = image(rows, cols, &vec![open_level; rows * cols]);
    let raw = model.record(&object, 1).unwrap();
    // The maps are really there: the raw signal is not the mean plus a constant.
    let spread = raw[0]
        .data
        .iter()
        .zip(&object.mean)
        .map(|(&r, &m)| f64::from(r) - m - 500.0)
        .fold(0.0f64, |a, d| a.max(d.abs()));
    assert!(spread > 1000.0, "gain/offset maps had no effect ({spread})");
    let ff = model.calibrate(&open, 2).unwrap();
    let corrected = ff.apply(&raw, Output::FlatField).unwrap();
    // f32 storage of raw, flat and dark (≤ 1.6·10⁴ ADU, step ≤ 2·10⁻³) over flat − dark
    // ≥ 7·10³ ADU: error < 10⁻⁶.
    for (got, want) in corrected[0].data.iter().zip(&t) {
        assert!((f64::from(*got) - want).abs() < 1e-6, "{got} vs {want}");
    }
    let l = ff.apply(&raw, Output::LogLineIntegral).unwrap();
    for (got, want) in l[0].data.iter().zip(&t) {
        assert!(
            (f64::from(*got) + want.ln()).abs() < 1e-4,
            "{got} vs {}",
            -want.ln()
        );
    }
}

#[test]
fn averaged_flat_fields_approach_the_expectation() {
    // 64 frames of 10⁴ ADU Poisson-like flats: relative noise of the mean 10⁻²/8.
    let mut model = DetectorModel::kv_flat_panel();
    model.calibration = Calibration {
        flat_frames: 64,
        dark_frames: 64,
    };
    model.blur = Blur::none();
    model.readout.bits = None;
    let w = model.channel_weights(&[60.0], &[0.8]).unwrap();
    let det = Detector::new(32, 32, 0.15);
    let mut open = ExpectedImage::zeros(&det, 1);
    open.accumulate_bin(&vec![600.0; 32 * 32], &w, 0).unwrap();
    let ff = model.calibrate(&open, 4).unwrap();
    let exact = model.expectation(&open).unwrap();
    let m = open.mean[0];
    let sd_of_mean = (open.second_moment[0] / 64.0).sqrt() * 1.05; // gain up to 1.05
    let worst = ff.flat()[0]
        .data
        .iter()
        .zip(&exact[0].data)
        .map(|(a, b)| f64::from(a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 5.0 * sd_of_mean,
        "{worst} vs σ {sd_of_mean} (mean {m})"
    );
    assert!(worst > 0.0, "averaged flats must carry some noise");
}

#[test]
fn monoenergetic_weights_are_energy_and_one_per_photon() {
    let ei = DetectorModel::ideal(); // 1 ADU per keV
    let w = ei.channel_weights(&[60.0], &[1.0]).unwrap();
    assert_eq!(w.mean, vec![vec![60.0]]);
    assert_eq!(w.second_moment, vec![vec![3600.0]]);
    let pc = DetectorModel::photon_counting(vec![20.0, 70.0]);
    let w = pc.channel_weights(&[60.0, 70.0, 100.0], &[1.0; 3]).unwrap();
    assert_eq!(w.mean, vec![vec![1.0, 0.0, 0.0], vec![0.0, 1.0, 1.0]]);
    assert_eq!(w.second_moment, w.mean);
    // End to end: 1000 photons of 60 keV, η = 0.5, 0.25 ADU/keV → 7500 ADU.
    let model = DetectorModel {
        mode: Mode::energy_integrating(0.25),
        ..DetectorModel::ideal()
    };
    let w = model.channel_weights(&[60.0], &[0.5]).unwrap();
    let mut e = ExpectedImage::zeros(&Detector::new(2, 3, 0.1), 1);
    e.accumulate_bin(&[1000.0; 6], &w, 0).unwrap();
    assert_eq!(model.record(&e, 0).unwrap()[0].data, [7500.0; 6]);
    // Scintillator: 0.6 mm with μ = 2 mm⁻¹ absorbs 1 − e^(−1.2).
    let s = Scintillator {
        material: "CsI".into(),
        thickness_mm: 0.6,
    };
    let eta = s.absorption(&[2.0]).unwrap()[0];
    assert!((eta - (1.0 - (-1.2f64).exp())).abs() < 1e-15);
}

#[test]
fn presets_validate_and_round_trip_through_toml() {
    for m in [
        DetectorModel::ideal(),
        DetectorModel::kv_flat_panel(),
        DetectorModel::cbct(),
        DetectorModel::photon_counting(vec![25.0, 50.0]),
    ] {
        m.validate().unwrap();
        let text = toml::to_string(&m).unwrap();
        let back: DetectorModel = toml::from_str(&text).unwrap();
        assert_eq!(back, m, "{text}");
    }
    let scene = r#"
        quantum_noise = true
        [mode]
        kind = "photon-counting"
        thresholds_kev = [20.0, 45.0]
        [blur]
        sigma_mm = 0.1
        [readout]
        electronic_noise_adu = 2.0
        bits = 14
        [calibration]
        flat_frames = 8
    "#;
    let m: DetectorModel = toml::from_str(scene).unwrap();
    assert_eq!(m.channels(), 2);
    assert_eq!(m.readout.bits, Some(14));
    assert_eq!(m.calibration.dark_frames, 0);
    let ei: DetectorModel = toml::from_str(
        "[mode]\nkind = \"energy-integrating\"\nconversion_gain_adu_per_kev = 0.5\n",
    )
    .unwrap();
    assert_eq!(ei.mode, Mode::energy_integrating(0.5));
    assert!(toml::from_str::<DetectorModel>("quantum-noise = true").is_err());
}

#[test]
fn bad_configuration_and_input_give_clear_errors() {
    let mut cases: Vec<(DetectorModel, &str)> = Vec::new();
    let mut m = DetectorModel::ideal();
    m.blur.sigma_mm = -0.1;
    cases.push((m, "sigma"));
    for bits in [0, 33] {
        let mut m = DetectorModel::ideal();
        m.readout.bits = Some(bits);
        cases.push((m, "bit depth"));
    }
    cases.push((
        DetectorModel::photon_counting(vec![50.0, 30.0]),
        "strictly increasing",
    ));
    let mut m = DetectorModel::ideal();
    m.readout.electronic_noise_adu = f64::NAN;
    cases.push((m, "electronic noise"));
    let mut m = DetectorModel::ideal();
    m.readout.saturation_adu = Some(0.0);
    cases.push((m, "saturation"));
    for (m, word) in cases {
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains(word), "{e} should mention {word}");
        assert!(m.record(&image(1, 1, &[1.0]), 0).is_err());
    }
    let ok = DetectorModel::ideal();
    let mut empty = image(1, 1, &[1.0]);
    empty.rows = 0;
    empty.mean.clear();
    empty.second_moment.clear();
    assert!(
        ok.record(&empty, 0)
            .unwrap_err()
            .to_string()
            .contains("empty")
    );
    let mut nan = image(1, 2, &[1.0, 2.0]);
    nan.mean[1] = f64::NAN;
    assert!(
        ok.record(&nan, 0)
            .unwrap_err()
            .to_string()
            .contains("row 0, col 1")
    );
    let mut zero_m2 = image(1, 2, &[1.0, 2.0]);
    zero_m2.second_moment[0] = 0.0;
    assert!(ok.record(&zero_m2, 0).is_err());
    let pc = DetectorModel::photon_counting(vec![20.0, 40.0]);
    assert!(
        pc.record(&image(1, 1, &[1.0]), 0)
            .unwrap_err()
            .to_string()
            .contains("channels")
    );
}

/// A ceiling that float32 cannot hold (a 16-bit ADC summed over 59 037 native pixels:
/// 3 868 989 795 ADU, stored as 3 868 989 696) still counts its clipped pixels: the
/// `kv-flat-panel-120kvp` preset once clipped large simulated pixels without a word.
#[test]
fn clipped_pixels_count_when_the_ceiling_is_not_a_float32() {
    let m = noiseless(Readout {
        bits: Some(16),
        native_pitch_mm: Some(0.15),
        ..Readout::ideal()
    });
    let pitch = (59_037.0f64).sqrt() * 0.15;
    let binning = m.readout.binning(pitch, pitch);
    let ceiling = m.readout.ceiling(binning);
    assert!(
        f64::from(ceiling as f32) < ceiling,
        "the ceiling {ceiling} must not be a float32"
    );
    let mut e = ExpectedImage::zeros(&Detector::new(1, 3, pitch), 1);
    e.mean.copy_from_slice(&[1.0e3, 1.0e12, 1.0e15]);
    e.second_moment = e.mean.iter().map(|m| m * 60.0).collect();
    let raw = m.record(&e, 0).unwrap();
    assert_eq!(raw[0].data[1], ceiling as f32);
    assert_eq!(m.saturated(&raw, pitch, pitch), 2);
}

#[test]
fn larger_pixels_read_as_sums_of_native_pixels() {
    // 0.2 mm simulated pixels over a 0.1 mm native panel: n = 4 native pixels each.
    let mean = [0.0, 100.0, 700.0, 5000.0];
    let e = image(1, 4, &mean);
    let native = |p: Option<f64>| {
        noiseless(Readout {
            bits: Some(8),
            saturation_adu: Some(200.0),
            offset_adu: 10.0,
            native_pitch_mm: p,
            ..Readout::ideal()
        })
    };
    assert_eq!(native(Some(0.1)).readout.binning(0.2, 0.2), 4.0);
    // Offset 4·10, full well 4·200, ADC range 4·255.
    assert_eq!(
        native(Some(0.1)).record(&e, 0).unwrap()[0].data,
        [40.0, 140.0, 740.0, 800.0]
    );
    // The same panel read at its own pitch saturates at 200.
    assert_eq!(
        native(None).record(&e, 0).unwrap()[0].data,
        [10.0, 110.0, 200.0, 200.0]
    );
    // Electronic noise adds in quadrature: variance 4·σ², over 10⁵ pixels.
    let n = 100_000;
    let flat = ExpectedImage::zeros(&Detector::new(100, 1000, 0.2), 1);
    let m = noiseless(Readout {
        electronic_noise_adu: 3.0,
        native_pitch_mm: Some(0.1),
        ..Readout::ideal()
    });
    let v = &m.record(&flat, 5).unwrap()[0].data;
    let mu = v.iter().map(|&x| f64::from(x)).sum::<f64>() / n as f64;
    let var = v.iter().map(|&x| (f64::from(x) - mu).powi(2)).sum::<f64>() / (n - 1) as f64;
    // Standard error of the variance: √(2/n) = 0.45 %; 2 % is 4.5 standard errors.
    assert!((var / 36.0 - 1.0).abs() < 0.02, "variance {var} vs 4·3²");
}
