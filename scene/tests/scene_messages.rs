//! A scene file's conflicting settings are refused naming the scene file's section and key
//! first (the flag beside it), so a user who wrote a TOML scene, not flags, can find the
//! line (issue 50's drift list). Each scene uses the built-in phantom, so no file is read.

use tomograf_scene::prepare::prepare;
use tomograf_scene::scene::Scene;

fn refused(toml: &str) -> String {
    let scene = Scene::from_toml(toml, None).expect("the scene parses");
    match prepare(&scene) {
        Ok(_) => panic!("scene accepted:\n{toml}"),
        Err(e) => format!("{e:#}"),
    }
}

#[test]
fn conflicting_scene_settings_name_their_section_and_key() {
    let small = "[volume]\nphantom_dims = [8, 8, 8]\n[detector]\nrows = 4\ncols = 4\n";
    for (extra, wanted) in [
        (
            "[projector]\nkind = \"siddon\"\nstep_voxels = 0.25\n",
            "[projector] step_voxels (--step)",
        ),
        (
            "[output]\nquantity = \"line-integral\"\ni0 = 2.0\n",
            "[output] i0 (--i0)",
        ),
        (
            "[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[output]\nquantity = \"transmission\"\n",
            "[output] quantity and i0",
        ),
        (
            "[acquisition]\npreset = \"kv-flat-panel-120kvp\"\n[projector]\nempty_below_per_mm = 1e-4\n",
            "[projector] empty_below_per_mm (--empty-below)",
        ),
    ] {
        let e = refused(&format!("{small}{extra}"));
        assert!(e.contains(wanted), "wanted {wanted:?} in: {e}");
    }
    // The energy of a μ volume: the built-in phantom is μ, so an energy is refused.
    let e = refused("[volume]\nphantom_dims = [8, 8, 8]\nunits = \"mu\"\nenergy_kev = 60.0\n");
    assert!(e.contains("[volume] energy_kev (--energy-kev) only"), "{e}");
    // With real detector physics the CT's energy is the calibration's, not the DRR's.
    let e = refused(
        "[volume]\nphantom_dims = [8, 8, 8]\nenergy_kev = 60.0\n\
         [acquisition]\npreset = \"kv-flat-panel-120kvp\"\n",
    );
    assert!(
        e.contains("[volume] energy_kev (--energy-kev) is the"),
        "{e}"
    );
}
