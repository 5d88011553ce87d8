//! Writing a generated benchmark: views, pairs, the manifest that `ggs bench manifest` runs,
//! and a summary.
//!
//! ```text
//! OUT/pairs.tsv                  manifest (format of shared/data/pairs.tsv)
//! OUT/pair_list.csv              name, scan, views, overlap, Euler angles, translation
//! OUT/views.csv                  scan, view, camera (floor frame), visible points
//! OUT/summary.md, summary.json   views per scan, pairs per overlap band, histograms
//! OUT/scans/<scan>.ply           the scan's points (sampled from the mesh if it was one)
//! OUT/visible/<scan>/<k>.txt     visible point indices of view k (FPv1 layout)
//! OUT/views/<scan>/<k>.ply       view k's points, scan frame (the pairs' sources)
//! OUT/pairs/<pair>.ply           T · view i (the pairs' targets)
//! ```
//! Every file is written atomically; nothing in them depends on time or thread count.

use super::{GeneratedPair, ScanViews};
use crate::manifest::{write_manifest, Pair};
use ggs::cloud::Point;
use ggs::error::{GgsError, Result};
use ggs::io::{ply, write_atomic};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Refuse to write into a non-empty folder unless `force`; create it otherwise.
pub fn prepare_out(out: &Path, force: bool) -> Result<()> {
    if let Ok(mut entries) = std::fs::read_dir(out) {
        if entries.next().is_some() && !force {
            return Err(GgsError::param(
                "out",
                format!(
                    "{} is not empty; choose a new folder or pass --force to overwrite",
                    out.display()
                ),
            ));
        }
    }
    std::fs::create_dir_all(out).map_err(|e| GgsError::io(out, e))
}

fn mkdir(p: &Path) -> Result<()> {
    std::fs::create_dir_all(p).map_err(|e| GgsError::io(p, e))
}

fn write_points(path: &Path, pts: &[Point]) -> Result<()> {
    ply::write_ply(path, pts, None, ply::PlyWriteOptions::default())
}

/// What one scan contributed, for the summary.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ScanSummary {
    pub name: String,
    pub points: usize,
    pub sampled_from_mesh: bool,
    pub views: usize,
    pub visible_min: usize,
    pub visible_max: usize,
    pub visible_mean: f64,
    pub pairs: usize,
    pub voxel: f64,
}

/// Write one scan's files (scan, visible indices, views, pair targets) and return its
/// summary line. `pairs` are this scan's pairs.
pub fn write_scan(out: &Path, scan: &ScanViews, pairs: &[GeneratedPair]) -> Result<ScanSummary> {
    let name = &scan.name;
    for sub in ["scans", "pairs"] {
        mkdir(&out.join(sub))?;
    }
    let (vis_dir, view_dir) = (out.join("visible").join(name), out.join("views").join(name));
    mkdir(&vis_dir)?;
    mkdir(&view_dir)?;
    write_points(&out.join("scans").join(format!("{name}.ply")), &scan.points)?;
    for (k, idx) in scan.visible.iter().enumerate() {
        let mut text = String::with_capacity(idx.len() * 7);
        for i in idx {
            writeln!(text, "{i}").expect("write to String");
        }
        let id = scan.view_ids[k];
        write_atomic(&vis_dir.join(format!("{id}.txt")), text.as_bytes())?;
        let pts: Vec<Point> = idx.iter().map(|&i| scan.points[i as usize]).collect();
        write_points(&view_dir.join(format!("{id}.ply")), &pts)?;
    }
    for p in pairs {
        let slot = scan
            .view_ids
            .iter()
            .position(|&v| v == p.view_i)
            .expect("pairs refer to the scan's views");
        let pts: Vec<Point> = scan.visible[slot]
            .iter()
            .map(|&i| p.transform.apply(&scan.points[i as usize]))
            .collect();
        write_points(&out.join("pairs").join(format!("{}.ply", p.name)), &pts)?;
    }
    let sizes: Vec<usize> = scan.visible.iter().map(Vec::len).collect();
    Ok(ScanSummary {
        name: name.clone(),
        points: scan.points.len(),
        sampled_from_mesh: scan.sampled,
        views: sizes.len(),
        visible_min: sizes.iter().copied().min().unwrap_or(0),
        visible_max: sizes.iter().copied().max().unwrap_or(0),
        visible_mean: sizes.iter().sum::<usize>() as f64 / sizes.len().max(1) as f64,
        pairs: pairs.len(),
        voxel: scan.voxel,
    })
}

/// One row of `views.csv`.
pub fn view_rows(scan: &ScanViews) -> String {
    let mut s = String::new();
    for ((c, v), id) in scan.cameras.iter().zip(&scan.visible).zip(&scan.view_ids) {
        writeln!(
            s,
            "{},{id},{},{},{},{}",
            scan.name,
            c[0],
            c[1],
            c[2],
            v.len()
        )
        .expect("String");
    }
    s
}

/// A labelled histogram bin.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Bin {
    pub range: String,
    pub count: usize,
}

fn histogram(values: &[f64], edges: &[f64], unit: &str) -> Vec<Bin> {
    let mut bins: Vec<Bin> = edges
        .windows(2)
        .map(|w| Bin {
            range: format!("[{}, {}){unit}", w[0], w[1]),
            count: 0,
        })
        .collect();
    for &v in values {
        if let Some(k) = edges.windows(2).position(|w| v >= w[0] && v < w[1]) {
            bins[k].count += 1;
        } else if v == *edges.last().expect("edges") {
            bins.last_mut().expect("bins").count += 1;
        }
    }
    bins
}

/// The benchmark's summary (`summary.json`; `summary.md` is its table form).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Summary {
    pub preset: String,
    pub seed: u64,
    pub pairs: usize,
    pub scans: Vec<ScanSummary>,
    pub overlap_percent: Vec<Bin>,
    pub rotation_deg: Vec<Bin>,
    pub translation: Vec<Bin>,
}

impl Summary {
    pub fn of(preset: &str, seed: u64, scans: Vec<ScanSummary>, pairs: &[GeneratedPair]) -> Self {
        let overlaps: Vec<f64> = pairs.iter().map(|p| p.overlap).collect();
        let angles: Vec<f64> = pairs
            .iter()
            .map(|p| {
                ggs::transform::rotation_angle_deg(
                    &p.transform.rotation,
                    &nalgebra::Matrix3::identity(),
                )
            })
            .collect();
        let norms: Vec<f64> = pairs
            .iter()
            .map(|p| p.transform.translation.norm())
            .collect();
        let ten: Vec<f64> = (0..=10).map(|k| k as f64 * 10.0).collect();
        let twenty: Vec<f64> = (0..=9).map(|k| k as f64 * 20.0).collect();
        Summary {
            preset: preset.to_string(),
            seed,
            pairs: pairs.len(),
            scans,
            overlap_percent: histogram(&overlaps, &ten, " %"),
            rotation_deg: histogram(&angles, &twenty, "°"),
            translation: histogram(
                &norms,
                &[
                    0.0,
                    0.25,
                    0.5,
                    0.75,
                    1.0,
                    2.0,
                    3.0,
                    5.0,
                    7.5,
                    10.0,
                    f64::INFINITY,
                ],
                "",
            ),
        }
    }

    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "# Generated benchmark: preset `{}`, seed {}\n\n{} pairs.\n",
            self.preset, self.seed, self.pairs
        );
        let _ = writeln!(
            s,
            "| scan | points | from mesh | views | visible min / mean / max | pairs | voxel |\n|---|---|---|---|---|---|---|"
        );
        for c in &self.scans {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} / {:.0} / {} | {} | {} |",
                c.name,
                c.points,
                if c.sampled_from_mesh { "yes" } else { "no" },
                c.views,
                c.visible_min,
                c.visible_mean,
                c.visible_max,
                c.pairs,
                c.voxel
            );
        }
        for (title, bins) in [
            ("Pairs per overlap band", &self.overlap_percent),
            ("Rotation angle of T", &self.rotation_deg),
            ("Translation norm of T", &self.translation),
        ] {
            let _ = writeln!(s, "\n## {title}\n\n| range | pairs |\n|---|---|");
            for b in bins.iter() {
                let _ = writeln!(s, "| {} | {} |", b.range, b.count);
            }
        }
        s
    }
}

/// Write the benchmark-wide files: manifest, pair list, view list, summaries.
pub fn write_index(
    out: &Path,
    header_comment: &str,
    pairs: &[GeneratedPair],
    view_csv: &str,
    summary: &Summary,
) -> Result<()> {
    let mut list = String::from(
        "name,scan,view_i,view_j,overlap,euler_x_deg,euler_y_deg,euler_z_deg,tx,ty,tz\n",
    );
    for p in pairs {
        let scan = &p.scan;
        let t = p.transform.translation;
        let _ = writeln!(
            list,
            "{},{scan},{},{},{},{},{},{},{},{},{}",
            p.name,
            p.view_i,
            p.view_j,
            p.overlap,
            p.euler_deg[0],
            p.euler_deg[1],
            p.euler_deg[2],
            t[0],
            t[1],
            t[2]
        );
    }
    let manifest: Vec<Pair> = pairs
        .iter()
        .map(|p| Pair {
            name: p.name.clone(),
            source: format!("views/{}/{}.ply", p.scan, p.view_j).into(),
            target: format!("pairs/{}.ply", p.name).into(),
            ground_truth: p.transform,
            gt_quality: "exact".into(),
            voxel: p.voxel,
        })
        .collect();
    write_manifest(&out.join("pairs.tsv"), &[header_comment], &manifest)?;
    write_atomic(&out.join("pair_list.csv"), list.as_bytes())?;
    write_atomic(
        &out.join("views.csv"),
        format!("scan,view,camera_x,camera_y,camera_z,visible_points\n{view_csv}").as_bytes(),
    )?;
    write_atomic(&out.join("summary.md"), summary.markdown().as_bytes())?;
    let json = serde_json::to_string_pretty(summary).expect("summary serializes") + "\n";
    write_atomic(&out.join("summary.json"), json.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_edges() {
        let b = histogram(
            &[0.0, 9.99, 10.0, 100.0, 55.0],
            &[0.0, 10.0, 50.0, 100.0],
            "",
        );
        assert_eq!(b.iter().map(|b| b.count).collect::<Vec<_>>(), vec![2, 1, 2]);
    }
}
