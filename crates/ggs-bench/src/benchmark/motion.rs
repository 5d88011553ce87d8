//! Random rigid motions of benchmark sources: a registration method that needs no initial
//! guess must solve a pair whatever the pose of its source. `ggs bench --move-seed S` moves
//! every source by [`random_motion`] and composes the ground truth with it
//! (`T' = T · M⁻¹` for the moved source `M·p`), so the same pairs can be run unmoved and
//! moved and the results compared.

use ggs::cloud::Cloud;
use ggs::rng::Rng;
use ggs::transform::Rigid;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// FNV-1a hash of a pair id: the motion of a pair depends on its id and the seed only, not on
/// the order, the selection or the sharding of the pairs.
fn id_hash(id: &str) -> u64 {
    id.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// A rotation uniform over SO(3) (a unit quaternion from four normal deviates, by Box–Muller)
/// and a translation uniform in the cube of half-side the source's bounding-box diagonal, about
/// the source's centroid: `M(p) = R·(p − c) + c + t`.
pub fn random_motion(seed: u64, id: &str, source: &Cloud) -> Rigid {
    let mut rng = Rng::stream(seed, &[id_hash(id)]);
    let mut normal = || {
        let u1 = rng.uniform().max(f64::MIN_POSITIVE);
        let u2 = rng.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let q = Quaternion::new(normal(), normal(), normal(), normal());
    let r = UnitQuaternion::from_quaternion(q)
        .to_rotation_matrix()
        .into_inner();
    let half = source.aabb().map_or(1.0, |b| b.diagonal());
    let t = Vector3::new(
        rng.range(-half, half),
        rng.range(-half, half),
        rng.range(-half, half),
    );
    let c = Vector3::from(source.centroid().unwrap_or([0.0; 3]));
    Rigid::new(r, c + t - r * c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ggs::transform::rotation_angle_deg;
    use nalgebra::Matrix3;

    fn cloud() -> Cloud {
        Cloud::new(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    }

    #[test]
    fn motions_repeat_per_id_and_differ_between_ids_and_seeds() {
        let c = cloud();
        let a = random_motion(1, "pair_a", &c);
        assert_eq!(a, random_motion(1, "pair_a", &c));
        assert_ne!(a, random_motion(1, "pair_b", &c));
        assert_ne!(a, random_motion(2, "pair_a", &c));
    }

    /// The angles of uniform rotations have the density (1 − cos θ)/π on [0, π]: mean
    /// π/2 + 2/π (≈ 126.5°), and (π/4 − sin π/4)/π ≈ 2.5 % below 45°.
    #[test]
    fn rotations_are_uniform_over_so3() {
        let c = cloud();
        let n = 4000;
        let angles: Vec<f64> = (0..n)
            .map(|i| {
                let m = random_motion(7, &format!("p{i}"), &c);
                rotation_angle_deg(&m.rotation, &Matrix3::identity())
            })
            .collect();
        let mean = angles.iter().sum::<f64>() / n as f64;
        assert!((mean - 126.476).abs() < 2.0, "mean {mean}");
        let below = angles.iter().filter(|&&a| a < 45.0).count() as f64 / n as f64;
        let expected = (std::f64::consts::FRAC_PI_4 - std::f64::consts::FRAC_PI_4.sin())
            / std::f64::consts::PI;
        assert!((below - expected).abs() < 0.012, "{below} vs {expected}");
    }
}
