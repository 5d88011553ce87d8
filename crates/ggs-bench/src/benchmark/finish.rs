//! The files of a finished run, written from its rows: the same for a serial run, a run
//! directory filled in any order and merged shards.

use super::html;
use super::report;
use super::row::PairRow;
use ggs::error::Result;
use std::path::Path;

/// Write the files of a finished run from its rows: `results.json` (summary and rows),
/// `summary.md`, `recall.svg` and `report.html`, each atomically.
pub(super) fn finish_run(
    name: &str,
    rows: &[PairRow],
    metres: bool,
    out: &Path,
) -> Result<report::Summary> {
    let summary = report::Summary::of(name, rows);
    let json = serde_json::json!({ "summary": &summary, "pairs": rows });
    let write = |file: &str, text: String| ggs::io::write_atomic(&out.join(file), text.as_bytes());
    write(
        "results.json",
        serde_json::to_string_pretty(&json).expect("rows serialize") + "\n",
    )?;
    write("summary.md", summary.markdown(rows, metres))?;
    write("recall.svg", report::recall_curves_svg(name, rows))?;
    let ctx = html::ReportContext {
        protocol: name,
        total_pairs: rows.len(),
        metres,
        out,
    };
    html::write_report(&ctx, rows)?;
    Ok(summary)
}
