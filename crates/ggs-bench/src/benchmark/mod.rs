//! Benchmark runners: the published protocols and generic manifests, run pair by pair into a
//! resumable CSV, with a summary in the layout of the papers' tables (docs/benchmarks.md).
//!
//! - [`protocol`]: pair lists, ground truth and default parameters of each protocol;
//! - [`row`]: one pair's result ([`PairRow`]) and the resumable CSV file;
//! - [`report`]: recall, mean errors, the Markdown table and the recall curves (SVG);
//! - [`html`]: `report.html`, the page with charts, every pair and a gallery of failures;
//! - [`plan`]: the pairs selected and how each is run, validated for every front end;
//! - [`run_dir`]: the run directory, written as pairs finish in any order, and the serial run;
//! - [`shard`]: a deterministic share of the pairs per run directory, and the merge of shards.

pub mod html;
pub mod motion;
pub mod plan;
pub mod protocol;
pub mod report;
pub mod row;
pub mod run_dir;
pub mod shard;

use ggs::cloud::{Cloud, Point};
use ggs::error::{GgsError, Result};
use ggs::metrics::{is_success, rre, rte};
use ggs::pipeline::{register, Registration, RegistrationConfig, VoxelSize};
use ggs::refine::RefineConfig;
use ggs::transform::Rigid;
pub use plan::{Plan, Selection};
pub use protocol::Protocol;
pub use row::PairRow;
pub use run_dir::{run, RunDir};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where a benchmark cloud comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum CloudRef {
    /// A whole point-cloud file.
    File(PathBuf),
    /// The points of `cloud` listed in `indices` (a text file of 0-based point indices, any
    /// whitespace), moved by `transform` if given: FAUST-partial views.
    Visible {
        cloud: PathBuf,
        indices: PathBuf,
        transform: Option<Rigid>,
    },
}

impl CloudRef {
    /// The files this cloud needs.
    pub fn files(&self) -> Vec<&Path> {
        match self {
            CloudRef::File(p) => vec![p],
            CloudRef::Visible { cloud, indices, .. } => vec![cloud, indices],
        }
    }

    /// Read the cloud.
    pub fn load(&self) -> Result<Cloud> {
        match self {
            CloudRef::File(p) => Ok(ggs::io::read_cloud(p, None)?.cloud),
            CloudRef::Visible {
                cloud,
                indices,
                transform,
            } => {
                let all = ggs::io::read_cloud(cloud, None)?.cloud;
                let idx = read_indices(indices, all.len())?;
                let moved = |p: Point| transform.as_ref().map_or(p, |t| t.apply(&p));
                Ok(Cloud::new(
                    idx.iter().map(|&i| moved(all.point(i))).collect(),
                ))
            }
        }
    }
}

/// Read a whitespace-separated list of point indices, each below `n`.
pub fn read_indices(path: &Path, n: usize) -> Result<Vec<usize>> {
    let text = std::fs::read_to_string(path).map_err(|e| GgsError::io(path, e))?;
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        for tok in line.split_whitespace() {
            let i: usize = tok.parse().map_err(|_| {
                GgsError::at_line(path, k + 1, format!("'{tok}' is not a point index"))
            })?;
            if i >= n {
                return Err(GgsError::at_line(
                    path,
                    k + 1,
                    format!("index {i} is out of range: the cloud has {n} points"),
                ));
            }
            out.push(i);
        }
    }
    if out.is_empty() {
        return Err(GgsError::in_file(path, "no point index"));
    }
    Ok(out)
}

/// One pair of a benchmark.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchPair {
    /// Unique within the protocol, e.g. `7-scenes-redkitchen/0_1`.
    pub id: String,
    pub source: CloudRef,
    pub target: CloudRef,
    /// Maps the source into the target's frame.
    pub ground_truth: Rigid,
    /// The pair's own voxel size (manifests), used unless one is forced.
    pub voxel: Option<f64>,
    /// The protocol's overlap of the pair (fraction), where it has one.
    pub overlap: Option<f64>,
}

/// The files that `pairs` need and that do not exist: `(count, first few)` in pair order,
/// each listed once.
pub fn missing_files(pairs: &[BenchPair], first: usize) -> (usize, Vec<PathBuf>) {
    let mut seen = std::collections::HashSet::new();
    let mut count = 0;
    let mut listed = Vec::new();
    for p in pairs {
        for f in p.source.files().into_iter().chain(p.target.files()) {
            if seen.insert(f.to_path_buf()) && !f.is_file() {
                count += 1;
                if listed.len() < first {
                    listed.push(f.to_path_buf());
                }
            }
        }
    }
    (count, listed)
}

/// A voxel size forced on every pair of a benchmark (`--voxel`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BenchVoxel {
    /// This edge length, in the clouds' units; the RTE threshold is 3 of them.
    Fixed(f64),
    /// The automatic voxel of `ggs register` with no flag ([`VoxelSize::AUTO`]), so that the
    /// benchmark measures what a user who gives no flag gets. The success thresholds stay
    /// the pair's (or the protocol's): 3 × its own voxel for the RTE.
    Auto,
}

impl std::str::FromStr for BenchVoxel {
    type Err = GgsError;
    /// `auto` or a positive number.
    fn from_str(s: &str) -> Result<Self> {
        if s == "auto" {
            return Ok(BenchVoxel::Auto);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(BenchVoxel::Fixed(v)),
            _ => Err(GgsError::param(
                "voxel",
                format!("'{s}' is neither 'auto' nor a positive number"),
            )),
        }
    }
}

impl BenchVoxel {
    /// As it appears in `run.json`: the number, or `"auto"`.
    fn to_json(self) -> serde_json::Value {
        match self {
            BenchVoxel::Fixed(v) => serde_json::json!(v),
            BenchVoxel::Auto => serde_json::json!("auto"),
        }
    }
}

/// How to run each pair.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// Forced voxel size; otherwise the pair's, otherwise the protocol's.
    pub voxel: Option<BenchVoxel>,
    /// The registration pipeline; its voxel is set per pair.
    pub pipeline: RegistrationConfig,
    pub max_rre_deg: f64,
    /// `None`: 3 × the pair's voxel.
    pub max_rte: Option<f64>,
    /// Used when neither `voxel` nor the pair gives one.
    pub default_voxel: Option<f64>,
    /// Move every source by a random rigid motion drawn from this seed and the pair's id
    /// ([`motion::random_motion`]), composing the ground truth with it.
    pub motion_seed: Option<u64>,
}

impl RunConfig {
    /// Everything that decides a row's result, as JSON (the thread count is left out: results
    /// do not depend on it). Written to `run.json` in the run directory; a resumed run must
    /// match it.
    pub fn fingerprint(&self, protocol: &str) -> serde_json::Value {
        let p = &self.pipeline;
        let set = &p.rotations;
        let refine = p.refine.map(|r| RefineConfig { threads: 0, ..r });
        serde_json::json!({
            "ggs": env!("CARGO_PKG_VERSION"),
            "protocol": protocol,
            "voxel": self.voxel.map(BenchVoxel::to_json),
            "default_voxel": self.default_voxel,
            "max_rre_deg": self.max_rre_deg,
            "max_rte": self.max_rte,
            "motion_seed": self.motion_seed,
            "rotations": { "name": set.name, "count": set.len(), "step_deg": set.step_deg },
            "search": {
                "mode": p.search.mode,
                "precision": p.search.precision,
                "top_k": p.search.top_k,
                "distinct_radius_deg": p.search.distinct_radius_deg,
                "max_memory": p.search.max_memory,
            },
            "polish": p.polish,
            "verify": p.verify,
            "first_look": p.first_look,
            "final_stage": p.final_stage,
            "refine": refine,
        })
    }
}

/// Write `value` as pretty JSON to `path` (atomically) if there is no file, or require the
/// file there to hold exactly that text: `differ` is the error otherwise, and `missing`, when
/// given, the error for an absent file (a resumed run whose record is gone).
pub(crate) fn pin_json(
    path: &Path,
    value: &impl serde::Serialize,
    differ: &str,
    missing: Option<&str>,
) -> Result<()> {
    let text = serde_json::to_string_pretty(value).expect("serializable") + "\n";
    match (std::fs::read_to_string(path), missing) {
        (Ok(earlier), _) if earlier == text => Ok(()),
        (Ok(_), _) => Err(GgsError::in_file(path, differ)),
        (Err(_), Some(why)) => Err(GgsError::in_file(path, why)),
        (Err(_), None) => ggs::io::write_atomic(path, text.as_bytes()),
    }
}

/// Register one pair and score it. Errors reading or registering the pair are recorded in
/// the row (a failed pair counts as unsuccessful), not returned.
pub fn run_pair(pair: &BenchPair, cfg: &RunConfig) -> PairRow {
    run_pair_pictured(pair, cfg, false).0
}

/// [`run_pair`], and for a pair that failed with an estimate, its gallery picture as PNG
/// bytes ([`html::failure_picture`]): what an executor returns to [`RunDir::record`].
pub fn run_pair_with_picture(pair: &BenchPair, cfg: &RunConfig) -> (PairRow, Option<Vec<u8>>) {
    let (row, image) = run_pair_pictured(pair, cfg, true);
    (row, image.map(|i| i.png()))
}

/// [`run_pair`], and with `picture`, the gallery picture of a pair that failed with an
/// estimate ([`html::failure_picture`]).
fn run_pair_pictured(
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
        let mut pc = cfg.pipeline.clone();
        pc.voxel = voxel;
        let reg = register(&source, &target, &pc)?;
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
