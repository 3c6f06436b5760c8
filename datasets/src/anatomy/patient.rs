//! Seeded patient parameters and the cross-section profiles derived from them.
//!
//! Patient frame = world frame (LPS, mm): x = 0 is the midline, y = 0 the antero-posterior
//! centre of the chest, z = 0 halfway between the lowest point of the lungs (posterior
//! costophrenic recess) and the lung apex. Every size below is in mm, scaled by the
//! patient's size factor `s` (lateral width / 340 mm) or its square root `sv` (for
//! bones, which vary less than soft tissue).

use super::ArmPose;
use super::raster::Crop;
use super::shapes::SecKey;
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Independent random streams, so that adding draws to one part never changes another.
pub(crate) mod stream {
    pub const PATIENT: u64 = 1;
    pub const TREES: u64 = 2;
    pub const NODULES: u64 = 3;
    pub const TEXTURE: u64 = 4;
}

/// A ChaCha8 generator for `stream` of `seed`.
pub(crate) fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream(stream);
    r
}

pub(crate) fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

pub(crate) fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// Exponents of the thoracic cavity's superelliptic cross-section (anterior, posterior).
pub(crate) const CAVITY_P: (f64, f64) = (2.0, 2.6);
/// Exponents of the torso outline (rounder front, flatter back).
pub(crate) const BODY_P: (f64, f64) = (2.2, 3.0);

/// Everything the generator draws for one patient, plus derived landmarks.
#[derive(Debug, Clone)]
pub(crate) struct Params {
    pub seed: u64,
    /// Size factor (lateral width / 340 mm) and its square root.
    pub s: f64,
    pub sv: f64,
    /// Lateral width and antero-posterior depth of the chest, skin to skin.
    pub width: f64,
    pub depth: f64,
    /// Subcutaneous fat thickness.
    pub fat: f64,
    /// Muscle over the ribs: lateral, anterior (pectorals), posterior (back muscles).
    pub m_lat: f64,
    pub m_ant: f64,
    pub m_post: f64,
    pub r_rib: f64,
    /// Pleural gap between ribs and lung.
    pub gap: f64,
    /// Height of one thoracic vertebra plus disc.
    pub h_vert: f64,
    /// Breathing state, 0 = expiration, 1 = deep inspiration.
    pub breath: f64,
    pub z_apex: f64,
    pub z_base: f64,
    pub lung_h: f64,
    /// Centre of the first thoracic vertebral body.
    pub z_t1: f64,
    /// Dome heights above `z_base`: [right, left].
    pub dome_h: [f64; 2],
    /// Thoracic cavity (inside the ribs) at mid chest: half-width, anterior and posterior
    /// y limits.
    pub a_e: f64,
    pub ya_e: f64,
    pub yp_e: f64,
    /// Thoracic vertebral body centre y, spinal canal radius, spinous tip y.
    pub y_vb: f64,
    pub r_canal: f64,
    pub y_tip: f64,
    pub heart_scale: f64,
    pub heart_off: DVec3,
    pub heart_turn: f64,
    pub arms: ArmPose,
    pub female: bool,
    pub breast: f64,
    pub stomach_gas: bool,
    pub nodule_count: usize,
    pub crop: Crop,
}

/// A draw `x` from the range `lo..hi` moved `k` times as far from the range's centre
/// ([`super::AnatomySpec::organ_spread`]); `x` itself, to the bit, when `k` is 1.
fn widen(x: f64, (lo, hi): (f64, f64), k: f64) -> f64 {
    if k == 1.0 {
        x
    } else {
        let c = 0.5 * (lo + hi);
        c + k * (x - c)
    }
}

impl Params {
    /// The patient of `seed` with the organs' ranges as drawn (`organ_spread` 1).
    #[cfg(test)]
    pub fn sample(seed: u64) -> Self {
        Self::sample_spread(seed, 1.0)
    }

    /// The patient of `seed`, the heart's size, position and turn and the diaphragm domes'
    /// heights drawn from ranges widened `spread` times about their centres
    /// ([`super::AnatomySpec::organ_spread`]); every other draw as at spread 1.
    pub fn sample_spread(seed: u64, spread: f64) -> Self {
        let k = spread;
        let mut r = rng(seed, stream::PATIENT);
        let width: f64 = r.random_range(280.0..400.0);
        let s = width / 340.0;
        let sv = s.sqrt();
        let depth = width * r.random_range(0.64..0.8);
        let fat_noise: f64 = r.random_range(-6.0..6.0);
        let fat = (4.0 + 22.0 * (width - 280.0) / 120.0 + fat_noise).clamp(3.0, 32.0);
        let m_lat = r.random_range(7.0..12.0) * s;
        let m_ant = r.random_range(7.0..13.0) * s;
        let m_post = r.random_range(15.0..24.0) * s;
        let r_rib = r.random_range(4.3..5.2) * sv;
        let gap = 2.0 * sv;
        let h_vert = r.random_range(21.5..25.0) * sv;
        let breath: f64 = r.random_range(0.0..1.0);
        // Apex a little above T1; lowest lung point between T11.3 (expiration) and T13.1
        // (L1, deep inspiration).
        let apex_above_t1 = 14.0 * sv;
        let lung_h = apex_above_t1 + (10.3 + 1.8 * breath) * h_vert;
        let (z_apex, z_base) = (lung_h / 2.0, -lung_h / 2.0);
        let z_t1 = z_apex - apex_above_t1;
        let dome_fraction = widen(0.27 + 0.08 * (1.0 - breath), (0.27, 0.35), k);
        let right_dome =
            dome_fraction * lung_h + widen(r.random_range(-8.0..8.0), (-8.0, 8.0), k) * sv;
        let left_dome = right_dome - widen(r.random_range(8.0..22.0), (8.0, 22.0), k) * sv;
        // Widened, the domes stay inside the lungs' lower half (at spread 1 they always are).
        let dome = |h: f64| {
            if k == 1.0 {
                h
            } else {
                h.clamp(25.0, 0.45 * lung_h)
            }
        };
        let (right_dome, left_dome) = (dome(right_dome), dome(left_dome));
        let a_e = width / 2.0 - fat - m_lat - 2.0 * r_rib - gap;
        let ya_e = -depth / 2.0 + fat + m_ant + 2.0 * r_rib + gap;
        let yp_e = depth / 2.0 - 0.8 * fat - m_post - 2.0 * r_rib - gap;
        let (b_vb, r_canal) = (13.5 * sv, 7.5 * sv);
        let y_tip = depth / 2.0 - 0.8 * fat - 10.0 * s;
        let y_vb = y_tip - 26.0 * s - 2.0 * r_canal - 2.5 - b_vb;
        let heart_scale = widen(r.random_range(0.88..1.15), (0.88, 1.15), k);
        let heart_off = DVec3::new(
            widen(r.random_range(-8.0..8.0), (-8.0, 8.0), k) * s,
            widen(r.random_range(0.0..12.0), (0.0, 12.0), k) * s,
            widen(r.random_range(-10.0..10.0), (-10.0, 10.0), k) * s,
        );
        let heart_turn = widen(r.random_range(-0.15..0.15), (-0.15, 0.15), k);
        let arms = if r.random_bool(0.5) {
            ArmPose::Down
        } else {
            ArmPose::Raised
        };
        let female = r.random_bool(0.5);
        let breast = r.random_range(0.5..1.3);
        let stomach_gas = r.random_bool(0.6);
        let nodule_count = r.random_range(0..=3usize);
        let crop = Crop {
            z0: z_base - r.random_range(5.0..30.0),
            z1: z_apex + r.random_range(2.0..15.0),
            radius: (a_e + 2.0 * r_rib + gap + 12.0).max(width / 2.0 * r.random_range(0.9..1.1)),
        };
        Params {
            seed,
            s,
            sv,
            width,
            depth,
            fat,
            m_lat,
            m_ant,
            m_post,
            r_rib,
            gap,
            h_vert,
            breath,
            z_apex,
            z_base,
            lung_h,
            z_t1,
            dome_h: [right_dome, left_dome],
            a_e,
            ya_e,
            yp_e,
            y_vb,
            r_canal,
            y_tip,
            heart_scale,
            heart_off,
            heart_turn,
            arms,
            female,
            breast,
            stomach_gas,
            nodule_count,
            crop,
        }
    }

    /// Normalised lung height: 0 at the lowest lung point, 1 at the apex.
    pub fn t(&self, z: f64) -> f64 {
        (z - self.z_base) / self.lung_h
    }

    /// Centre of thoracic vertebra `i` (1 = T1 … 12 = T12; 0, −1 … are cervical, 13 …
    /// lumbar).
    pub fn z_thoracic(&self, i: f64) -> f64 {
        self.z_t1 - (i - 1.0) * self.h_vert
    }

    /// Upper end of the manubrium (jugular notch).
    pub fn z_jugular(&self) -> f64 {
        self.z_t1 - 1.7 * self.h_vert
    }

    /// Top of the neck, where the head begins.
    pub fn z_neck_top(&self) -> f64 {
        self.z_apex + 135.0 * self.sv
    }

    /// The vertebral body's centre y at height z (cervical lordosis above T1, lumbar
    /// lordosis below T12).
    pub fn spine_y(&self, z: f64) -> f64 {
        let t12 = self.z_thoracic(12.0);
        self.y_vb
            - 16.0 * self.s * smoothstep(self.z_t1, self.z_t1 + 90.0, z)
            - 10.0 * self.s * smoothstep(t12, t12 - 120.0, z)
    }

    /// Semi-axes (lateral, antero-posterior) of the vertebral body at height z: cervical
    /// above T1, growing down the thoracic spine, lumbar below T12.
    pub fn vertebra(&self, z: f64) -> (f64, f64) {
        let (t1, t12) = (self.z_t1, self.z_thoracic(12.0));
        let (a, b) = if z >= t1 {
            let q = smoothstep(t1, t1 + 50.0, z);
            (lerp(14.0, 12.0, q), lerp(12.0, 10.0, q))
        } else if z >= t12 {
            let q = (t1 - z) / (t1 - t12);
            (lerp(14.0, 19.0, q), lerp(12.0, 16.0, q))
        } else {
            let q = smoothstep(t12, t12 - 60.0, z);
            (lerp(19.0, 23.0, q), lerp(16.0, 17.5, q))
        };
        (a * self.sv, b * self.sv)
    }

    /// Centre y of the spinal canal at height z.
    pub fn canal_y(&self, z: f64) -> f64 {
        self.spine_y(z) + self.vertebra(z).1 + 1.5 + self.r_canal
    }

    /// Taper of the thoracic cavity towards the apex: 1 below mid chest, 0 at the apex.
    fn taper(&self, z: f64) -> f64 {
        let t = self.t(z);
        if t <= 0.0 {
            1.0
        } else {
            (1.0 - t.powi(3)).max(0.0).sqrt()
        }
    }

    /// Cross-section of the thoracic cavity (inside of the rib cage and pleura) at `z`;
    /// `xm` is the medial limit of the lungs (mediastinum half-width at the apices).
    pub fn cavity(&self, z: f64) -> SecKey {
        let g = self.taper(z);
        let t = self.t(z);
        let xm_top = 26.0 * self.s;
        let b = (self.yp_e - self.ya_e) / 2.0;
        let cy = (self.yp_e + self.ya_e) / 2.0;
        SecKey {
            z,
            cx: 0.0,
            cy: cy + (1.0 - g) * 0.3 * b,
            a: xm_top + (self.a_e - xm_top) * g,
            ba: b * (0.35 + 0.65 * g),
            bp: b * (0.45 + 0.55 * g),
            xm: self.s * lerp(6.0, 26.0, smoothstep(0.7, 1.0, t)),
        }
    }

    /// The centreline ring of the ribs at `z`: the cavity widened by pleura and one rib
    /// radius.
    pub fn ring(&self, z: f64) -> SecKey {
        let mut k = self.cavity(z);
        let d = self.gap + self.r_rib;
        k.a += d;
        k.ba += d;
        k.bp += d;
        k
    }

    /// Point of the rib ring at angle `theta` (0 = posterior midline, π/2 = lateral,
    /// π = anterior midline) on side `side` (+1 left, −1 right), at height `z`.
    pub fn ring_point(&self, theta: f64, z: f64, side: f64) -> DVec3 {
        let k = self.ring(z);
        let (c, sn) = (theta.cos(), theta.sin());
        let (b, p) = if c >= 0.0 {
            (k.bp, CAVITY_P.1)
        } else {
            (k.ba, CAVITY_P.0)
        };
        let x = side * k.a * sn.abs().powf(2.0 / p);
        let y = k.cy + c.signum() * b * c.abs().powf(2.0 / p);
        DVec3::new(x, y, z)
    }

    /// Torso outline (skin) at `z`, from the abdomen up to the shoulders; the neck and
    /// head are separate shapes.
    pub fn torso(&self, z: f64) -> SecKey {
        let t = self.t(z);
        let u = z - self.z_apex;
        let (w, d) = (self.width / 2.0, self.depth / 2.0);
        // Relative half-width, anterior and posterior half-depth, posterior shift of the
        // centre.
        let (fa, fba, fbp, shift) = if t <= 0.0 {
            let q = smoothstep(-0.4, 0.0, t);
            (lerp(0.95, 0.99, q), lerp(1.03, 1.0, q), 1.0, 0.0)
        } else if t <= 0.75 {
            (lerp(0.99, 1.0, smoothstep(0.0, 0.3, t)), 1.0, 1.0, 0.0)
        } else if u <= 0.0 {
            let q = (t - 0.75) / (1.0 - 0.75);
            (
                lerp(1.0, 0.94, q),
                lerp(1.0, 0.9, q),
                lerp(1.0, 0.96, q),
                0.0,
            )
        } else if u <= 30.0 {
            let q = u / 30.0;
            (
                lerp(0.94, 0.74, q),
                lerp(0.9, 0.65, q),
                lerp(0.96, 0.75, q),
                0.05 * q,
            )
        } else {
            let q = ((u - 30.0) / 25.0).min(1.0);
            (
                lerp(0.74, 0.42, q),
                lerp(0.65, 0.42, q),
                lerp(0.75, 0.5, q),
                0.05 + 0.07 * q,
            )
        };
        let cy = shift * self.depth;
        let mut k = SecKey {
            z,
            cx: 0.0,
            cy,
            a: w * fa,
            ba: d * fba,
            bp: d * fbp,
            xm: 0.0,
        };
        if u <= 20.0 {
            // Always enclose ribs, muscle and fat, and the spinous processes.
            let ring = self.ring(z);
            let r = self.r_rib;
            k.a = k.a.max(ring.a + r + self.m_lat + self.fat);
            k.ba =
                k.ba.max(cy - (ring.cy - ring.ba - r - self.m_ant - self.fat));
            k.bp =
                k.bp.max(ring.cy + ring.bp + r + self.m_post + 0.8 * self.fat - cy);
            let tip = self.y_tip + self.spine_y(z) - self.y_vb;
            k.bp = k.bp.max(tip + 8.0 * self.s + 0.8 * self.fat - cy);
        }
        k
    }

    /// y of the front of the torso at `(x, z)`.
    pub fn torso_front(&self, x: f64, z: f64) -> f64 {
        let k = self.torso(z);
        let q = (1.0 - (x / k.a).abs().powf(BODY_P.0)).max(0.0);
        k.cy - k.ba * q.powf(1.0 / BODY_P.0)
    }

    /// The neck cross-section centre y and semi-axes (a, ba, bp).
    pub fn neck(&self) -> (f64, f64, f64, f64) {
        let yc = self.spine_y(self.z_t1 + 120.0) - 15.0 * self.s;
        let f = 0.5 * self.fat;
        (yc, 56.0 * self.s + f, 48.0 * self.s + f, 60.0 * self.s + f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampled_patients_are_consistent() {
        for seed in 0..200 {
            let p = Params::sample(seed);
            assert!((280.0..400.0).contains(&p.width), "{seed}");
            assert!(p.depth > 0.6 * p.width && p.depth < 0.82 * p.width);
            assert!(
                p.a_e > 80.0 && p.yp_e - p.ya_e > 100.0,
                "{seed}: cavity {p:?}"
            );
            assert!(p.z_apex > p.z_base + 200.0 && p.z_t1 < p.z_apex);
            for h in p.dome_h {
                assert!(h > 20.0 && h < 0.5 * p.lung_h, "{seed}: dome {h}");
            }
            // The cavity narrows to the apex and is widest low down.
            assert!(p.cavity(p.z_apex - 5.0).a < 0.5 * p.cavity(0.0).a);
            // The torso encloses the rib ring with muscle and fat at every level.
            for i in 0..=20 {
                let z = lerp(p.z_base - 50.0, p.z_apex, i as f64 / 20.0);
                let (t, r) = (p.torso(z), p.ring(z));
                assert!(t.a >= r.a + p.r_rib + p.m_lat + p.fat - 1e-9);
                assert!(
                    t.cy + t.bp >= r.cy + r.bp + p.r_rib + p.m_post,
                    "{seed} z {z}"
                );
            }
            // Spine posterior of the cavity centre, canal behind the vertebral body.
            assert!(p.y_vb > (p.ya_e + p.yp_e) / 2.0);
            assert!(p.canal_y(0.0) > p.spine_y(0.0) + p.vertebra(0.0).1);
            assert!(p.crop.z0 < p.z_base && p.crop.z1 > p.z_apex);
        }
    }

    #[test]
    fn streams_are_independent_and_seeded() {
        let a: Vec<u64> = (0..4).map(|_| rng(5, stream::PATIENT).random()).collect();
        let b: u64 = rng(5, stream::TREES).random();
        assert!(a.iter().all(|&x| x == a[0]));
        assert_ne!(a[0], b);
        assert_ne!(a[0], rng(6, stream::PATIENT).random::<u64>());
    }
}
