//! Rebuilding the published FAUST-partial (FPv1) pairs from the FAUST scans.
//!
//! The published CSV (`Scan, Viewpoint_i, Viewpoint_j, overlap, T00..T33`) embeds each
//! camera's position (floor frame) in the viewpoint name. For every scan found in the scans
//! folder the cameras are read from the names, the views recomputed by hidden point removal,
//! each pair's overlap recomputed and compared with the published value, and the pairs
//! written like a generated benchmark: source = view j, target = T · view i.

use super::output::{self, Summary};
use super::viewpoints::parse_fpv1_viewpoint;
use super::{views_of_points, GeneratedPair, GeneratorConfig, ScanInput, ScanViews};
use ggs::cloud::Point;
use ggs::error::{GgsError, Result};
use ggs::transform::Rigid;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One row of the published list.
#[derive(Debug, Clone, PartialEq)]
pub struct Fpv1Row {
    pub line: usize,
    pub scan: String,
    pub view_i: u32,
    pub camera_i: Point,
    pub view_j: u32,
    pub camera_j: Point,
    /// Published overlap, percent.
    pub overlap: f64,
    pub transform: Rigid,
}

/// Parse the published CSV (header required).
pub fn parse_fpv1_csv(path: &Path, text: &str) -> Result<Vec<Fpv1Row>> {
    let mut lines = text.lines().enumerate();
    let header = lines
        .next()
        .map(|(_, h)| h)
        .ok_or_else(|| GgsError::in_file(path, "empty file"))?;
    if !header.starts_with("Scan,Viewpoint_i,Viewpoint_j,overlap,T00") {
        return Err(GgsError::at_line(
            path,
            1,
            "expected the header 'Scan,Viewpoint_i,Viewpoint_j,overlap,T00,…,T33'",
        ));
    }
    let mut rows = Vec::new();
    for (k, line) in lines {
        let n = k + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 20 {
            return Err(GgsError::at_line(
                path,
                n,
                format!("expected 20 comma-separated fields, found {}", f.len()),
            ));
        }
        let view = |s: &str, col: &str| {
            parse_fpv1_viewpoint(s).ok_or_else(|| {
                GgsError::at_line(
                    path,
                    n,
                    format!("{col}: '{s}' is not a viewpoint name like 'viewpoint3-[x y z]'"),
                )
            })
        };
        let (vi, ci) = view(f[1], "Viewpoint_i")?;
        let (vj, cj) = view(f[2], "Viewpoint_j")?;
        let num = |s: &str, col: &str| {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    GgsError::at_line(path, n, format!("{col}: '{s}' is not a finite number"))
                })
        };
        let overlap = num(f[3], "overlap")?;
        let m: Vec<f64> = f[4..20]
            .iter()
            .enumerate()
            .map(|(q, s)| num(s, &format!("T{}{}", q / 4, q % 4)))
            .collect::<Result<_>>()?;
        let transform = Rigid::from_row_major(&m, 1e-3)
            .map_err(|e| GgsError::at_line(path, n, format!("T: {e}")))?;
        rows.push(Fpv1Row {
            line: n,
            scan: f[0].trim().to_string(),
            view_i: vi,
            camera_i: ci,
            view_j: vj,
            camera_j: cj,
            overlap,
            transform,
        });
    }
    Ok(rows)
}

/// A published overlap next to the recomputed one.
#[derive(Debug, Clone, PartialEq)]
pub struct OverlapCheck {
    pub pair: String,
    pub published: f64,
    pub recomputed: f64,
}

/// What a rebuild did.
#[derive(Debug, Clone)]
pub struct Rebuilt {
    pub summary: Summary,
    pub pairs: Vec<GeneratedPair>,
    pub checks: Vec<OverlapCheck>,
    /// Scans listed in the CSV but not found in the scans folder (their pairs are skipped).
    pub missing_scans: Vec<String>,
}

/// Find `<dir>/<scan>.<ext>` for a point-cloud extension.
fn find_scan(dir: &Path, scan: &str) -> Option<PathBuf> {
    ["ply", "PLY", "obj", "pcd", "npy", "xyz"]
        .iter()
        .map(|e| dir.join(format!("{scan}.{e}")))
        .find(|p| p.is_file())
}

/// Rebuild the pairs of `csv` whose scans are in `scans_dir`, into `out`. The scans are used
/// as they are (no sampling); cameras come from the CSV; R = `cfg.flip_factor` × diagonal.
pub fn rebuild(
    csv: &Path,
    scans_dir: &Path,
    cfg: &GeneratorConfig,
    out: &Path,
    mut progress: impl FnMut(usize, usize, &str),
) -> Result<Rebuilt> {
    let text = std::fs::read_to_string(csv).map_err(|e| GgsError::io(csv, e))?;
    let rows = parse_fpv1_csv(csv, &text)?;
    let mut by_scan: BTreeMap<String, Vec<&Fpv1Row>> = BTreeMap::new();
    for r in &rows {
        by_scan.entry(r.scan.clone()).or_default().push(r);
    }
    let mut missing = Vec::new();
    let mut pairs_all = Vec::new();
    let mut checks = Vec::new();
    let mut scans = Vec::new();
    let mut view_csv = String::new();
    let total = by_scan.len();
    for (done, (scan, rows)) in by_scan.iter().enumerate() {
        match find_scan(scans_dir, scan) {
            None => missing.push(scan.clone()),
            Some(path) => {
                let views = scan_views(csv, &path, scan, rows, cfg)?;
                let pairs = published_pairs(scan, rows, &views, &mut checks);
                scans.push(output::write_scan(out, &views, &pairs)?);
                view_csv.push_str(&output::view_rows(&views));
                pairs_all.extend(pairs);
            }
        }
        progress(done + 1, total, scan);
    }
    if scans.is_empty() {
        return Err(GgsError::param(
            "scans",
            format!(
                "none of the {total} scans of {} is in {} (expected files like {}/{}.ply)",
                csv.display(),
                scans_dir.display(),
                scans_dir.display(),
                by_scan.keys().next().map_or("tr_scan_000", |s| s.as_str())
            ),
        ));
    }
    let summary = Summary::of("fpv1-published", 0, scans, &pairs_all);
    let comment = format!(
        "rebuilt by ggs partial {} from {} (published T; overlaps recomputed), flip factor {}",
        env!("CARGO_PKG_VERSION"),
        csv.file_name()
            .map_or_else(String::new, |f| f.to_string_lossy().into_owned()),
        cfg.flip_factor
    );
    output::write_index(out, &comment, &pairs_all, &view_csv, &summary)?;
    write_overlap_checks(out, &checks)?;
    Ok(Rebuilt {
        summary,
        pairs: pairs_all,
        checks,
        missing_scans: missing,
    })
}

/// The views of one scan from its published cameras, in the order of their indices. One
/// index must always name the same position (an error names the two lines otherwise).
fn scan_views(
    csv: &Path,
    path: &Path,
    scan: &str,
    rows: &[&Fpv1Row],
    cfg: &GeneratorConfig,
) -> Result<ScanViews> {
    let mut cams: BTreeMap<u32, (Point, usize)> = BTreeMap::new();
    for r in rows {
        for (v, c) in [(r.view_i, r.camera_i), (r.view_j, r.camera_j)] {
            let e = cams.entry(v).or_insert((c, r.line));
            if e.0 != c {
                return Err(GgsError::at_line(
                    csv,
                    r.line,
                    format!(
                        "{scan}: viewpoint{v} is at {c:?} here but at {:?} on line {}",
                        e.0, e.1
                    ),
                ));
            }
        }
    }
    let points = ggs::io::read_exact_points(path, None)?.points;
    let input = ScanInput {
        name: scan.to_string(),
        ..ScanInput::new(path)
    };
    let cameras = cams.values().map(|c| c.0).collect();
    let mut views = views_of_points(scan, points, false, &input, cfg, Some(cameras))?;
    views.view_ids = cams.keys().copied().collect();
    Ok(views)
}

/// The published pairs of one scan with their overlaps recomputed (each also recorded in
/// `checks` next to the published value). Repeated view pairs get a `-2`, `-3`, … suffix.
fn published_pairs(
    scan: &str,
    rows: &[&Fpv1Row],
    views: &ScanViews,
    checks: &mut Vec<OverlapCheck>,
) -> Vec<GeneratedPair> {
    let slot: BTreeMap<u32, usize> = views
        .view_ids
        .iter()
        .enumerate()
        .map(|(i, &v)| (v, i))
        .collect();
    let mut names = std::collections::HashSet::new();
    let mut pairs = Vec::new();
    for r in rows {
        let recomputed = super::overlap::overlap_percent(
            &views.visible[slot[&r.view_i]],
            &views.visible[slot[&r.view_j]],
        );
        let mut name = format!("{scan}_{}_{}", r.view_i, r.view_j);
        let mut k = 1;
        while !names.insert(name.clone()) {
            k += 1;
            name = format!("{scan}_{}_{}-{k}", r.view_i, r.view_j);
        }
        checks.push(OverlapCheck {
            pair: name.clone(),
            published: r.overlap,
            recomputed,
        });
        let (rot, t) = (r.transform.rotation, r.transform.translation);
        pairs.push(GeneratedPair {
            name,
            scan: scan.to_string(),
            view_i: r.view_i,
            view_j: r.view_j,
            overlap: recomputed,
            euler_deg: euler_xyz_of(&rot),
            transform: Rigid::new(rot, t),
            voxel: views.voxel,
        });
    }
    pairs
}

/// `overlap_check.csv`: each pair's published and recomputed overlap and their difference.
fn write_overlap_checks(out: &Path, checks: &[OverlapCheck]) -> Result<()> {
    let mut check_csv = String::from("pair,published_overlap,recomputed_overlap,difference\n");
    for c in checks {
        check_csv.push_str(&format!(
            "{},{},{},{}\n",
            c.pair,
            c.published,
            c.recomputed,
            c.recomputed - c.published
        ));
    }
    ggs::io::write_atomic(&out.join("overlap_check.csv"), check_csv.as_bytes())
}

/// Euler 'xyz' angles (degrees) of a rotation `R = R_z(γ)·R_y(β)·R_x(α)`.
pub fn euler_xyz_of(r: &nalgebra::Matrix3<f64>) -> [f64; 3] {
    let beta = (-r[(2, 0)]).clamp(-1.0, 1.0).asin();
    let (alpha, gamma) = if r[(2, 0)].abs() < 1.0 - 1e-12 {
        (r[(2, 1)].atan2(r[(2, 2)]), r[(1, 0)].atan2(r[(0, 0)]))
    } else {
        // Gimbal lock: put the whole remaining angle in α.
        ((-r[(1, 2)]).atan2(r[(1, 1)]), 0.0)
    };
    [alpha.to_degrees(), beta.to_degrees(), gamma.to_degrees()]
}

#[cfg(test)]
mod tests {
    use super::super::presets::euler_xyz;
    use super::super::viewpoints::fpv1_icosphere;
    use super::*;

    const PUBLISHED: &str = include_str!("../../protocols/fpv1_benchmark_1724_pairs.csv");

    #[test]
    fn parses_the_published_list() {
        let rows = parse_fpv1_csv(Path::new("fpv1.csv"), PUBLISHED).unwrap();
        assert_eq!(rows.len(), 1724);
        assert_eq!(rows[0].scan, "tr_scan_000");
        assert_eq!(rows[0].view_j, 4);
        assert!((rows[0].overlap - 60.104).abs() < 1e-3);
    }

    #[test]
    fn published_cameras_are_the_first_twelve_above_floor_vertices() {
        // In every scan, the published camera k minus camera 0 equals
        // 1.5 m × (vertex_k − vertex_0) of our icosphere's above-floor list (the centre
        // cancels), so our vertex order names the same cameras.
        let rows = parse_fpv1_csv(Path::new("fpv1.csv"), PUBLISHED).unwrap();
        let sphere: Vec<[f64; 3]> = fpv1_icosphere(1)
            .into_iter()
            .filter(|v| v[1] > -0.7) // below the floor for FAUST: u_y ≤ −0.77
            .collect();
        let mut checked = 0;
        let mut cams: BTreeMap<(String, u32), Point> = BTreeMap::new();
        for r in &rows {
            cams.insert((r.scan.clone(), r.view_i), r.camera_i);
            cams.insert((r.scan.clone(), r.view_j), r.camera_j);
        }
        for ((scan, k), c) in &cams {
            let Some(c0) = cams.get(&(scan.clone(), 0)) else {
                continue;
            };
            let v = sphere[*k as usize];
            let v0 = sphere[0];
            for a in 0..3 {
                let expected = 1.5 * (v[a] - v0[a]);
                assert!(
                    (c[a] - c0[a] - expected).abs() < 2e-6,
                    "{scan} viewpoint{k} axis {a}: {} vs {expected}",
                    c[a] - c0[a]
                );
            }
            checked += 1;
        }
        assert!(checked > 1000, "{checked}");
    }

    #[test]
    fn euler_round_trip() {
        for a in [[10.0, 20.0, 30.0], [-170.0, 80.0, 5.0], [0.0, -45.0, 179.0]] {
            let b = euler_xyz_of(&euler_xyz(a));
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-9, "{a:?} {b:?}");
            }
        }
    }

    #[test]
    fn bad_rows_name_their_line() {
        let p = Path::new("x.csv");
        let head = "Scan,Viewpoint_i,Viewpoint_j,overlap,T00,T01,T02,T03,T10,T11,T12,T13,T20,T21,T22,T23,T30,T31,T32,T33\n";
        let ok = "s,viewpoint0-[0 1 0],viewpoint1-[1 1 0],70,1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1\n";
        assert_eq!(parse_fpv1_csv(p, &format!("{head}{ok}")).unwrap().len(), 1);
        let e = parse_fpv1_csv(
            p,
            &format!(
                "{head}{ok}s,viewpoint0,viewpoint1-[1 1 0],70,1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1\n"
            ),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("line 3") && e.contains("Viewpoint_i"), "{e}");
        let e = parse_fpv1_csv(p, &format!("{head}s,viewpoint0-[0 1 0],viewpoint1-[1 1 0],70,2,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("T:"), "{e}");
        assert!(parse_fpv1_csv(p, "a,b\n").is_err());
    }
}
