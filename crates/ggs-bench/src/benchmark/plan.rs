//! What a benchmark run is: the pairs selected from a protocol or manifest and how each is
//! run ([`Plan`]), validated once here for every front end (`ggs bench`, `ggs.bench.run` in
//! Python, whichever executor runs the pairs).

use super::config::{BenchVoxel, RunConfig};
use super::pair::{missing_files, BenchPair};
use super::protocol::Protocol;
use super::shard::{Shard, ShardFile};
use ggs::error::{GgsError, Result};
use ggs::Settings;
use std::path::PathBuf;

/// Which pairs to run and the protocol's thresholds, as a user gives them.
#[derive(Debug, Clone, Default)]
pub struct Selection {
    /// `3dmatch`, `kitti`, `eth`, `fpv1` or `manifest`.
    pub protocol: String,
    /// The manifest file (`pairs.tsv` format) for `manifest`.
    pub manifest: Option<PathBuf>,
    /// The protocol's clouds (not for `manifest`, whose paths are relative to it).
    pub data: Option<PathBuf>,
    /// Only pairs whose id contains one of these comma-separated substrings.
    pub pairs: Option<String>,
    /// Only the first N pairs (after `pairs`).
    pub limit: Option<usize>,
    /// Only this share of the selected pairs.
    pub shard: Option<Shard>,
    /// Forced voxel size, or the automatic one (default: the pair's, else the protocol's).
    pub voxel: Option<BenchVoxel>,
    /// Move every source by a random motion from this seed ([`super::motion`]).
    pub move_seed: Option<u64>,
    /// Success thresholds (default: the protocol's).
    pub max_rre_deg: Option<f64>,
    pub max_rte: Option<f64>,
}

/// A benchmark run, validated: its pairs (all files present) and configuration.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The protocol's name (`manifest` for a manifest).
    pub name: &'static str,
    /// The pairs to run, in order (this shard's, when sharded).
    pub pairs: Vec<BenchPair>,
    pub cfg: RunConfig,
    /// Distances in metres (the summary's RTE in cm): every protocol but a manifest.
    pub metres: bool,
    /// `shard.json` of a sharded run.
    pub shard: Option<ShardFile>,
}

impl Plan {
    /// Resolve `sel` with `settings` on `threads` worker threads per pair; `paper_rotations`:
    /// use the protocol's own rotation set of the paper (`--preset paper` with no rotation set
    /// given). Errors name what is wrong: bad settings, an unknown protocol, a missing
    /// directory, an empty selection, the first missing files.
    pub fn new(
        sel: &Selection,
        settings: Settings,
        threads: usize,
        paper_rotations: bool,
    ) -> Result<Plan> {
        let protocol = Protocol::from_name(&sel.protocol, sel.manifest.as_deref())?;
        let data = data_dir(&protocol, sel)?;
        let defaults = protocol.defaults();
        let mut pairs = protocol.pairs(&data)?;
        if let Some(filter) = &sel.pairs {
            let keys: Vec<&str> = filter.split(',').filter(|k| !k.is_empty()).collect();
            pairs.retain(|p| keys.iter().any(|k| p.id.contains(k)));
        }
        if let Some(n) = sel.limit {
            pairs.truncate(n);
        }
        if pairs.is_empty() {
            return Err(GgsError::param(
                "pairs",
                "no pair selected (check --pairs and --limit)",
            ));
        }
        check_files(&pairs, protocol.name())?;
        let mut settings = settings;
        if paper_rotations {
            settings.rotations = defaults.paper_rotations.to_string();
        }
        // Bad settings are refused before any pair runs.
        settings.plan(threads)?;
        let cfg = RunConfig {
            voxel: sel.voxel,
            settings,
            threads,
            cancel: None,
            max_rre_deg: sel.max_rre_deg.unwrap_or(defaults.max_rre_deg),
            max_rte: sel.max_rte.or(defaults.max_rte),
            default_voxel: defaults.voxel,
            motion_seed: sel.move_seed,
        };
        let metres = !matches!(protocol, Protocol::Manifest(_));
        let shard = sel.shard.map(|shard| {
            let selected_pairs = pairs.len();
            pairs = shard.select(&pairs);
            ShardFile {
                shard,
                selected_pairs,
                metres,
                ids: pairs.iter().map(|p| p.id.clone()).collect(),
            }
        });
        if let Some(f) = &shard {
            if pairs.is_empty() {
                return Err(GgsError::param(
                    "shard",
                    format!(
                        "shard {}/{} has no pair: {} pairs were selected",
                        f.shard.index, f.shard.count, f.selected_pairs
                    ),
                ));
            }
        }
        Ok(Plan {
            name: protocol.name(),
            pairs,
            cfg,
            metres,
            shard,
        })
    }

    /// The run directory used when none is given: `ggs-bench-<protocol>`.
    pub fn default_out(&self) -> PathBuf {
        PathBuf::from(format!("ggs-bench-{}", self.name))
    }
}

/// The directory of the protocol's clouds: none for a manifest, else `--data`, which must be
/// a directory.
fn data_dir(protocol: &Protocol, sel: &Selection) -> Result<PathBuf> {
    match (protocol, &sel.data) {
        (Protocol::Manifest(_), None) => Ok(PathBuf::new()),
        (Protocol::Manifest(_), Some(_)) => Err(GgsError::param(
            "data",
            "--data is not used with a manifest: its paths are relative to the manifest",
        )),
        (_, Some(d)) if d.is_dir() => Ok(d.clone()),
        (_, Some(d)) => Err(GgsError::param(
            "data",
            format!("--data {}: not a directory", d.display()),
        )),
        (p, None) => Err(GgsError::param(
            "data",
            format!("{} needs --data DIR with its point clouds", p.name()),
        )),
    }
}

/// An error listing the first missing files, if any file the pairs need is missing.
fn check_files(pairs: &[BenchPair], protocol: &str) -> Result<()> {
    let (count, first) = missing_files(pairs, 5);
    if count == 0 {
        return Ok(());
    }
    let list: Vec<String> = first.iter().map(|p| format!("  {}", p.display())).collect();
    Err(GgsError::param(
        "data",
        format!(
            "{count} file(s) the {protocol} pairs need are missing; the first:\n{}",
            list.join("\n")
        ),
    ))
}
