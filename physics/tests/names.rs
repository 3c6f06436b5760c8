//! The name tables scenes, the command line and Python share (`Projector::from_name`,
//! `Quantity::from_name`, `Output::from_name`): every documented name parses, in any case,
//! and an unknown one is named with the choices.

use tomograf_physics::detector::Output;
use tomograf_sim::{Projector, Quantity};

#[test]
fn documented_names_parse_and_unknown_ones_are_named() {
    assert_eq!(
        Projector::from_name("siddon", 0.5).unwrap(),
        Projector::Siddon
    );
    assert_eq!(
        Projector::from_name("Trilinear", 0.25).unwrap(),
        Projector::Trilinear { step_voxels: 0.25 }
    );
    let e = Projector::from_name("montecarlo", 0.5)
        .unwrap_err()
        .to_string();
    assert_eq!(e, "unknown projector 'montecarlo': use siddon or trilinear");

    assert_eq!(
        Quantity::from_name("line-integral", 1.0).unwrap(),
        Quantity::LineIntegral
    );
    assert_eq!(
        Quantity::from_name("line_integral", 1.0).unwrap(),
        Quantity::LineIntegral
    );
    assert_eq!(
        Quantity::from_name("transmission", 1.0).unwrap(),
        Quantity::Transmission
    );
    assert_eq!(
        Quantity::from_name("intensity", 1e4).unwrap(),
        Quantity::Intensity { i0: 1e4 }
    );
    // Checked: I0 must be finite and > 0.
    assert!(Quantity::from_name("intensity", 0.0).is_err());
    let e = Quantity::from_name("dose", 1.0).unwrap_err().to_string();
    assert!(
        e.starts_with("unknown quantity 'dose': use line-integral"),
        "{e}"
    );

    for (name, out) in [
        ("raw", Output::Raw),
        ("flat-field", Output::FlatField),
        ("LOG-LINE-INTEGRAL", Output::LogLineIntegral),
    ] {
        assert_eq!(Output::from_name(name).unwrap(), out);
    }
    let e = Output::from_name("log").unwrap_err().to_string();
    assert_eq!(
        e,
        "unknown signal 'log': use raw, flat-field or log-line-integral"
    );
}
