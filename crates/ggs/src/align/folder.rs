//! The files of an alignment, in one folder: `poses.json` (the [`Alignment`]), `poses.txt`,
//! `scans/NAME.ply` (each placed scan moved into the common frame) and `model.ply` (the
//! placed scans merged and thinned). Each file is written atomically; the report page
//! (`report.html`, [`crate::html::alignment`]) is written beside them by the front ends.

use super::result::Alignment;
use super::scan::AlignScan;
use crate::error::{GgsError, Result};
use crate::io::{write_atomic, write_cloud};
use std::collections::BTreeSet;
use std::path::Path;

/// Write the alignment's files into `dir` (created if needed).
pub fn write_folder(dir: &Path, scans: &[AlignScan], a: &Alignment) -> Result<()> {
    std::fs::create_dir_all(dir.join("scans")).map_err(|e| GgsError::io(dir, e))?;
    let json = serde_json::to_string_pretty(a).expect("an alignment serializes");
    write_atomic(&dir.join("poses.json"), json.as_bytes())?;
    write_atomic(&dir.join("poses.txt"), a.poses_text().as_bytes())?;
    let mut used = BTreeSet::new();
    for (i, (scan, out)) in scans.iter().zip(&a.scans).enumerate() {
        let Some(pose) = &out.pose else { continue };
        let stem = Path::new(&scan.name)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| format!("scan{}", i + 1));
        let name = if used.insert(stem.clone()) {
            stem
        } else {
            format!("{stem}_{}", i + 1)
        };
        let moved: Vec<_> = scan.cloud.iter().map(|p| pose.apply(&p)).collect();
        write_cloud(&dir.join("scans").join(format!("{name}.ply")), &moved, None)?;
    }
    write_cloud(&dir.join("model.ply"), &a.merged_model(scans), None)
}
