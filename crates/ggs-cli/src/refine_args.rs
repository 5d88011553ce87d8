//! `ggs refine`'s input matrix and the refinement's report, shared with `ggs register`.

use anyhow::{Context, Result};
use ggs::refine::RefineResult;
use ggs::Rigid;
use std::path::Path;

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
