//! Spectra: beam figures against SpekPy's own computation, and user spectrum files.
//!
//! Reference: SpekPy 2.5.4 (Poludniowski et al., Med. Phys. 48 (2021) 3630) `get_hvl1`,
//! `get_hvl2`, `get_emean`, `get_kerma`, `get_flu` for the same beams (12° W anode,
//! 2.5 mm Al + the added filters), printed by `python3 scripts/make_spectra.py --reference`.
//! The spectra themselves come from SpekPy, so this is not an independent check of the
//! bremsstrahlung model; it checks everything this crate does with them — bin and unit
//! conventions (photons/mm² vs /cm², per bin vs per keV), filtration with our Elam/xraydb
//! attenuation instead of SpekPy's PENELOPE data, air kerma with NIST μ_en/ρ, and the HVL
//! solver. Tolerances (observed in brackets): fluence and mean energy 0.2 % (≤ 0.12 %; 0.00 %
//! without added filters, the rest is Elam vs PENELOPE attenuation in the filters); HVL1 and
//! HVL2 1 % (≤ 0.61 %); air kerma 2 % (≤ 1.3 %: NIST's air μ_en/ρ grid is 10–20 keV apart
//! where the photo-effect hands over to Compton, and SpekPy uses its own μ_en/ρ data).

use std::io::Write;
use tomograf_physics::spectrum::{Filter, Spectrum};
use tomograf_sim::material::by_name;

/// (kVp, added Al mm, added Cu mm, HVL1 mm Al, HVL2 mm Al, mean keV, µGy/mAs at 1 m,
/// photons/mm²/mAs at 1 m), SpekPy 2.5.4.
type Beam = (f64, f64, f64, f64, f64, f64, f64, f64);
const SPEKPY: [Beam; 8] = [
    (50.0, 0.0, 0.0, 1.7504, 2.3192, 32.2226, 33.3575, 436328.0),
    (70.0, 0.0, 0.0, 2.3971, 3.4604, 39.4045, 64.8985, 1.10171e6),
    (70.0, 1.0, 0.0, 2.8927, 3.9579, 41.0471, 46.8273, 881709.0),
    (
        100.0, 0.0, 0.0, 3.4590, 5.3992, 49.1481, 118.8958, 2.51167e6,
    ),
    (100.0, 0.0, 0.2, 6.7173, 8.1229, 57.6765, 45.9684, 1.30995e6),
    (
        120.0, 0.0, 0.0, 4.2200, 6.6730, 54.4469, 158.7081, 3.61543e6,
    ),
    (120.0, 1.0, 0.1, 6.8379, 8.7127, 60.8700, 85.6772, 2.37534e6),
    (
        150.0, 0.0, 0.3, 9.8822, 11.3524, 73.2217, 101.1117, 2.93346e6,
    ),
];

fn rel(a: f64, b: f64) -> f64 {
    a / b - 1.0
}

#[test]
fn beam_figures_match_spekpy() {
    let al = by_name("al").unwrap();
    for (kvp, add_al, add_cu, hvl1, hvl2, mean, kerma, flu) in SPEKPY {
        let mut filters = Vec::new();
        if add_al > 0.0 {
            filters.push(Filter::named("al", add_al).unwrap());
        }
        if add_cu > 0.0 {
            filters.push(Filter::named("cu", add_cu).unwrap());
        }
        let s = Spectrum::tungsten(kvp, &filters).unwrap();
        let got = [
            ("fluence", s.total_fluence(), flu, 0.002),
            ("mean energy", s.mean_energy_kev(), mean, 0.002),
            ("air kerma", s.air_kerma_ugy_per_mas().unwrap(), kerma, 0.02),
            ("HVL1", s.half_value_layer_mm(&al).unwrap(), hvl1, 0.02),
            (
                "HVL2",
                s.second_half_value_layer_mm(&al).unwrap(),
                hvl2,
                0.02,
            ),
        ];
        for (what, ours, theirs, tol) in got {
            let d = rel(ours, theirs);
            eprintln!(
                "{kvp} kVp +{add_al} Al +{add_cu} Cu: {what} {ours:.4} vs SpekPy {theirs:.4} ({:+.2} %)",
                100.0 * d
            );
            assert!(
                d.abs() < tol,
                "{kvp} kVp +{add_al} mm Al +{add_cu} mm Cu: {what} {ours} vs {theirs}"
            );
        }
    }
}

#[test]
fn hvl_and_mean_energy_rise_with_filtration_and_kvp() {
    let al = by_name("al").unwrap();
    let mut last = (0.0, 0.0);
    for kvp in [40.0, 60.0, 80.0, 100.0, 120.0, 150.0] {
        let s = Spectrum::tungsten(kvp, &[]).unwrap();
        let now = (s.half_value_layer_mm(&al).unwrap(), s.mean_energy_kev());
        assert!(now.0 > last.0 && now.1 > last.1, "{kvp}");
        last = now;
        let hard = s.filtered(&Filter::named("cu", 0.3).unwrap()).unwrap();
        assert!(hard.half_value_layer_mm(&al).unwrap() > now.0);
        // A harder beam is more homogeneous: HVL2/HVL1 grows towards 1.
        let h = |s: &Spectrum| {
            s.half_value_layer_mm(&al).unwrap() / s.second_half_value_layer_mm(&al).unwrap()
        };
        assert!(h(&hard) > h(&s) && h(&hard) < 1.0);
    }
}

fn write_tmp(text: &str) -> tempfile::NamedTempFile {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(text.as_bytes()).unwrap();
    f
}

#[test]
fn user_file_round_trip_and_formats() {
    let f = write_tmp("# my tube\nenergy_kev,photons\n20,100\n30\t250\n40 50 # tail\n\n");
    let s = Spectrum::from_file(f.path()).unwrap();
    assert_eq!(s.energies_kev(), &[20.0, 30.0, 40.0]);
    assert_eq!(s.fluence(), &[100.0, 250.0, 50.0]);
    assert_eq!(s.total_fluence(), 400.0);
    assert!((s.mean_energy_kev() - (2000.0 + 7500.0 + 2000.0) / 400.0).abs() < 1e-12);
}

/// Spectrum files as other tools write them: the same beam (20, 30, 40 keV at 100, 250, 50
/// photons/mAs/mm² at 1 m per 1 keV bin... written at 0.5 keV spacing here) in four styles.
#[test]
fn user_files_from_other_tools_load_to_the_same_beam() {
    use tomograf_physics::spectrum::FluenceUnit;
    // Reference: 0.5 keV bins, per bin, tomograf's unit; the 0 and 0.5 keV rows are empty.
    let bins = [(20.0, 100.0), (20.5, 0.0), (21.0, 250.0), (21.5, 50.0)];
    let per_bin = |scale: f64| -> String {
        bins.iter()
            .map(|(e, f)| format!("{e} {}\n", f * scale))
            .collect()
    };
    // XCIST style: a bin-count line, space separated, leading empty rows below 1 keV.
    let xcist = format!("6\n0.0 0\n0.5 0\n{}", per_bin(1.0));
    // SpekPy style: several header lines, semicolons, photons per keV per cm² (×100/0.5).
    let spekpy = format!(
        "Spectrum exported by a tool\nEnergy [keV]; Fluence [cm^-2 keV^-1 mAs^-1]\n{}",
        bins.iter()
            .map(|(e, f)| format!("{e};{}\n", f * 100.0 / 0.5))
            .collect::<String>()
    );
    // TASMIP-style table: per keV per mm², tab separated, a % comment.
    let tasmip = format!(
        "% kV=21.5\n{}",
        bins.iter()
            .map(|(e, f)| format!("{e}\t{}\n", f / 0.5))
            .collect::<String>()
    );
    // Per bin per cm², CSV with one header line.
    let csv = format!(
        "keV,photons\n{}",
        bins.iter()
            .map(|(e, f)| format!("{e},{}\n", f * 100.0))
            .collect::<String>()
    );
    let cases = [
        (xcist, FluenceUnit::PerMm2),
        (spekpy, FluenceUnit::PerCm2PerKev),
        (tasmip, FluenceUnit::PerMm2PerKev),
        (csv, FluenceUnit::PerCm2),
    ];
    for (text, unit) in cases {
        let f = write_tmp(&text);
        let s = Spectrum::from_file_in(f.path(), unit).unwrap();
        assert_eq!(s.energies_kev(), &[20.0, 20.5, 21.0, 21.5], "{unit:?}");
        for (got, (_, want)) in s.fluence().iter().zip(bins) {
            assert!(
                (got - want).abs() <= 1e-9 * want.max(1.0),
                "{unit:?}: {got} vs {want}"
            );
        }
    }
    // The default unit is tomograf's own.
    let f = write_tmp("20 4\n");
    assert_eq!(Spectrum::from_file(f.path()).unwrap().fluence(), &[4.0]);
}

#[test]
fn user_file_errors_name_the_problem_and_line() {
    let cases = [
        ("20,100\n10,5\n", "line 2", "does not increase"),
        ("20,100\n20,5\n", "line 2", "does not increase"),
        ("20,-1\n", "line 1", "≥ 0"),
        ("20,abc\n", "line 1", "not a number"),
        ("20,1,2\n", "line 1", "expected 2 columns"),
        ("0.5,10\n", "line 1", "outside 1–500 keV"),
        ("20,inf\n", "line 1", "finite"),
        ("# nothing\n", "", "no data rows"),
        ("20,0\n30,0\n", "", "total fluence is zero"),
        ("keV,n\n20,1\nfoo,1\n", "line 3", "not a number"),
        (
            "3\n20,1\n30,1\n",
            "line 1",
            "the bin count says 3 rows but 2 follow",
        ),
        ("2.5\n20,1\n", "line 1", "bin count (an integer)"),
        ("0.5,0\n1.5,2\n1.0,0\n", "line 3", "does not increase"),
    ];
    for (text, line, msg) in cases {
        let f = write_tmp(text);
        let e = Spectrum::from_file(f.path()).unwrap_err().to_string();
        assert!(e.contains(line) && e.contains(msg), "{text:?}: {e}");
        assert!(e.contains(&f.path().display().to_string()), "{e}");
    }
    let e = Spectrum::from_file("/nonexistent/spectrum.csv")
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot read spectrum file"), "{e}");
    let e = Spectrum::from_bins(vec![20.0, 30.0], vec![1.0])
        .unwrap_err()
        .to_string();
    assert!(e.contains("2 energies but 1 fluence"), "{e}");
}

/// IEC 61267 RQR beam qualities (first HVL in mm Al at a tube voltage; RRPPS lists the same
/// values rounded to 0.1 mm). Reaching them takes added Al on top of the tables' 2.5 mm; the
/// amount is printed (docs/physics.md) and checked to reproduce the target HVL, to be ≥ 0
/// (the shipped beams are softer than every RQR) and below 5 mm (RQR beams are lightly
/// filtered clinical beams). The added thickness itself has no published value to test.
#[test]
fn iec_rqr_qualities_are_reachable_with_added_aluminium() {
    let al = by_name("al").unwrap();
    for (name, kvp, hvl) in [
        ("RQR3", 50.0, 1.78),
        ("RQR5", 70.0, 2.58),
        ("RQR8", 100.0, 3.97),
        ("RQR9", 120.0, 5.00),
        ("RQR10", 150.0, 6.57),
    ] {
        let s = Spectrum::tungsten(kvp, &[]).unwrap();
        let t = s.filtration_for_hvl_mm(&al, &al, hvl).unwrap();
        let beam = s.filtered(&Filter::new(al.clone(), t).unwrap()).unwrap();
        let got = beam.half_value_layer_mm(&al).unwrap();
        let h = got / beam.second_half_value_layer_mm(&al).unwrap();
        eprintln!(
            "{name}: {kvp} kV, HVL1 {hvl} mm Al needs +{t:.2} mm Al (total {:.2}); \
             HVL1/HVL2 {h:.2}, mean {:.1} keV, {:.1} µGy/mAs at 1 m",
            t + 2.5,
            beam.mean_energy_kev(),
            beam.air_kerma_ugy_per_mas().unwrap()
        );
        assert!((got / hvl - 1.0).abs() < 1e-5, "{name}: {got}");
        assert!((0.0..5.0).contains(&t), "{name}: {t}");
    }
    let s = Spectrum::tungsten(70.0, &[]).unwrap();
    assert!(s.filtration_for_hvl_mm(&al, &al, 1.0).is_err());
}
