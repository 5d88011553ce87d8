//! The published benchmark protocols (docs/benchmarks.md): pair lists, ground truth and defaults.
//!
//! The metadata ships inside the library (`crates/ggs-bench/protocols/`, see its README for the
//! provenance); only the point clouds come from the user's data directory:
//!
//! | protocol | clouds under `--data DIR` | ground truth | pairs |
//! |---|---|---|---|
//! | `3dmatch` | `<scene>/cloud_bin_<k>.ply` | shipped (gt.log of each scene) | 1623 gt pairs, PREDATOR overlap ≥ 0.30 → 1523 |
//! | `kitti` | `<seq>/velodyne/<frame:06>.bin` | shipped | 555 (target = frame0, source = frame1) |
//! | `eth` | `<scene>/Hokuyo_<k>.ply` | the user's `<scene>/gt.log` | overlap ≥ 0.30 both ways → 713 |
//! | `fpv1` | `<scan>.ply` (or `scans/<scan>.ply`) + `visible/<scan>/<view>.txt` | shipped | 1724 |
//!
//! In every protocol the ground truth `T` maps the source into the target's frame.

use super::pair::{BenchPair, CloudRef};
use ggs::error::{GgsError, Result};
use ggs::transform::Rigid;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

const THREEDMATCH_PAIRS: &str = include_str!("../../protocols/3dmatch_1623_pairs_with_overlap.csv");
const THREEDMATCH_PREDATOR: &str = include_str!("../../protocols/3dmatch_overlap_predator.csv");
const KITTI_PAIRS: &str = include_str!("../../protocols/kitti_test_555_pairs.csv");
const ETH_OVERLAP: &str = include_str!("../../protocols/eth_overlap_perfect_match.csv");
const FPV1_PAIRS: &str = include_str!("../../protocols/fpv1_benchmark_1724_pairs.csv");

/// Minimum overlap of the 3DMatch and ETH protocols.
pub const MIN_OVERLAP: f64 = 0.30;

/// Tolerance for a ground-truth rotation to be accepted as one: the published 3DMatch
/// matrices carry 9 significant digits and are orthonormal to ~7e-5 only. They are used as
/// published (as the reference evaluation does).
const ROTATION_TOL: f64 = 1e-3;

/// A benchmark protocol.
#[derive(Debug, Clone, PartialEq)]
pub enum Protocol {
    ThreeDMatch,
    Kitti,
    Eth,
    Fpv1,
    /// A `pairs.tsv`-style manifest (the file's path).
    Manifest(PathBuf),
}

/// Default parameters of a protocol (docs/benchmarks.md), all overridable.
#[derive(Debug, Clone, PartialEq)]
pub struct Defaults {
    /// Voxel size in the clouds' units; `None`: the manifest's per-pair value.
    pub voxel: Option<f64>,
    /// Success threshold on RRE, degrees (strict).
    pub max_rre_deg: f64,
    /// Success threshold on RTE in the clouds' units; `None`: `3 ×` the pair's voxel.
    pub max_rte: Option<f64>,
    /// The rotation set of `--preset paper` for this protocol: the GGS paper's `limited15`,
    /// except FAUST-partial, whose rotations span ±180° and need a full-SO(3) set. Every
    /// protocol otherwise runs the default pipeline (full SO(3), verified hypotheses): ggs's
    /// best with no initial guess.
    pub paper_rotations: &'static str,
}

impl Protocol {
    /// Parse a protocol name (`3dmatch`, `kitti`, `eth`, `fpv1`); `manifest` needs a path.
    pub fn from_name(name: &str, manifest: Option<&Path>) -> Result<Protocol> {
        Ok(match name.to_ascii_lowercase().as_str() {
            "3dmatch" => Protocol::ThreeDMatch,
            "kitti" => Protocol::Kitti,
            "eth" => Protocol::Eth,
            "fpv1" | "faust-partial" => Protocol::Fpv1,
            "manifest" => Protocol::Manifest(
                manifest
                    .ok_or_else(|| {
                        GgsError::param("protocol", "manifest needs the manifest file's path")
                    })?
                    .to_path_buf(),
            ),
            other => {
                return Err(GgsError::param(
                    "protocol",
                    format!("unknown protocol '{other}' (3dmatch, kitti, eth, fpv1, manifest)"),
                ))
            }
        })
    }

    /// Short name, as in file names and tables.
    pub fn name(&self) -> &'static str {
        match self {
            Protocol::ThreeDMatch => "3dmatch",
            Protocol::Kitti => "kitti",
            Protocol::Eth => "eth",
            Protocol::Fpv1 => "fpv1",
            Protocol::Manifest(_) => "manifest",
        }
    }

    /// The protocols' published thresholds and voxel sizes. KITTI's RTE threshold is the later 0.6 m (the GGS paper used 2 m);
    /// FAUST-partial needs a full SO(3) set (its rotations span ±180°). A generic manifest
    /// succeeds within 10° and 3 voxels of the pair's own voxel size.
    pub fn defaults(&self) -> Defaults {
        let d = |voxel, r, t, paper_rotations| Defaults {
            voxel: Some(voxel),
            max_rre_deg: r,
            max_rte: Some(t),
            paper_rotations,
        };
        match self {
            Protocol::ThreeDMatch => d(0.06, 15.0, 0.30, "limited15"),
            Protocol::Kitti => d(0.75, 5.0, 0.6, "limited15"),
            Protocol::Eth => d(0.60, 5.0, 0.30, "limited15"),
            Protocol::Fpv1 => d(0.06, 10.0, 0.03, "hopf15-dedup"),
            Protocol::Manifest(_) => Defaults {
                voxel: None,
                max_rre_deg: 10.0,
                max_rte: None,
                paper_rotations: "limited15",
            },
        }
    }

    /// The protocol's pairs, with the clouds' paths under `data` (not checked here: see
    /// [`super::missing_files`]). ETH reads its ground truth from `data`.
    pub fn pairs(&self, data: &Path) -> Result<Vec<BenchPair>> {
        match self {
            Protocol::ThreeDMatch => threedmatch_pairs(data),
            Protocol::Kitti => kitti_pairs(data),
            Protocol::Eth => eth_pairs(data),
            Protocol::Fpv1 => fpv1_pairs(data),
            Protocol::Manifest(path) => Ok(crate::manifest::read_manifest(path)?
                .into_iter()
                .map(|p| BenchPair {
                    id: p.name,
                    source: CloudRef::File(p.source),
                    target: CloudRef::File(p.target),
                    ground_truth: p.ground_truth,
                    voxel: Some(p.voxel),
                    overlap: None,
                })
                .collect()),
        }
    }
}

/// Rows of an embedded CSV `file` (header skipped), split on commas, with their 1-based line
/// numbers; a row without exactly as many fields as the header is an error.
fn csv_rows<'a>(
    file: &'static str,
    text: &'a str,
) -> impl Iterator<Item = Result<(usize, Vec<&'a str>)>> + 'a {
    let header = text.lines().next().unwrap_or("");
    let n = header.split(',').count();
    text.lines()
        .enumerate()
        .skip(1)
        .filter(|(_, l)| !l.trim().is_empty())
        .map(move |(i, l)| {
            let f: Vec<&str> = l.split(',').map(str::trim).collect();
            if f.len() == n {
                Ok((i + 1, f))
            } else {
                Err(meta_error(
                    file,
                    i + 1,
                    format!("expected {n} fields ({header}), found {}", f.len()),
                ))
            }
        })
}

/// An error in shipped metadata (a broken build, not bad user input).
fn meta_error(file: &str, line: usize, message: impl Into<String>) -> GgsError {
    GgsError::at_line(Path::new(file), line, message)
}

fn num<T: std::str::FromStr>(file: &str, line: usize, field: &str, s: &str) -> Result<T> {
    s.parse()
        .map_err(|_| meta_error(file, line, format!("{field}: cannot read '{s}'")))
}

/// A row-major 4×4 from 16 fields.
fn matrix(file: &str, line: usize, fields: &[&str]) -> Result<Rigid> {
    let mut m = [0.0; 16];
    for (k, f) in fields.iter().enumerate() {
        m[k] = num(file, line, "T", f)?;
    }
    Rigid::from_row_major(&m, ROTATION_TOL).map_err(|e| meta_error(file, line, e.to_string()))
}

/// 3DMatch: the 1623 gt.log pairs (with their ground truth), kept where the PREDATOR
/// overlap is at least 0.30. gt.log maps cloud j into cloud i: source = j, target = i.
fn threedmatch_pairs(data: &Path) -> Result<Vec<BenchPair>> {
    const PAIRS: &str = "3dmatch_1623_pairs_with_overlap.csv";
    const PREDATOR: &str = "3dmatch_overlap_predator.csv";
    let mut overlap: HashMap<(String, u32, u32), f64> = HashMap::new();
    for row in csv_rows(PREDATOR, THREEDMATCH_PREDATOR) {
        let (line, f) = row?;
        let key = (
            f[0].to_string(),
            num(PREDATOR, line, "i", f[1])?,
            num(PREDATOR, line, "j", f[2])?,
        );
        overlap.insert(key, num(PREDATOR, line, "overlap", f[3])?);
    }
    let mut pairs = Vec::new();
    for row in csv_rows(PAIRS, THREEDMATCH_PAIRS) {
        let (line, f) = row?;
        let (scene, i, j): (&str, u32, u32) = (
            f[0],
            num(PAIRS, line, "i", f[1])?,
            num(PAIRS, line, "j", f[2])?,
        );
        let o = *overlap
            .get(&(scene.to_string(), i, j))
            .ok_or_else(|| meta_error(PAIRS, line, "pair missing from the PREDATOR overlaps"))?;
        if o < MIN_OVERLAP {
            continue;
        }
        let cloud = |k: u32| CloudRef::File(data.join(scene).join(format!("cloud_bin_{k}.ply")));
        pairs.push(BenchPair {
            id: format!("{scene}/{i}_{j}"),
            source: cloud(j),
            target: cloud(i),
            ground_truth: matrix(PAIRS, line, &f[3..19])?,
            voxel: None,
            overlap: Some(o),
        });
    }
    Ok(pairs)
}

/// KITTI: the 555 test pairs of sequences 08–10; T maps frame1 (source) into frame0.
fn kitti_pairs(data: &Path) -> Result<Vec<BenchPair>> {
    const FILE: &str = "kitti_test_555_pairs.csv";
    csv_rows(FILE, KITTI_PAIRS)
        .map(|row| {
            let (line, f) = row?;
            let scan = |frame: &str| {
                CloudRef::File(
                    data.join(f[0])
                        .join("velodyne")
                        .join(format!("{frame}.bin")),
                )
            };
            Ok(BenchPair {
                id: format!("{}/{}_{}", f[0], f[1], f[2]),
                source: scan(f[2]),
                target: scan(f[1]),
                ground_truth: matrix(FILE, line, &f[3..19])?,
                voxel: None,
                overlap: None,
            })
        })
        .collect()
}

/// ETH scenes, in the order of the tables.
pub const ETH_SCENES: [&str; 4] = [
    "gazebo_summer",
    "gazebo_winter",
    "wood_autmn",
    "wood_summer",
];

/// The ETH pairs: unordered `(scene, i, j, overlap(i, j))` with `i < j` whose Perfect-Match
/// overlap is at least 0.30 in both directions (713), in table order (scene, i, j).
pub fn eth_selection() -> Result<Vec<(String, u32, u32, f64)>> {
    const FILE: &str = "eth_overlap_perfect_match.csv";
    let mut overlap: HashMap<(String, u32, u32), f64> = HashMap::new();
    for row in csv_rows(FILE, ETH_OVERLAP) {
        let (line, f) = row?;
        overlap.insert(
            (
                f[0].to_string(),
                num(FILE, line, "i", f[1])?,
                num(FILE, line, "j", f[2])?,
            ),
            num(FILE, line, "overlap", f[3])?,
        );
    }
    let mut selected: Vec<(String, u32, u32, f64)> = overlap
        .iter()
        .filter(|((s, i, j), &o)| {
            i < j && o >= MIN_OVERLAP && overlap.get(&(s.clone(), *j, *i)) >= Some(&MIN_OVERLAP)
        })
        .map(|((s, i, j), &o)| (s.clone(), *i, *j, o))
        .collect();
    selected.sort_by(|a, b| {
        let scene = |s: &str| ETH_SCENES.iter().position(|x| *x == s);
        (scene(&a.0), a.1, a.2).cmp(&(scene(&b.0), b.1, b.2))
    });
    Ok(selected)
}

/// ETH: [`eth_selection`] with the ground truth from the user's `<scene>/gt.log`.
fn eth_pairs(data: &Path) -> Result<Vec<BenchPair>> {
    let selected = eth_selection()?;
    let missing: Vec<String> = ETH_SCENES
        .iter()
        .map(|s| data.join(s).join("gt.log"))
        .filter(|p| !p.is_file())
        .map(|p| p.display().to_string())
        .collect();
    if !missing.is_empty() {
        return Err(GgsError::param(
            "data",
            format!(
                "ETH needs each scene's gt.log; {} missing: {}",
                missing.len(),
                missing.join(", ")
            ),
        ));
    }
    let mut logs: HashMap<String, HashMap<(u32, u32), Rigid>> = HashMap::new();
    let mut pairs = Vec::new();
    for (scene, i, j, o) in selected {
        if !logs.contains_key(&scene) {
            let path = data.join(&scene).join("gt.log");
            let text = std::fs::read_to_string(&path).map_err(|e| GgsError::io(&path, e))?;
            logs.insert(scene.clone(), parse_gt_log(&path, &text)?);
        }
        let log = &logs[&scene];
        let gt_path = data.join(&scene).join("gt.log");
        // gt.log maps j into i; a record listed the other way round is inverted.
        let ground_truth = match (log.get(&(i, j)), log.get(&(j, i))) {
            (Some(t), _) => *t,
            (None, Some(t)) => t.inverse(),
            (None, None) => {
                return Err(GgsError::in_file(
                    &gt_path,
                    format!("no record for the pair {i} {j} (nor {j} {i})"),
                ))
            }
        };
        let cloud = |k: u32| CloudRef::File(data.join(&scene).join(format!("Hokuyo_{k}.ply")));
        pairs.push(BenchPair {
            id: format!("{scene}/{i}_{j}"),
            source: cloud(j),
            target: cloud(i),
            ground_truth,
            voxel: None,
            overlap: Some(o),
        });
    }
    Ok(pairs)
}

/// Parse a gt.log: records of a line `i j n` and four lines of a 4×4 mapping cloud j into
/// cloud i.
pub fn parse_gt_log(path: &Path, text: &str) -> Result<HashMap<(u32, u32), Rigid>> {
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    if !lines.len().is_multiple_of(5) {
        return Err(GgsError::in_file(
            path,
            format!(
                "{} non-empty lines: records are 5 lines (i j n, then a 4×4 matrix)",
                lines.len()
            ),
        ));
    }
    let mut out = HashMap::new();
    for rec in lines.chunks_exact(5) {
        let (line, head) = rec[0];
        let ids: Vec<&str> = head.split_whitespace().collect();
        let id = |k: usize| -> Result<u32> {
            ids.get(k).and_then(|s| s.parse().ok()).ok_or_else(|| {
                GgsError::at_line(path, line, format!("expected 'i j n', found '{head}'"))
            })
        };
        let (i, j) = (id(0)?, id(1)?);
        let mut m = [0.0; 16];
        for (r, &(l, row)) in rec[1..].iter().enumerate() {
            let v: Vec<f64> = row
                .split_whitespace()
                .map(|s| s.parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| {
                    GgsError::at_line(path, l, format!("cannot read a matrix row: '{row}'"))
                })?;
            if v.len() != 4 {
                return Err(GgsError::at_line(
                    path,
                    l,
                    format!("expected 4 numbers, found {}", v.len()),
                ));
            }
            m[4 * r..4 * r + 4].copy_from_slice(&v);
        }
        let t = Rigid::from_row_major(&m, ROTATION_TOL)
            .map_err(|e| GgsError::at_line(path, line, e.to_string()))?;
        out.insert((i, j), t);
    }
    Ok(out)
}

/// The view index of an FPv1 viewpoint name such as `viewpoint4-[ 0.37 0.36 -1.19]`.
pub fn fpv1_view_index(name: &str) -> Option<u32> {
    name.strip_prefix("viewpoint")?
        .split('-')
        .next()?
        .parse()
        .ok()
}

/// FAUST-partial (FPv1): 1724 pairs; target = T·scan[visible from v_i], source =
/// scan[visible from v_j], so T maps the source into the target. The visible-point sets are
/// index files `visible/<scan>/<view>.txt` under `data` (from `ggs partial`, or precomputed).
fn fpv1_pairs(data: &Path) -> Result<Vec<BenchPair>> {
    const FILE: &str = "fpv1_benchmark_1724_pairs.csv";
    let mut ids = HashSet::new();
    csv_rows(FILE, FPV1_PAIRS)
        .map(|row| {
            let (line, f) = row?;
            let view = |s: &str| {
                fpv1_view_index(s).ok_or_else(|| {
                    meta_error(FILE, line, format!("cannot read the view index of '{s}'"))
                })
            };
            let (scan, vi, vj) = (f[0], view(f[1])?, view(f[2])?);
            let t = matrix(FILE, line, &f[4..20])?;
            // `ggs partial --fpv1` writes the scans under `scans/`; a FAUST folder has them
            // at its top.
            let scans = if data.join("scans").is_dir() {
                data.join("scans")
            } else {
                data.to_path_buf()
            };
            let visible = |v: u32| CloudRef::Visible {
                cloud: scans.join(format!("{scan}.ply")),
                indices: data.join("visible").join(scan).join(format!("{v}.txt")),
                transform: None,
            };
            let mut target = visible(vi);
            if let CloudRef::Visible { transform, .. } = &mut target {
                *transform = Some(t);
            }
            let mut id = format!("{scan}/{vi}_{vj}");
            // The published list repeats some (scan, vi, vj) with different T: keep all.
            let mut k = 1;
            while !ids.insert(id.clone()) {
                k += 1;
                id = format!("{scan}/{vi}_{vj}#{k}");
            }
            Ok(BenchPair {
                id,
                source: visible(vj),
                target,
                ground_truth: t,
                voxel: None,
                overlap: Some(num::<f64>(FILE, line, "overlap", f[3])? / 100.0),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_index_from_the_name() {
        assert_eq!(fpv1_view_index("viewpoint0-[-0.41 2.43 0.08]"), Some(0));
        assert_eq!(fpv1_view_index("viewpoint11-[ 0.3 1.9 -1.1]"), Some(11));
        assert_eq!(fpv1_view_index("view3"), None);
    }

    #[test]
    fn metadata_rows_need_the_header_width() {
        let rows: Vec<_> = csv_rows("m.csv", "a,b,c\n1,2,3\n\n4,5\n").collect();
        assert_eq!(rows[0].as_ref().unwrap(), &(2, vec!["1", "2", "3"]));
        let e = rows[1].as_ref().unwrap_err().to_string();
        assert!(
            e.contains("line 4") && e.contains("expected 3 fields"),
            "{e}"
        );
    }

    #[test]
    fn gt_log_errors_name_the_line() {
        let p = Path::new("gt.log");
        let ok = "0 1 2\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
        assert_eq!(parse_gt_log(p, ok).unwrap().len(), 1);
        let e = parse_gt_log(p, &ok.replace("0 1 0 0", "0 x 0 0"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 3"), "{e}");
        let e = parse_gt_log(p, &ok[..ok.len() - 8])
            .unwrap_err()
            .to_string();
        assert!(e.contains("records are 5 lines"), "{e}");
        let e = parse_gt_log(p, &ok.replace("1 0 0 0", "2 0 0 0"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 1"), "{e}");
    }
}
