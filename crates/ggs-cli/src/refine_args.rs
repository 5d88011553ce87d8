//! Refinement options shared by `ggs register` and `ggs refine`.

use anyhow::{Context, Result};
use clap::Args;
use ggs::refine::{
    CorrespondenceDistance, Method, RefineConfig, RefineResult, RobustKernel,
    DEFAULT_DISTANCE_QUANTILE,
};
use ggs::Rigid;
use std::path::Path;

#[derive(Args, Clone)]
pub struct RefineOptions {
    /// Fixed correspondence distance in cloud units (default: the 0.25 quantile of the
    /// source-to-target nearest-neighbour distances after the initial transform).
    #[arg(long, value_name = "D")]
    pub max_distance: Option<f64>,
    /// Quantile used when no fixed distance is given (default 0.25, the reference's).
    #[arg(long, value_name = "Q")]
    pub distance_quantile: Option<f64>,
    /// Robust kernel: none, huber:K, cauchy:K, geman-mcclure:K (K in cloud units).
    #[arg(long, default_value = "none")]
    pub kernel: String,
    /// Iteration cap (default 500, the reference's).
    #[arg(long)]
    pub max_iterations: Option<usize>,
    /// Neighbours for normals and covariances (default 20).
    #[arg(long)]
    pub neighbors: Option<usize>,
}

impl RefineOptions {
    /// The library's defaults ([`RefineConfig::default`]) changed by the options given.
    pub fn config(&self, method: Method, threads: usize) -> Result<RefineConfig> {
        let base = RefineConfig::default();
        let quantile = self.distance_quantile.unwrap_or(DEFAULT_DISTANCE_QUANTILE);
        let correspondence = match self.max_distance {
            Some(d) => CorrespondenceDistance::Fixed(d),
            None => CorrespondenceDistance::Quantile(quantile),
        };
        Ok(RefineConfig {
            method,
            correspondence,
            kernel: parse_kernel(&self.kernel)?,
            max_iterations: self.max_iterations.unwrap_or(base.max_iterations),
            neighbors: self.neighbors.unwrap_or(base.neighbors),
            threads,
            ..base
        })
    }
}

pub fn parse_method(s: &str) -> Result<Option<Method>> {
    if s == "none" {
        return Ok(None);
    }
    Method::from_name(s)
        .map(Some)
        .with_context(|| format!("unknown refinement '{s}' (known: gicp, p2plane, p2p, none)"))
}

fn parse_kernel(s: &str) -> Result<RobustKernel> {
    s.parse().context("--kernel")
}

/// Read a 4×4 matrix file: 16 numbers, `#` comments allowed.
pub fn read_matrix(path: &Path) -> Result<Rigid> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let mut nums = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        for tok in line.split(|c: char| c.is_whitespace() || c == ',') {
            if tok.is_empty() {
                continue;
            }
            nums.push(tok.parse::<f64>().map_err(|_| {
                anyhow::anyhow!(
                    "{}: line {}: '{tok}' is not a number",
                    path.display(),
                    i + 1
                )
            })?);
        }
    }
    Rigid::from_row_major(&nums, 1e-4).map_err(|m| anyhow::anyhow!("{}: {m}", path.display()))
}

pub fn print_report(r: &RefineResult) -> Result<()> {
    let q = &r.report;
    outln!(
        "refine      {}: {} iterations, {} ({}), {:.0} ms",
        r.method.name(),
        q.iterations,
        q.convergence(),
        q.stop_reason,
        r.total_ms
    );
    outln!(
        "quality     fitness {:.3} (source) / {:.3} (target) within {:.4}, inlier RMSE {:.4}, {} inliers{}",
        q.fitness_source,
        q.fitness_target,
        q.correspondence_distance,
        q.inlier_rmse,
        q.inliers,
        if q.degenerate { ", DEGENERATE geometry (see --json information_eigenvalues)" } else { "" }
    );
    Ok(())
}
