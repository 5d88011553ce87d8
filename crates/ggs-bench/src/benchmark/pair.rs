//! A benchmark pair: where its clouds come from, its ground truth, and which files are missing.

use ggs::cloud::{Cloud, Point};
use ggs::error::{GgsError, Result};
use ggs::transform::Rigid;
use std::path::{Path, PathBuf};

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
