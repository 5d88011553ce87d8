//! One pair registered and scored into its row.

use super::config::{BenchVoxel, RunConfig};
use super::pair::BenchPair;
use super::row::PairRow;
use super::{html, motion, report};
use ggs::error::{GgsError, Result};
use ggs::metrics::{is_success, rre, rte};
use ggs::pipeline::{Registration, VoxelSize};
use ggs::settings::register_with;
use ggs::transform::Rigid;
use ggs::{Runtime, Settings};
use std::time::Instant;

/// Register one pair and score it. Errors reading or registering the pair are recorded in
/// the row (a failed pair counts as unsuccessful), not returned.
pub fn run_pair(pair: &BenchPair, cfg: &RunConfig) -> PairRow {
    run_pair_pictured(pair, cfg, false).0
}

/// [`run_pair`], and for a pair that failed with an estimate, its gallery picture as PNG
/// bytes ([`html::failure_picture`]): what an executor returns to [`RunDir::record`](super::run_dir::RunDir::record).
pub fn run_pair_with_picture(pair: &BenchPair, cfg: &RunConfig) -> (PairRow, Option<Vec<u8>>) {
    let (row, image) = run_pair_pictured(pair, cfg, true);
    (row, image.map(|i| i.png()))
}

/// [`run_pair`], and with `picture`, the gallery picture of a pair that failed with an
/// estimate ([`html::failure_picture`]).
pub(super) fn run_pair_pictured(
    pair: &BenchPair,
    cfg: &RunConfig,
    picture: bool,
) -> (PairRow, Option<ggs::render::Image>) {
    let t0 = Instant::now();
    let mut row = PairRow::new(&pair.id, pair.overlap);
    let mut image = None;
    let result = (|| -> Result<()> {
        let (voxel, threshold_voxel) = pair_voxels(pair, cfg)?;
        if let VoxelSize::Fixed(v) = voxel {
            row.voxel = v;
        }
        row.max_rre_deg = cfg.max_rre_deg;
        let (mut source, target) = (pair.source.load()?, pair.target.load()?);
        let mut truth = pair.ground_truth;
        if let Some(seed) = cfg.motion_seed {
            let m = motion::random_motion(seed, &pair.id, &source);
            source = source.transformed(&m);
            truth = truth.compose(&m.inverse());
        }
        row.source_points = source.len();
        row.target_points = target.len();
        row.read_ms = t0.elapsed().as_secs_f64() * 1e3;
        let settings = Settings {
            voxel: match voxel {
                VoxelSize::Fixed(v) => Some(v),
                VoxelSize::Auto { .. } => None,
            },
            ..cfg.settings.clone()
        };
        let runtime = Runtime {
            threads: cfg.threads,
            cancel: cfg.cancel.clone(),
            ..Runtime::default()
        };
        let reg = register_with(&source, &target, &settings, &runtime)?;
        row.voxel = reg.voxel;
        row.max_rte = cfg
            .max_rte
            .unwrap_or(3.0 * threshold_voxel.unwrap_or(reg.voxel));
        fill_row(&mut row, &reg, &truth);
        if picture && !row.success {
            let t = &reg.transform;
            image = Some(html::failure_picture(
                &source.to_points(),
                &target.to_points(),
                t,
                &truth,
            ));
        }
        Ok(())
    })();
    if let Err(e) = result {
        row.error = Some(e.to_string());
        row.success = false;
    }
    row.total_ms = t0.elapsed().as_secs_f64() * 1e3;
    (row, image)
}

/// The voxel size to register `pair` with, and the voxel whose multiple is the pair's RTE
/// threshold (see [`BenchVoxel`]; `None`: the automatic voxel itself, for a pair and
/// protocol that give none).
fn pair_voxels(pair: &BenchPair, cfg: &RunConfig) -> Result<(VoxelSize, Option<f64>)> {
    let own = pair.voxel.or(cfg.default_voxel);
    match (cfg.voxel, own) {
        (Some(BenchVoxel::Fixed(v)), _) | (None, Some(v)) => Ok((VoxelSize::Fixed(v), Some(v))),
        (Some(BenchVoxel::Auto), _) => Ok((VoxelSize::AUTO, own)),
        (None, None) => Err(GgsError::param("voxel", "no voxel size for this pair")),
    }
}

/// Coarse rank of the first hypothesis whose pose meets the thresholds: the verified poses
/// (after polish and the verification's ICP) when the pipeline verified, else the coarse
/// search's grid poses. `None`: no hypothesis was right, so no choice among them could
/// have solved the pair.
pub fn right_pose_rank(
    reg: &Registration,
    truth: &Rigid,
    max_rre_deg: f64,
    max_rte: f64,
) -> Option<usize> {
    let right = |t: &Rigid| is_success(rre(t, truth), rte(t, truth), max_rre_deg, max_rte);
    match &reg.verification {
        Some(v) => v
            .hypotheses
            .iter()
            .find(|h| right(&h.transform))
            .map(|h| h.rank),
        None => reg
            .search
            .hypotheses
            .iter()
            .position(|h| right(&h.transform)),
    }
}

/// The row's results from a registration, scored against `truth`.
fn fill_row(row: &mut PairRow, reg: &Registration, truth: &Rigid) {
    row.coarse_ms = reg.timings.search_ms;
    row.verify_ms = reg.timings.verify_ms;
    row.refine_ms = reg.timings.refine_ms;
    row.score = reg.search.winner().score;
    row.ambiguity = reg.search.ambiguity;
    row.coarse_rre = rre(&reg.coarse_transform, truth);
    row.coarse_rte = rte(&reg.coarse_transform, truth);
    if let Some(r) = &reg.refine {
        row.fitness_source = Some(r.report.fitness_source);
        row.fitness_target = Some(r.report.fitness_target);
        row.inlier_rmse = Some(r.report.inlier_rmse);
        row.iterations = Some(r.report.iterations);
        row.converged = Some(r.report.converged);
        row.degenerate = Some(r.report.degenerate);
    }
    if let Some(v) = &reg.verification {
        row.chosen_rank = Some(reg.chosen_rank);
        row.verified = Some(v.hypotheses.len());
        row.verify_score = Some(v.hypotheses[v.chosen].evidence.score);
        row.runner_up_score = v.runner_up.map(|k| v.hypotheses[k].evidence.score);
    }
    row.first_look = reg.first_look.map(|f| f.accepted);
    row.confidence = reg.confidence;
    row.ambiguous = reg.ambiguous;
    row.warnings = reg.warnings.join(" | ");
    row.rre = rre(&reg.transform, truth);
    row.rte = rte(&reg.transform, truth);
    row.success = is_success(row.rre, row.rte, row.max_rre_deg, row.max_rte);
    row.transform = reg.transform.to_rows().concat();
    row.right_rank = right_pose_rank(reg, truth, row.max_rre_deg, row.max_rte);
}

/// What a finished run wrote and measured.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// Rows of the selected pairs, in their order.
    pub rows: Vec<PairRow>,
    pub summary: report::Summary,
    /// Pairs taken from an earlier run's CSV instead of being run again.
    pub resumed: usize,
    /// Distances in metres (the summary's RTE in cm).
    pub metres: bool,
}
