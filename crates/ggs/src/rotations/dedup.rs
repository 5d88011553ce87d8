//! Duplicate removal for rotation sets. Both rules keep the first occurrence, so the order of
//! the survivors is the order of the input.

use nalgebra::Matrix3;

/// Indices of the rotations kept when every rotation within `tol_deg` (geodesic angle) of an
/// earlier kept one is dropped. `tol_deg` must be ≥ 0.
///
/// Uses the chordal form, stable for tiny angles: `‖A − B‖_F = 2√2·sin(θ/2)`, so
/// `angle(A, B) ≤ tol ⇔ ‖A − B‖_F ≤ 2√2·sin(tol/2)` (plus 1e-13 for float noise).
///
/// Kept rotations are bucketed by their diagonal on a grid of twice the chordal tolerance
/// `d`: a duplicate differs by at most `d` in every entry, so its bucket lies, along each
/// axis, between those of `v − d` and `v + d` (one bucket, or two near a boundary: 3.4 of
/// the 27 neighbours on average instead of all 27). The same answer as comparing with every
/// kept one; the removal on `hopf15-id`: 13 → 8 million instructions.
pub fn dedup_geodesic(rotations: &[Matrix3<f64>], tol_deg: f64) -> Vec<usize> {
    let max_sq = (2.0 * 2f64.sqrt() * (tol_deg.to_radians() / 2.0).sin() + 1e-13).powi(2);
    // A margin so that rounding in the bucket arithmetic never drops a bucket.
    let d = max_sq.sqrt() * (1.0 + 1e-9);
    let cell = 2.0 * d;
    let diagonal = |r: &Matrix3<f64>| [r[(0, 0)], r[(1, 1)], r[(2, 2)]];
    let key = |v: [f64; 3]| v.map(|x| crate::num::floor_i64(x / cell));
    let mut buckets: rustc_hash::FxHashMap<[i64; 3], Vec<usize>> = Default::default();
    let mut kept: Vec<usize> = Vec::new();
    for (i, r) in rotations.iter().enumerate() {
        let v = diagonal(r);
        let (lo, hi) = (key(v.map(|x| x - d)), key(v.map(|x| x + d)));
        let mut duplicate = false;
        'search: for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    let Some(b) = buckets.get(&[x, y, z]) else {
                        continue;
                    };
                    if b.iter()
                        .any(|&j| (rotations[j] - r).norm_squared() <= max_sq)
                    {
                        duplicate = true;
                        break 'search;
                    }
                }
            }
        }
        if !duplicate {
            kept.push(i);
            buckets.entry(key(v)).or_default().push(i);
        }
    }
    kept
}

/// Indices kept by the element-wise rule of the reference files: a rotation is a duplicate of
/// an earlier kept one `K` when every entry satisfies `|r − k| ≤ 1e-16 + 1e-16·|k|`.
///
/// With matrices from [`super::euler::euler_matrix`] this reproduces
/// `R_limited_15_15_15_removed_duplicates.npy` (1886 rows) and
/// `R_15_15_15_removed_duplicates.npy` (6364 rows) row for row: the few gimbal-lock rows whose
/// entries carry `sin²45° + cos²45° = 1 + 2⁻⁵²` survive there as they did in the original.
pub fn dedup_reference(rotations: &[Matrix3<f64>]) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    for (i, r) in rotations.iter().enumerate() {
        let duplicate = kept.iter().any(|&j| {
            let k = &rotations[j];
            r.iter()
                .zip(k.iter())
                .all(|(a, b)| (a - b).abs() <= 1e-16 + 1e-16 * b.abs())
        });
        if !duplicate {
            kept.push(i);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bucketed search keeps exactly what comparing with every kept rotation keeps.
    #[test]
    fn bucketed_dedup_equals_brute_force() {
        let brute = |rots: &[Matrix3<f64>], tol_deg: f64| {
            let max_sq = (2.0 * 2f64.sqrt() * (tol_deg.to_radians() / 2.0).sin() + 1e-13).powi(2);
            let mut kept: Vec<usize> = Vec::new();
            for (i, r) in rots.iter().enumerate() {
                if !kept.iter().any(|&j| (rots[j] - r).norm_squared() <= max_sq) {
                    kept.push(i);
                }
            }
            kept
        };
        let mut next = crate::test_rng::uniform(5);
        let mut rots = Vec::new();
        for _ in 0..400 {
            let (a, b, c) = (next() * 0.6, next() * 0.6, next() * 0.6);
            rots.push(*nalgebra::Rotation3::from_euler_angles(a, b, c).matrix());
        }
        // Exact copies and copies moved by about the tolerance of the clean removal.
        for k in 0..100 {
            let r = rots[k * 3];
            let tiny = nalgebra::Rotation3::from_euler_angles(next() * 2e-8, 0.0, next() * 2e-8);
            rots.push(if k % 2 == 0 { r } else { tiny.matrix() * r });
        }
        for tol in [0.0, 1e-6, 0.5, 3.0, 20.0, 180.0] {
            assert_eq!(dedup_geodesic(&rots, tol), brute(&rots, tol), "tol {tol}");
        }
    }
    use crate::rotations::euler::euler_matrix;

    #[test]
    fn geodesic_dedup_of_gimbal_lock() {
        // At β = −90° only α − γ matters.
        let m = vec![
            euler_matrix(0.0, -90.0, 0.0),
            euler_matrix(30.0, -90.0, 30.0),
            euler_matrix(30.0, -90.0, 0.0),
        ];
        assert_eq!(dedup_geodesic(&m, 1e-6), vec![0, 2]);
    }

    #[test]
    fn tolerance_groups_close_rotations() {
        let m = vec![
            euler_matrix(0.0, 0.0, 0.0),
            euler_matrix(0.0, 0.0, 4.0),
            euler_matrix(0.0, 0.0, 6.0),
        ];
        assert_eq!(dedup_geodesic(&m, 5.0), vec![0, 2]);
        assert_eq!(dedup_geodesic(&m, 0.0), vec![0, 1, 2]);
    }
}
