//! How well a given transform aligns two clouds, as Open3D's `evaluate_registration` defines
//! it, plus the share of the target that is matched.
//!
//! For `T` and a distance `d`: `fitness_source = |{p : min_q ‖T·p − q‖ ≤ d}| / |source|`,
//! `inlier_rmse = sqrt(mean ‖T·p − q‖²)` over those inliers (cloud units),
//! `fitness_target = |{q : min_p ‖T·p − q‖ ≤ d}| / |target|`.

use super::grid::RadiusSearch;
use crate::cloud::{Cloud, Point};
use crate::error::{GgsError, Result};
use crate::transform::Rigid;
use rayon::prelude::*;

/// The figures of [`evaluate`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Evaluation {
    pub fitness_source: f64,
    pub fitness_target: f64,
    pub inlier_rmse: f64,
    pub inliers: usize,
}

/// Evaluate `t` (`p_target = T · p_source`) at the correspondence distance `max_distance`.
pub fn evaluate(
    source: &Cloud,
    target: &Cloud,
    t: &Rigid,
    max_distance: f64,
) -> Result<Evaluation> {
    source.ensure_not_empty("source")?;
    target.ensure_not_empty("target")?;
    if !(max_distance.is_finite() && max_distance > 0.0) {
        return Err(GgsError::param(
            "max_distance",
            format!("must be a positive number, got {max_distance}"),
        ));
    }
    let moved: Vec<Point> = source.iter().map(|p| t.apply(&p)).collect();
    let target = target.to_points();
    let in_target = RadiusSearch::new(&target, max_distance, None);
    // Per-point results collected in order, then summed in order: thread-count independent.
    let found: Vec<Option<f64>> = moved
        .par_iter()
        .map(|p| in_target.nearest(p).map(|(_, d2)| d2))
        .collect();
    let inliers = found.iter().flatten().count();
    let sq: f64 = found.iter().flatten().sum();
    let in_moved = RadiusSearch::new(&moved, max_distance, None);
    let matched_target = target
        .par_iter()
        .filter(|q| in_moved.nearest(q).is_some())
        .count();
    Ok(Evaluation {
        fitness_source: inliers as f64 / source.len() as f64,
        fitness_target: matched_target as f64 / target.len() as f64,
        inlier_rmse: super::root_mean(sq, inliers),
        inliers,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    #[test]
    fn a_shifted_copy_is_evaluated_exactly() {
        let pts: Vec<Point> = (0..100).map(|i| [i as f64 * 0.01, 0.0, 0.0]).collect();
        let c = Cloud::new(pts);
        let e = evaluate(&c, &c, &Rigid::identity(), 0.001).unwrap();
        assert_eq!(
            (e.fitness_source, e.fitness_target, e.inlier_rmse),
            (1.0, 1.0, 0.0)
        );
        // Lifted by 0.003: every point matches at d = 0.005 with an error of exactly 0.003.
        let up = Rigid::new(Matrix3::identity(), Vector3::new(0.0, 0.003, 0.0));
        let e = evaluate(&c, &c, &up, 0.005).unwrap();
        assert_eq!(e.inliers, 100);
        assert!((e.inlier_rmse - 0.003).abs() < 1e-12);
        assert_eq!(evaluate(&c, &c, &up, 0.002).unwrap().fitness_source, 0.0);
        assert!(evaluate(&c, &c, &up, -1.0).is_err());
    }
}
