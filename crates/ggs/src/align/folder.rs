//! The files of an alignment, in one folder: `poses.json` (the [`Alignment`]), `poses.txt`,
//! `scans/NAME.ply` (each placed scan moved into the common frame) and `model.ply` (the
//! placed scans merged and thinned). Each file is written atomically; the report page
//! (`report.html`, [`crate::html::alignment`]) is written beside them by the front ends.

use super::result::Alignment;
use super::scan::AlignScan;
use crate::error::{GgsError, Result};
use crate::io::{write_atomic, write_cloud};
use rayon::prelude::*;
use std::collections::BTreeSet;
use std::path::Path;

/// Write the alignment's files into `dir` (created if needed). The files are independent and
/// written side by side on the current thread pool; an error names the first file that
/// failed, in the order of the module documentation.
pub fn write_folder(dir: &Path, scans: &[AlignScan], a: &Alignment) -> Result<()> {
    std::fs::create_dir_all(dir.join("scans")).map_err(|e| GgsError::io(dir, e))?;
    let names = moved_scan_names(scans, a);
    let (documents, clouds) = rayon::join(
        || -> Result<()> {
            let json = serde_json::to_string_pretty(a).expect("an alignment serializes");
            write_atomic(&dir.join("poses.json"), json.as_bytes())?;
            write_atomic(&dir.join("poses.txt"), a.poses_text().as_bytes())
        },
        || -> Result<()> {
            let model = || write_cloud(&dir.join("model.ply"), &a.merged_model(scans), None);
            let moved = |i: usize| -> Result<()> {
                let (Some(name), Some(pose)) = (&names[i], &a.scans[i].pose) else {
                    return Ok(());
                };
                let points: Vec<_> = scans[i].cloud.iter().map(|p| pose.apply(&p)).collect();
                write_cloud(
                    &dir.join("scans").join(format!("{name}.ply")),
                    &points,
                    None,
                )
            };
            let (scans_written, model_written) = rayon::join(
                || {
                    (0..scans.len())
                        .into_par_iter()
                        .map(moved)
                        .collect::<Vec<_>>()
                },
                model,
            );
            scans_written.into_iter().collect::<Result<()>>()?;
            model_written
        },
    );
    documents?;
    clouds
}

/// The file stem of each placed scan's moved copy (`None`: unplaced): its own file stem, or
/// `scanN` without one, with `_N` added to a stem an earlier scan took.
fn moved_scan_names(scans: &[AlignScan], a: &Alignment) -> Vec<Option<String>> {
    let mut used = BTreeSet::new();
    scans
        .iter()
        .zip(&a.scans)
        .enumerate()
        .map(|(i, (scan, out))| {
            out.pose?;
            let stem = Path::new(&scan.name)
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .filter(|s| !s.is_empty())
                .unwrap_or_else(|| format!("scan{}", i + 1));
            Some(if used.insert(stem.clone()) {
                stem
            } else {
                format!("{stem}_{}", i + 1)
            })
        })
        .collect()
}
