use glam::DVec3;
use std::time::Instant;
use tomograf_sim::acquisition::Acquisition;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::tissue::TissueModel;
use tomograf_sim::*;

fn ms<T>(f: impl Fn() -> T) -> (f64, T) {
    let _ = f();
    let mut ts = vec![];
    let mut out = f();
    for _ in 0..15 {
        let t = Instant::now();
        out = f();
        ts.push(t.elapsed().as_secs_f64() * 1e3);
    }
    ts.sort_by(f64::total_cmp);
    (ts[0], out)
}

fn main() {
    let hu = Phantom::thorax()
        .voxelize([256, 256, 256], DVec3::new(1.4, 1.4, 1.3), DVec3::ZERO)
        .unwrap();
    let mut acq = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    if std::env::args().nth(1).as_deref() == Some("5") {
        acq.materials = TissueModel::five_tissue();
    }
    if std::env::args().nth(1).as_deref() == Some("1") {
        acq.materials = TissueModel::water(70.0);
    }
    let p = acq.prepare(&hu, 1).unwrap();
    println!(
        "materials {:?} bins {}",
        p.composition().materials(),
        p.integrator().energies_kev().len()
    );
    let mu = Attenuation::hounsfield_at_kev(60.0)
        .unwrap()
        .to_mu(hu.clone())
        .unwrap();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(256, 256, 2.0),
        isocentre: DVec3::ZERO,
    };
    let v = g.view(Pose::new(30.0, 0.0)).unwrap();
    let r = Renderer::new(&mu, Projector::Siddon).unwrap();
    let (t_mono, _) = ms(|| r.render(&v).unwrap());
    let (t_mt, mt) = ms(|| p.mass_thickness(Projector::Siddon, &v).unwrap());
    let (t_int, obj) = ms(|| p.integrator().expected(&mt, &v, 2.0).unwrap());
    let (t_open, _) = ms(|| p.integrator().open(&v, 2.0).unwrap());
    let (t_rec, _) = ms(|| acq.detector.record(&obj, 3).unwrap());
    let (t_acq, _) = ms(|| p.acquire(Projector::Siddon, &v, 3).unwrap());
    println!(
        "mono {t_mono:.1} ms | mass thickness {t_mt:.1} | integrate {t_int:.1} | open {t_open:.1} | record {t_rec:.1} | acquire(all, cached flat) {t_acq:.1}"
    );
    println!(
        "poly/mono = {:.2}; detector adds {:.0}%",
        (t_mt + t_int) / t_mono,
        100.0 * t_rec / (t_mt + t_int)
    );
}
