//! Procedural chest phantoms: determinism (repeat, thread count, seed), HU inside the
//! published range of every tissue, and anatomy where it belongs in the LPS frame
//! (+x patient left, +y posterior, +z head).

use glam::DVec3;
use std::collections::HashMap;
use std::sync::OnceLock;
use tomograf_datasets::anatomy::{
    AnatomySpec, ArmPose, Labeled, Profile, Structure, Tissue, describe, generate,
    generate_labeled, hu_range,
};

/// 96³ voxels of 4.5 mm: 432 mm in every direction, enough for the chest and some neck.
const DIMS: [usize; 3] = [96, 96, 96];
const SPACING: [f64; 3] = [4.5, 4.5, 4.5];

fn spec(seed: u64, profile: Profile) -> AnatomySpec {
    AnatomySpec::new(seed, profile, DIMS, SPACING)
}

fn with_devices(seed: u64, profile: Profile) -> AnatomySpec {
    let mut s = spec(seed, profile);
    s.table = true;
    s.pacemaker = true;
    s
}

/// Full-chest phantoms with table and pacemaker for a few seeds, generated once.
fn full(seed: u64) -> &'static Labeled {
    static CACHE: OnceLock<Vec<Labeled>> = OnceLock::new();
    &CACHE.get_or_init(|| {
        (0..4)
            .map(|s| generate_labeled(&with_devices(s, Profile::FullChest)).unwrap())
            .collect()
    })[seed as usize]
}

/// The phantom of `spec` generated on a pool of `threads` threads.
fn on_threads(threads: usize, spec: &AnatomySpec) -> Labeled {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| generate_labeled(spec).unwrap())
}

/// World centre of every voxel, in storage order.
fn positions(l: &Labeled) -> impl Iterator<Item = DVec3> + '_ {
    let v = &l.volume;
    let [nx, ny, nz] = v.dims();
    (0..nz).flat_map(move |k| {
        (0..ny).flat_map(move |j| {
            (0..nx).map(move |i| v.index_to_world(DVec3::new(i as f64, j as f64, k as f64)))
        })
    })
}

/// Voxel positions of a structure.
fn voxels_of(l: &Labeled, s: Structure) -> Vec<DVec3> {
    positions(l)
        .zip(&l.structure)
        .filter(|(_, st)| **st == s)
        .map(|(p, _)| p)
        .collect()
}

fn centroid(pts: &[DVec3]) -> DVec3 {
    assert!(!pts.is_empty());
    pts.iter().copied().sum::<DVec3>() / pts.len() as f64
}

fn litres(l: &Labeled, n: usize) -> f64 {
    let s = l.volume.spacing();
    n as f64 * s.x * s.y * s.z / 1e6
}

#[test]
fn same_spec_same_bytes_and_seeds_differ() {
    let s = with_devices(11, Profile::FullChest);
    let a = generate(&s).unwrap();
    let b = generate(&s).unwrap();
    assert_eq!(a.data(), b.data());
    let mut other = s.clone();
    other.seed = 12;
    let c = generate(&other).unwrap();
    let differing = a
        .data()
        .iter()
        .zip(c.data())
        .filter(|(x, y)| x != y)
        .count();
    assert!(differing > a.len() / 10, "only {differing} voxels differ");
}

#[test]
fn thread_count_does_not_change_the_result() {
    let s = with_devices(5, Profile::LidcCropped);
    let (one, two) = (on_threads(1, &s), on_threads(2, &s));
    assert_eq!(one.volume.data(), two.volume.data());
    assert_eq!(one.tissue, two.tissue);
    assert_eq!(one.structure, two.structure);
    assert_eq!(one.patient, two.patient);
}

#[test]
fn grid_is_centred_with_identity_direction() {
    let v = &full(0).volume;
    assert_eq!(v.dims(), DIMS);
    assert!(v.centre().length() < 1e-9);
    assert_eq!(v.direction(), glam::DMat3::IDENTITY);
    assert_eq!(v.spacing(), DVec3::from(SPACING));
}

#[test]
fn every_voxel_lies_in_its_tissue_range() {
    let mut labeled: Vec<&Labeled> = (0..4).map(full).collect();
    let lidc = generate_labeled(&with_devices(3, Profile::LidcCropped)).unwrap();
    labeled.push(&lidc);
    let mut seen: HashMap<Tissue, (usize, f64)> = HashMap::new();
    for l in labeled {
        let (lo, hi) = l.volume.min_max();
        assert!(lo >= -1024.0 && hi <= 3071.0, "{lo} … {hi}");
        for (&t, &hu) in l.tissue.iter().zip(l.volume.data()) {
            let (a, b) = hu_range(t);
            assert!(
                hu >= a && hu <= b,
                "{t:?} voxel at {hu} HU outside [{a}, {b}]"
            );
            let e = seen.entry(t).or_default();
            e.0 += 1;
            e.1 += hu as f64;
        }
    }
    // Every tissue class shows up (nodules depend on the seed), with a plausible mean.
    for t in Tissue::ALL {
        if t == Tissue::Nodule {
            continue;
        }
        let &(n, sum) = seen.get(&t).unwrap_or_else(|| panic!("no {t:?} voxels"));
        let mean = sum / n as f64;
        let expect = match t {
            Tissue::Air => -1000.0,
            Tissue::Padding => -1024.0,
            Tissue::Lung => -850.0,
            Tissue::Fat => -100.0,
            Tissue::Bone => 1000.0,
            Tissue::Marrow => 250.0,
            Tissue::Metal => 2900.0,
            Tissue::Foam => -920.0,
            Tissue::Plastic => 150.0,
            Tissue::Cartilage => 120.0,
            _ => 43.0,
        };
        assert!((mean - expect).abs() < 110.0, "{t:?}: mean {mean}");
    }
}

#[test]
fn lungs_on_both_sides_with_adult_volumes() {
    for seed in 0..4 {
        let l = full(seed);
        for (st, sign) in [(Structure::LungLeft, 1.0), (Structure::LungRight, -1.0)] {
            let v = voxels_of(l, st);
            let lateral = v.iter().filter(|p| sign * p.x > 20.0).count();
            assert!(
                lateral as f64 > 0.9 * v.len() as f64,
                "seed {seed} {st:?}: {lateral} of {} voxels at |x| > 20 mm on its side",
                v.len()
            );
            // Parenchyma only (vessels and airways inside it are labelled apart).
            let litres = litres(l, v.len());
            assert!(
                (1.0..4.0).contains(&litres),
                "seed {seed} {st:?}: {litres} L"
            );
        }
        // The apex is narrower than the base: compare the lung areas near each end.
        let p = &l.patient;
        let lung: Vec<DVec3> = [Structure::LungLeft, Structure::LungRight]
            .into_iter()
            .flat_map(|s| voxels_of(l, s))
            .collect();
        let h = p.lung_apex_z_mm - p.lung_base_z_mm;
        let band = |lo: f64, hi: f64| {
            lung.iter()
                .filter(|q| q.z > p.lung_base_z_mm + lo * h && q.z < p.lung_base_z_mm + hi * h)
                .count()
        };
        let (top, mid) = (band(0.88, 0.98), band(0.35, 0.45));
        assert!(
            top * 2 < mid,
            "seed {seed}: {top} lung voxels near the apex, {mid} at mid height"
        );
        // Diaphragm domes: no lung under the dome tops near the dome centres.
        assert!(lung.iter().all(|q| q.z >= p.lung_base_z_mm - 3.0));
    }
}

#[test]
fn heart_spine_and_ribs_where_they_belong() {
    for seed in 0..4 {
        let l = full(seed);
        let p = &l.patient;
        let thorax = |q: &&DVec3| q.z > p.lung_base_z_mm && q.z < p.lung_apex_z_mm;
        let spine: Vec<DVec3> = voxels_of(l, Structure::Vertebra)
            .iter()
            .filter(thorax)
            .copied()
            .collect();
        let spine_c = centroid(&spine);
        assert!(spine_c.y > 0.0, "seed {seed}: spine at y = {}", spine_c.y);
        assert!(
            spine_c.x.abs() < 3.0,
            "seed {seed}: spine at x = {}",
            spine_c.x
        );
        let heart_c = centroid(&voxels_of(l, Structure::Heart));
        assert!(
            heart_c.y < spine_c.y - 20.0,
            "seed {seed}: heart {heart_c} spine {spine_c}"
        );
        assert!(
            heart_c.x > 0.0 && heart_c.x < 50.0,
            "seed {seed}: heart {heart_c}"
        );
        assert!((heart_c - DVec3::from(p.heart_centre_mm)).length() < 25.0);
        let ribs = voxels_of(l, Structure::Rib);
        let left = ribs.iter().filter(|q| q.x > 30.0).count();
        let right = ribs.iter().filter(|q| q.x < -30.0).count();
        assert!(
            left > 300 && right > 300,
            "seed {seed}: ribs {left} left, {right} right"
        );
        let ratio = left as f64 / right as f64;
        assert!(
            (0.7..1.4).contains(&ratio),
            "seed {seed}: rib ratio {ratio}"
        );
        // Ribs are bone outside, marrow inside; the sternum is anterior, on the midline.
        let sternum = centroid(&voxels_of(l, Structure::Sternum));
        assert!(sternum.y < heart_c.y && sternum.x.abs() < 3.0, "{sternum}");
        // Trachea (air) between sternum and spine; descending aorta left of the spine.
        let lumen = voxels_of(l, Structure::AirwayLumen);
        let trachea: Vec<DVec3> = lumen
            .iter()
            .filter(|q| q.z > p.lung_apex_z_mm - 60.0 && q.x.abs() < 30.0)
            .copied()
            .collect();
        let tc = centroid(&trachea);
        assert!(tc.y < spine_c.y && tc.y > sternum.y, "trachea {tc}");
        let aorta: Vec<DVec3> = voxels_of(l, Structure::Aorta)
            .into_iter()
            .filter(|q| q.z < heart_c.z)
            .collect();
        assert!(
            centroid(&aorta).x > 10.0,
            "descending aorta {}",
            centroid(&aorta)
        );
    }
}

#[test]
fn nodules_sit_in_the_lungs() {
    let mut found = 0;
    for seed in 0..12 {
        let p = describe(&spec(seed, Profile::FullChest)).unwrap();
        assert!(p.nodules.len() <= 3);
        for n in &p.nodules {
            assert!((3.0..=30.0).contains(&n.diameter_mm), "{n:?}");
            assert!((0.0..=100.0).contains(&n.hu));
            assert!(n.centre_mm[2] > p.lung_base_z_mm && n.centre_mm[2] < p.lung_apex_z_mm);
            found += 1;
        }
    }
    assert!(found > 3, "only {found} nodules in 12 patients");
    // In a generated volume, the voxel at a large nodule's centre is nodule.
    for seed in 0..4 {
        let l = full(seed);
        for n in l.patient.nodules.iter().filter(|n| n.diameter_mm > 10.0) {
            let idx = l.volume.world_to_index(DVec3::from(n.centre_mm)).round();
            let [nx, ny, _] = l.volume.dims();
            let i = idx.x as usize + nx * (idx.y as usize + ny * idx.z as usize);
            assert_eq!(l.structure[i], Structure::Nodule, "seed {seed}: {n:?}");
        }
    }
}

#[test]
fn pacemaker_in_left_upper_chest_with_metal_values() {
    for seed in 0..4 {
        let l = full(seed);
        let can = voxels_of(l, Structure::Pacemaker);
        let c = centroid(&can);
        let heart = centroid(&voxels_of(l, Structure::Heart));
        assert!(
            c.x > 0.0 && c.y < 0.0 && c.z > heart.z + 30.0,
            "seed {seed}: can {c}"
        );
        assert!((c - DVec3::from(l.patient.pacemaker_mm.unwrap())).length() < 8.0);
        // ≈ 50 × 45 × 8 mm: 18 cm³.
        let cc = litres(l, can.len()) * 1000.0;
        assert!(
            (8.0..30.0).contains(&cc),
            "seed {seed}: can volume {cc} cm³"
        );
        for (t, (st, hu)) in l.tissue.iter().zip(l.structure.iter().zip(l.volume.data())) {
            if matches!(st, Structure::Pacemaker | Structure::PacemakerLead) {
                assert_eq!(*t, Tissue::Metal);
                assert!(*hu >= 2000.0 && *hu <= 3071.0, "{hu}");
            }
        }
        // Leads reach the heart.
        let leads = voxels_of(l, Structure::PacemakerLead);
        assert!(leads.iter().any(|q| q.z < heart.z + 10.0), "seed {seed}");
    }
    // Off by default.
    let plain = generate_labeled(&spec(0, Profile::FullChest)).unwrap();
    assert!(!plain.structure.contains(&Structure::Pacemaker));
    assert!(!plain.structure.contains(&Structure::Table));
    assert!(!plain.tissue.contains(&Tissue::Metal));
}

#[test]
fn table_lies_under_the_patient() {
    for seed in 0..4 {
        let l = full(seed);
        let mut body_max = f64::NEG_INFINITY;
        let mut table_min = f64::INFINITY;
        let mut table_n = 0;
        for (q, st) in positions(l).zip(&l.structure) {
            if *st == Structure::Table {
                table_min = table_min.min(q.y);
                table_n += 1;
            } else if st.is_body() {
                body_max = body_max.max(q.y);
            }
        }
        assert!(table_n > 1000, "seed {seed}: {table_n} table voxels");
        assert!(
            table_min > body_max,
            "seed {seed}: table from y = {table_min}, body to {body_max}"
        );
        let top = l.patient.table_top_y_mm.unwrap();
        assert!(
            top > body_max - 1.0 && top < body_max + 30.0,
            "{top} vs {body_max}"
        );
    }
}

/// Non-air voxels (anything but outside air, padding and table) matching `pred`.
fn body_count(l: &Labeled, pred: impl Fn(DVec3) -> bool) -> usize {
    positions(l)
        .zip(&l.structure)
        .filter(|(q, st)| st.is_body() && pred(*q))
        .count()
}

#[test]
fn full_chest_shows_neck_and_arms_that_lidc_lacks() {
    // 6 mm voxels: 576 mm wide, so that arms beside a wide chest are inside the grid.
    let wide = |seed, profile| AnatomySpec::new(seed, profile, [96, 72, 80], [6.0, 6.0, 6.0]);
    let mut poses = Vec::new();
    for seed in 0..12 {
        let full = describe(&wide(seed, Profile::FullChest)).unwrap();
        let lidc = describe(&wide(seed, Profile::LidcCropped)).unwrap();
        assert!(lidc.arms.is_none() && full.field_of_view.is_none());
        // Same patient in both profiles.
        assert_eq!(full.width_mm, lidc.width_mm);
        assert_eq!(full.nodules, lidc.nodules);
        poses.push(full.arms.unwrap());
    }
    let down = poses.iter().position(|a| *a == ArmPose::Down).unwrap() as u64;
    let raised = poses.iter().position(|a| *a == ArmPose::Raised).unwrap() as u64;
    for seed in [down, raised] {
        let f = generate_labeled(&wide(seed, Profile::FullChest)).unwrap();
        let c = generate_labeled(&wide(seed, Profile::LidcCropped)).unwrap();
        let p = &f.patient;
        let fov = c.patient.field_of_view.unwrap();
        // Neck above the apex.
        let above = |q: DVec3| q.z > p.lung_apex_z_mm + 20.0;
        assert!(body_count(&f, above) > 500, "seed {seed}: no neck");
        assert_eq!(body_count(&c, above), 0, "seed {seed}: LIDC shows a neck");
        assert!(fov.z_max_mm < p.lung_apex_z_mm + 20.0 && fov.z_min_mm < p.lung_base_z_mm);
        // Outside the cropped field of view: padding only.
        for (q, (st, hu)) in positions(&c).zip(c.structure.iter().zip(c.volume.data())) {
            if q.z > fov.z_max_mm + 3.0 || q.x.hypot(q.y) > fov.radius_mm + 3.0 {
                assert_eq!(*st, Structure::OutsideFov);
                assert_eq!(*hu, -1024.0);
            }
        }
        // Nothing lateral of the chest in LIDC.
        let lateral = |q: DVec3| q.x.abs() > p.width_mm / 2.0 + 5.0;
        assert_eq!(body_count(&c, lateral), 0, "seed {seed}");
        let arm_bone = voxels_of(&f, Structure::ArmBone);
        assert!(voxels_of(&c, Structure::ArmBone).is_empty());
        if seed == down {
            // Upper arms beside the chest, lateral of the ribs.
            let beside = |q: DVec3| lateral(q) && q.z.abs() < 50.0;
            assert!(
                body_count(&f, beside) > 500,
                "seed {seed}: no arms beside the chest"
            );
            assert!(arm_bone.iter().any(|q| q.x > p.width_mm / 2.0 && q.z < 0.0));
            assert!(
                arm_bone
                    .iter()
                    .any(|q| q.x < -p.width_mm / 2.0 && q.z < 0.0)
            );
        } else {
            // Arms raised beside the head: humeri above the shoulders.
            assert!(
                arm_bone
                    .iter()
                    .any(|q| q.z > p.lung_apex_z_mm + 60.0 && q.x > 50.0)
            );
            assert!(
                arm_bone
                    .iter()
                    .any(|q| q.z > p.lung_apex_z_mm + 60.0 && q.x < -50.0)
            );
            assert!(body_count(&f, |q| lateral(q) && q.z.abs() < 50.0) == 0);
        }
    }
}

#[test]
fn bad_specs_are_refused() {
    let mut s = spec(1, Profile::FullChest);
    s.dims = [0, 10, 10];
    assert!(generate(&s).is_err());
    let mut s = spec(1, Profile::FullChest);
    s.spacing_mm = [1.0, f64::NAN, 1.0];
    assert!(generate(&s).unwrap_err().to_string().contains("spacing"));
    assert!(Profile::parse("chest").is_err());
    assert_eq!(Profile::parse("lidc").unwrap(), Profile::LidcCropped);
    let json = serde_json::to_string(&with_devices(3, Profile::FullChest)).unwrap();
    assert!(json.contains("\"full-chest\""));
    let back: AnatomySpec = serde_json::from_str(&json).unwrap();
    assert_eq!(
        generate(&back).unwrap().data()[..1000],
        generate(&with_devices(3, Profile::FullChest))
            .unwrap()
            .data()[..1000]
    );
}

/// Soft-tissue heterogeneity: only muscle, organs, blood and myocardium change, their spread
/// grows to about the asked standard deviation (60 HU: 55–65 with the few HU of white noise
/// and the clamp), it is correlated (neighbours alike) and the same on any thread count; the
/// spec without it serialises as before (so earlier items keep their ids) and an impossible
/// value is refused by name.
#[test]
fn soft_tissue_heterogeneity_changes_soft_tissue_only() {
    let plain = generate_labeled(&spec(4, Profile::LidcCropped)).unwrap();
    let mut s = spec(4, Profile::LidcCropped);
    s.heterogeneity_hu = 60.0;
    let (het, het2) = (on_threads(1, &s), on_threads(2, &s));
    assert_eq!(het.volume.data(), het2.volume.data());
    assert_eq!(het.tissue, plain.tissue);
    let soft = |t: Tissue| {
        matches!(
            t,
            Tissue::Muscle | Tissue::SoftTissue | Tissue::Blood | Tissue::Heart
        )
    };
    let (mut n, mut s1, mut s2, mut lag) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (a, b) = (plain.volume.data(), het.volume.data());
    for (i, t) in het.tissue.iter().enumerate() {
        if !soft(*t) {
            assert_eq!(a[i], b[i], "voxel {i} of {t:?} changed");
            continue;
        }
        let d = (b[i] - a[i]) as f64;
        n += 1.0;
        s1 += d;
        s2 += d * d;
        if i + 1 < b.len() && soft(het.tissue[i + 1]) {
            lag += d * (b[i + 1] - a[i + 1]) as f64;
        }
    }
    let sd = (s2 / n - (s1 / n).powi(2)).sqrt();
    assert!((50.0..70.0).contains(&sd), "added texture sd {sd:.1} HU");
    assert!(lag / s2 > 0.7, "neighbours correlate: {:.2}", lag / s2);

    let json = serde_json::to_string(&spec(4, Profile::LidcCropped)).unwrap();
    assert!(!json.contains("heterogeneity"), "{json}");
    for bad in [-1.0, f64::NAN, 500.0] {
        s.heterogeneity_hu = bad;
        let e = generate(&s).unwrap_err().to_string();
        assert!(e.contains("heterogeneity"), "{e}");
    }
}

/// Organ spread: at `k` the heart's size lies `k` times as far from its range's centre as
/// at 1, for the same seed (every other draw unchanged: the body is the same), the domes stay
/// inside the lungs' lower half, the spec at 1 serialises as before (earlier items keep their
/// ids) and an impossible spread is refused by name.
#[test]
fn organ_spread_widens_the_heart_and_domes_only() {
    let centre = 0.5 * (0.88 + 1.15);
    let mut widest = 0.0f64;
    for seed in 0..40 {
        let base = describe(&spec(seed, Profile::FullChest)).unwrap();
        for k in [0.0, 2.5, 3.0] {
            let mut s = spec(seed, Profile::FullChest);
            s.organ_spread = k;
            let p = describe(&s).unwrap();
            let expected = centre + k * (base.heart_scale - centre);
            assert!(
                (p.heart_scale - expected).abs() < 1e-12,
                "seed {seed} k {k}: heart {} against {expected}",
                p.heart_scale
            );
            assert_eq!((p.width_mm, p.depth_mm), (base.width_mm, base.depth_mm));
            assert_eq!(
                (p.lung_apex_z_mm, p.lung_base_z_mm),
                (base.lung_apex_z_mm, base.lung_base_z_mm)
            );
            let lung_h = p.lung_apex_z_mm - p.lung_base_z_mm;
            for top in p.dome_top_z_mm {
                let h = top - p.lung_base_z_mm;
                assert!(
                    h >= 25.0 - 1e-9 && h <= 0.45 * lung_h + 1e-9,
                    "seed {seed}: dome {h}"
                );
            }
            if k == 0.0 {
                assert!((p.heart_scale - centre).abs() < 1e-12);
            }
            if k == 3.0 {
                widest = widest.max((p.heart_scale - centre).abs());
            }
        }
    }
    // Forty seeds at 3 × reach hearts beyond the drawn range (±0.135) by far.
    assert!(widest > 0.3, "widest heart offset {widest}");
    let json = serde_json::to_string(&spec(4, Profile::LidcCropped)).unwrap();
    assert!(!json.contains("organ_spread"), "{json}");
    let mut s = spec(4, Profile::LidcCropped);
    s.organ_spread = 2.0;
    let json = serde_json::to_string(&s).unwrap();
    assert!(json.contains("\"organ_spread\":2.0"), "{json}");
    for bad in [-0.5, f64::NAN, 3.5] {
        s.organ_spread = bad;
        let e = generate(&s).unwrap_err().to_string();
        assert!(e.contains("organ spread"), "{e}");
    }
}

/// Deformation: the phantom warped by a smooth field moves its voxels (another volume), is
/// the same on any thread count, interpolates (no value outside the unwarped phantom's
/// range), keeps each tissue's share of the grid to a few per cent (a smooth, nearly
/// volume-preserving warp), serialises as before at 0 and is refused out of range by name.
#[test]
fn deformation_warps_smoothly_and_keeps_the_tissues() {
    let plain = generate_labeled(&spec(5, Profile::FullChest)).unwrap();
    let mut s = spec(5, Profile::FullChest);
    s.deform_mm = 5.0;
    let (warped, warped2) = (on_threads(1, &s), on_threads(2, &s));
    assert_eq!(warped.volume.data(), warped2.volume.data());
    assert_eq!(warped.tissue, warped2.tissue);
    let (a, b) = (plain.volume.data(), warped.volume.data());
    let changed = a.iter().zip(b).filter(|(x, y)| x != y).count();
    assert!(
        changed > a.len() / 4,
        "{changed} of {} voxels moved",
        a.len()
    );
    let (lo, hi) = a
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(
        b.iter().all(|&v| v >= lo && v <= hi),
        "a value outside {lo}…{hi}"
    );
    let share = |l: &Labeled, t: Tissue| {
        l.tissue.iter().filter(|&&x| x == t).count() as f64 / l.tissue.len() as f64
    };
    for t in [Tissue::Lung, Tissue::Fat, Tissue::Muscle, Tissue::Bone] {
        let (p, w) = (share(&plain, t), share(&warped, t));
        assert!((w - p).abs() < 0.05 * p + 0.002, "{t:?}: {p:.4} → {w:.4}");
    }
    assert_eq!(warped.patient.heart_scale, plain.patient.heart_scale);
    let json = serde_json::to_string(&spec(5, Profile::FullChest)).unwrap();
    assert!(!json.contains("deform"), "{json}");
    assert!(
        serde_json::to_string(&s)
            .unwrap()
            .contains("\"deform_mm\":5.0")
    );
    for bad in [-1.0, f64::INFINITY, 31.0] {
        s.deform_mm = bad;
        let e = generate(&s).unwrap_err().to_string();
        assert!(e.contains("deformation"), "{e}");
    }
}
