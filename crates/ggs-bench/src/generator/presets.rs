//! Ground-truth presets: how each pair's rigid motion is drawn, and which overlaps are kept
//! (docs/generator.md).
//!
//! | preset | rotation (Euler 'xyz', degrees) | translation | overlap % |
//! |---|---|---|---|
//! | `fpv1` | each angle uniform in [−180, 180) | uniform in [−0.5, 0.5) m per axis | [60, 100] |
//! | `fpv1-code` | each angle an integer uniform in [0, 45) | uniform in [−0.5, 0.5) m per axis | [60, 100] |
//! | `fp-r-e` / `-m` / `-h` | E: [−15, 15]; M: ±[15, 45]; H: x, z ±[45, 180], y ±[45, 90] | E | E |
//! | `fp-t-e` / `-m` / `-h` | E | norm E [0, 1] m, M [1, 5] m, H [5, 10] m, random direction | E |
//! | `fp-o-e` / `-m` / `-h` | E | E | E [60, 100], M [30, 60), H [10, 30) |
//! | `scene-e` / `-m` / `-h` | as `fpv1` | as `fpv1` | E [60, 100], M [30, 60), H [10, 30) |
//!
//! The scene presets cut their views as crops of a scene ([`super::crops`]), the others by
//! hidden point removal from cameras around a scan.
//!
//! Euler 'xyz' is the extrinsic convention of SciPy (lower case): rotate about x by α, then
//! about the fixed y by β, then about the fixed z by γ, so `R = R_z(γ)·R_y(β)·R_x(α)`.

use ggs::rng::Rng;
use ggs::transform::Rigid;
use nalgebra::{Matrix3, Vector3};

/// Difficulty level of an EGS variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    Easy,
    Medium,
    Hard,
}

/// What an EGS variant varies; the other two stay at Easy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Varies {
    Rotation,
    Translation,
    Overlap,
}

/// A ground-truth preset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    Fpv1,
    Fpv1Code,
    Fp(Varies, Level),
    /// Crops of a scene (a room, a LiDAR scan) at an overlap level, each pair turned as `fpv1`.
    Scene(Level),
}

/// Every preset name, in a stable order.
pub const PRESET_NAMES: &[&str] = &[
    "fpv1",
    "fpv1-code",
    "fp-r-e",
    "fp-r-m",
    "fp-r-h",
    "fp-t-e",
    "fp-t-m",
    "fp-t-h",
    "fp-o-e",
    "fp-o-m",
    "fp-o-h",
    "scene-e",
    "scene-m",
    "scene-h",
];

/// A range of overlap percentages; the upper end is included only at 100.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverlapBand {
    pub min: f64,
    pub max: f64,
}

impl OverlapBand {
    pub fn contains(&self, o: f64) -> bool {
        o >= self.min && (o < self.max || (self.max >= 100.0 && o <= 100.0))
    }
}

impl Preset {
    pub fn from_name(name: &str) -> Option<Preset> {
        let level = |c: &str| match c {
            "e" => Some(Level::Easy),
            "m" => Some(Level::Medium),
            "h" => Some(Level::Hard),
            _ => None,
        };
        match name.to_ascii_lowercase().as_str() {
            "fpv1" => Some(Preset::Fpv1),
            "fpv1-code" => Some(Preset::Fpv1Code),
            other if other.starts_with("scene-") => {
                Some(Preset::Scene(level(other.strip_prefix("scene-")?)?))
            }
            other => {
                let rest = other.strip_prefix("fp-")?;
                let (v, l) = rest.split_once('-')?;
                let varies = match v {
                    "r" => Varies::Rotation,
                    "t" => Varies::Translation,
                    "o" => Varies::Overlap,
                    _ => return None,
                };
                Some(Preset::Fp(varies, level(l)?))
            }
        }
    }

    pub fn name(&self) -> String {
        let level = |l: &Level| match l {
            Level::Easy => 'e',
            Level::Medium => 'm',
            Level::Hard => 'h',
        };
        match self {
            Preset::Fpv1 => "fpv1".into(),
            Preset::Fpv1Code => "fpv1-code".into(),
            Preset::Fp(v, l) => format!(
                "fp-{}-{}",
                match v {
                    Varies::Rotation => 'r',
                    Varies::Translation => 't',
                    Varies::Overlap => 'o',
                },
                level(l)
            ),
            Preset::Scene(l) => format!("scene-{}", level(l)),
        }
    }

    /// True for the presets whose views are crops of a scene.
    pub fn is_scene(&self) -> bool {
        matches!(self, Preset::Scene(_))
    }

    /// The overlap band of the preset.
    pub fn overlap(&self) -> OverlapBand {
        let level = match self {
            Preset::Fp(Varies::Overlap, l) | Preset::Scene(l) => *l,
            _ => Level::Easy,
        };
        match level {
            Level::Easy => OverlapBand {
                min: 60.0,
                max: 100.0,
            },
            Level::Medium => OverlapBand {
                min: 30.0,
                max: 60.0,
            },
            Level::Hard => OverlapBand {
                min: 10.0,
                max: 30.0,
            },
        }
    }

    /// Draw the Euler 'xyz' angles (degrees) and the translation of one pair.
    pub fn draw(&self, rng: &mut Rng) -> ([f64; 3], [f64; 3]) {
        let box_translation = |rng: &mut Rng| [0; 3].map(|_: i32| rng.range(-0.5, 0.5));
        match self {
            Preset::Fpv1 | Preset::Scene(_) => {
                let a = [0; 3].map(|_: i32| rng.range(-180.0, 180.0));
                (a, box_translation(rng))
            }
            Preset::Fpv1Code => {
                let a = [0; 3].map(|_: i32| rng.below(45) as f64);
                (a, box_translation(rng))
            }
            Preset::Fp(v, l) => {
                let rot_level = if *v == Varies::Rotation {
                    *l
                } else {
                    Level::Easy
                };
                let tr_level = if *v == Varies::Translation {
                    *l
                } else {
                    Level::Easy
                };
                let signed = |rng: &mut Rng, lo: f64, hi: f64| rng.sign() * rng.range(lo, hi);
                let angles = match rot_level {
                    Level::Easy => [0; 3].map(|_: i32| rng.range(-15.0, 15.0)),
                    Level::Medium => [0; 3].map(|_: i32| signed(rng, 15.0, 45.0)),
                    Level::Hard => [
                        signed(rng, 45.0, 180.0),
                        signed(rng, 45.0, 90.0),
                        signed(rng, 45.0, 180.0),
                    ],
                };
                let (lo, hi) = match tr_level {
                    Level::Easy => (0.0, 1.0),
                    Level::Medium => (1.0, 5.0),
                    Level::Hard => (5.0, 10.0),
                };
                let norm = rng.range(lo, hi);
                let d = rng.unit_vector();
                (angles, [d[0] * norm, d[1] * norm, d[2] * norm])
            }
        }
    }
}

/// `R = R_z(γ)·R_y(β)·R_x(α)` for Euler 'xyz' angles `[α, β, γ]` in degrees.
pub fn euler_xyz(angles_deg: [f64; 3]) -> Matrix3<f64> {
    let [a, b, c] = angles_deg.map(f64::to_radians);
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, a.cos(), -a.sin(), 0.0, a.sin(), a.cos());
    let ry = Matrix3::new(b.cos(), 0.0, b.sin(), 0.0, 1.0, 0.0, -b.sin(), 0.0, b.cos());
    let rz = Matrix3::new(c.cos(), -c.sin(), 0.0, c.sin(), c.cos(), 0.0, 0.0, 0.0, 1.0);
    rz * ry * rx
}

/// The rigid motion of drawn angles and translation.
pub fn rigid(angles_deg: [f64; 3], t: [f64; 3]) -> Rigid {
    Rigid::new(euler_xyz(angles_deg), Vector3::new(t[0], t[1], t[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for n in PRESET_NAMES {
            assert_eq!(Preset::from_name(n).unwrap().name(), *n);
        }
        assert!(Preset::from_name("fp-x-e").is_none());
        assert!(Preset::from_name("fp-r-x").is_none());
        assert!(Preset::from_name("fpv2").is_none());
        assert!(Preset::from_name("scene-x").is_none());
        assert!(Preset::from_name("scene-h").unwrap().is_scene());
        assert!(!Preset::from_name("fp-o-h").unwrap().is_scene());
    }

    #[test]
    fn euler_xyz_is_extrinsic() {
        // 90° about x then 90° about the fixed z: e_y → e_z → e_z; e_x → e_x → e_y.
        let r = euler_xyz([90.0, 0.0, 90.0]);
        let ey = r * Vector3::y();
        let ex = r * Vector3::x();
        assert!((ey - Vector3::z()).norm() < 1e-12);
        assert!((ex - Vector3::y()).norm() < 1e-12);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn draws_stay_in_their_ranges() {
        let mut rng = Rng::new(3);
        for _ in 0..2000 {
            let (a, t) = Preset::Fpv1.draw(&mut rng);
            assert!(a.iter().all(|x| (-180.0..180.0).contains(x)));
            assert!(t.iter().all(|x| (-0.5..0.5).contains(x)));
            let (a, _) = Preset::Fpv1Code.draw(&mut rng);
            assert!(a
                .iter()
                .all(|x| x.fract() == 0.0 && (0.0..45.0).contains(x)));
            let (a, t) = Preset::Fp(Varies::Rotation, Level::Hard).draw(&mut rng);
            assert!((45.0..180.0).contains(&a[0].abs()) && (45.0..180.0).contains(&a[2].abs()));
            assert!((45.0..90.0).contains(&a[1].abs()));
            assert!(Vector3::from(t).norm() <= 1.0 + 1e-12);
            let (a, t) = Preset::Fp(Varies::Translation, Level::Medium).draw(&mut rng);
            assert!(a.iter().all(|x| x.abs() <= 15.0));
            let n = Vector3::from(t).norm();
            assert!((1.0 - 1e-12..=5.0 + 1e-12).contains(&n));
            let (a, _) = Preset::Fp(Varies::Rotation, Level::Medium).draw(&mut rng);
            assert!(a.iter().all(|x| (15.0..45.0).contains(&x.abs())));
        }
    }

    #[test]
    fn the_three_easy_variants_are_one_benchmark() {
        // fp-r-e, fp-t-e and fp-o-e all sit at E on every axis: same draws, same band.
        let e = [
            Preset::Fp(Varies::Rotation, Level::Easy),
            Preset::Fp(Varies::Translation, Level::Easy),
            Preset::Fp(Varies::Overlap, Level::Easy),
        ];
        for seed in 0..50 {
            let d: Vec<_> = e.iter().map(|p| p.draw(&mut Rng::new(seed))).collect();
            assert!(d[0] == d[1] && d[1] == d[2]);
        }
        assert!(e[0].overlap() == e[1].overlap() && e[1].overlap() == e[2].overlap());
    }

    #[test]
    fn overlap_bands() {
        let e = Preset::Fpv1.overlap();
        assert!(e.contains(60.0) && e.contains(100.0) && !e.contains(59.99));
        let m = Preset::Fp(Varies::Overlap, Level::Medium).overlap();
        assert!(m.contains(30.0) && !m.contains(60.0));
        let h = Preset::Fp(Varies::Overlap, Level::Hard).overlap();
        assert_eq!(Preset::Scene(Level::Hard).overlap(), h);
        assert_eq!(Preset::Scene(Level::Medium).overlap(), m);
        assert!(h.contains(10.0) && !h.contains(30.0) && !h.contains(9.0));
        assert_eq!(Preset::Fp(Varies::Rotation, Level::Hard).overlap(), e);
    }
}
