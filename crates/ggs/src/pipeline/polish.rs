//! Polishing a coarse hypothesis on a finer rotation grid, scored by the same correlation.
//!
//! A grid of step `S` leaves the right rotation up to half its largest gap away (8° for the
//! 15° sets), and from starts 10–15° off ICP can settle in a wrong local minimum. Around a
//! hypothesis `R` the polish scores the 7 rotations `R` and `exp(±h·e_d)·R` (`exp` of a
//! rotation vector in radians, `e_d` the axes; the centre first) at the voxel size with the
//! exact score of the grid search, and moves to the best; it repeats while the best is not
//! the centre (at most `max_moves` times), then divides `h` by 3, for `levels` levels starting
//! at `h = step_fraction · S`. Ties keep the centre (the lowest index wins), so the polish never
//! lowers the match score and stops where no neighbour is strictly better. (The 27-rotation
//! cube `exp(h·(i, j, k))·R` was measured too: the same picks on the benchmarks here at four
//! times the cost.)

use crate::cloud::Cloud;
use crate::error::Result;
use crate::rotations::RotationSet;
use crate::search::{grid_search, Hypothesis, SearchConfig, SearchMode};
use nalgebra::{Matrix3, Rotation3, Vector3};

/// Parameters of the polish.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PolishConfig {
    /// First step `h`, as a fraction of the rotation set's step (1/3: 5° for a 15° set).
    pub step_fraction: f64,
    /// Levels; each divides the step by 3.
    pub levels: usize,
    /// Moves of the centre allowed at each level.
    pub max_moves: usize,
}

impl Default for PolishConfig {
    fn default() -> Self {
        PolishConfig {
            step_fraction: 1.0 / 3.0,
            levels: 1,
            max_moves: 4,
        }
    }
}

/// What the polish did to one hypothesis.
#[derive(Debug, Clone, Copy)]
pub struct Polished {
    /// The best hypothesis found (its `rotation_index` refers to the coarse set's start).
    pub hypothesis: Hypothesis,
    /// Rotations scored.
    pub scored: usize,
}

/// The 7 rotations `r` and `exp(±h·e_d)·r`, the centre (`r` itself) first.
fn local_grid(r: &Matrix3<f64>, h_rad: f64) -> Vec<Matrix3<f64>> {
    let mut out = vec![*r];
    for d in 0..3 {
        for sign in [-1.0, 1.0] {
            let mut w = Vector3::zeros();
            w[d] = sign * h_rad;
            out.push(Rotation3::new(w).into_inner() * r);
        }
    }
    out
}

/// Polish `start` (found over a set of step `set_step_deg`) with the search parameters of
/// `search` (voxel, precision, threads, memory budget), see the module documentation.
pub fn polish(
    source: &Cloud,
    target: &Cloud,
    start: &Hypothesis,
    set_step_deg: f64,
    search: &SearchConfig,
    cfg: &PolishConfig,
) -> Result<Polished> {
    let mut local_cfg = search.clone();
    local_cfg.mode = SearchMode::Exhaustive;
    local_cfg.top_k = 1;
    local_cfg.progress = None;
    let mut best = *start;
    let mut scored = 0;
    let mut h = (cfg.step_fraction * set_step_deg).to_radians();
    for _ in 0..cfg.levels {
        for _ in 0..=cfg.max_moves {
            let set = RotationSet {
                name: "polish".into(),
                matrices: local_grid(&best.transform.rotation, h),
                step_deg: h.to_degrees(),
            };
            let r = grid_search(source, target, &set, &local_cfg)?;
            scored += set.len();
            if r.winner().rotation_index == 0 || r.winner().match_score <= best.match_score {
                break;
            }
            best = Hypothesis {
                rotation_index: start.rotation_index,
                ..r.hypotheses[0]
            };
        }
        h /= 3.0;
    }
    Ok(Polished {
        hypothesis: best,
        scored,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transform::rotation_angle_deg;

    #[test]
    fn the_local_grid_is_centred_and_steps_h_along_each_axis() {
        let r = Rotation3::new(Vector3::new(0.3, -0.2, 1.0)).into_inner();
        let g = local_grid(&r, 0.1);
        assert_eq!(g.len(), 7);
        assert_eq!(g[0], r);
        for m in &g[1..] {
            assert!((rotation_angle_deg(m, &r) - 0.1f64.to_degrees()).abs() < 1e-9);
        }
        // Opposite steps are 2h apart.
        assert!((rotation_angle_deg(&g[1], &g[2]) - 0.2f64.to_degrees()).abs() < 1e-9);
    }
}
