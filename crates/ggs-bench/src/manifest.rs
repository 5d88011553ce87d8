//! Pair manifests in the format of `shared/data/pairs.tsv`: tab-separated
//! `name  source  target  T(16 numbers, row-major)  gt_quality  suggested_voxel`, `#` comments.
//! Source and target paths are relative to the manifest's folder unless absolute.

use ggs::error::{GgsError, Result};
use ggs::transform::Rigid;
use std::path::{Path, PathBuf};

/// One registration pair with its ground truth, `p_target = T · p_source`.
#[derive(Debug, Clone)]
pub struct Pair {
    pub name: String,
    pub source: PathBuf,
    pub target: PathBuf,
    pub ground_truth: Rigid,
    /// `exact` or `reference` (a pose that itself came from a registration).
    pub gt_quality: String,
    /// Voxel size that suits the pair, in the clouds' units.
    pub voxel: f64,
}

/// The manifest's first line: the columns, as a comment.
pub const HEADER: &str = "# name\tsource\ttarget\tT (16 numbers, row-major; p_target = T * p_source)\tgt_quality\tsuggested_voxel_m";

/// The text of a manifest: [`HEADER`], one `# ` line per comment, one line per pair (paths as
/// given, T row-major in Rust's shortest round-trip form, so reading it back gives the same
/// bits).
pub fn manifest_text(comments: &[&str], pairs: &[Pair]) -> String {
    use std::fmt::Write;
    let mut tsv = format!("{HEADER}\n");
    for c in comments {
        let _ = writeln!(tsv, "# {c}");
    }
    for p in pairs {
        let m: Vec<String> = p
            .ground_truth
            .to_rows()
            .concat()
            .iter()
            .map(|v| format!("{v}"))
            .collect();
        let _ = writeln!(
            tsv,
            "{}\t{}\t{}\t{}\t{}\t{}",
            p.name,
            p.source.display(),
            p.target.display(),
            m.join(" "),
            p.gt_quality,
            p.voxel
        );
    }
    tsv
}

/// Writes a manifest atomically (a temporary file, then a rename).
pub fn write_manifest(path: &Path, comments: &[&str], pairs: &[Pair]) -> Result<()> {
    ggs::io::write_atomic(path, manifest_text(comments, pairs).as_bytes())
}

/// Read a manifest file.
pub fn read_manifest(path: &Path) -> Result<Vec<Pair>> {
    let text = std::fs::read_to_string(path).map_err(|e| GgsError::io(path, e))?;
    let base = path.parent().unwrap_or(Path::new("."));
    parse_manifest(path, base, &text)
}

/// Parse manifest text; `path` names it in errors, `base` resolves relative paths.
pub fn parse_manifest(path: &Path, base: &Path, text: &str) -> Result<Vec<Pair>> {
    let mut pairs = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        if line.trim().is_empty() || line.trim_start().starts_with('#') {
            continue;
        }
        let f: Vec<&str> = line.split('\t').collect();
        if f.len() != 6 {
            return Err(GgsError::at_line(
                path,
                n,
                format!(
                    "expected 6 tab-separated fields (name, source, target, T, gt_quality, voxel), found {}",
                    f.len()
                ),
            ));
        }
        let nums: Vec<f64> = f[3]
            .split_whitespace()
            .map(|t| {
                t.parse::<f64>().map_err(|_| {
                    GgsError::at_line(path, n, format!("field T: '{t}' is not a number"))
                })
            })
            .collect::<Result<_>>()?;
        let ground_truth = Rigid::from_row_major(&nums, 1e-3)
            .map_err(|m| GgsError::at_line(path, n, format!("field T: {m}")))?;
        let voxel: f64 = f[5].trim().parse().map_err(|_| {
            GgsError::at_line(
                path,
                n,
                format!("field suggested_voxel: '{}' is not a number", f[5]),
            )
        })?;
        if !(voxel.is_finite() && voxel > 0.0) {
            return Err(GgsError::at_line(
                path,
                n,
                format!("field suggested_voxel: must be positive, got {voxel}"),
            ));
        }
        let resolve = |p: &str| {
            let p = Path::new(p.trim());
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                base.join(p)
            }
        };
        pairs.push(Pair {
            name: f[0].trim().to_string(),
            source: resolve(f[1]),
            target: resolve(f[2]),
            ground_truth,
            gt_quality: f[4].trim().to_string(),
            voxel,
        });
    }
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_manifests_read_back_bit_for_bit() {
        let t = Rigid::from_row_major(
            &[
                0.825336, 0.0, -0.564642, 0.037267, 0.0, 1.0, 0.0, 0.0, 0.564642, 0.0, 0.825336,
                0.038325, 0.0, 0.0, 0.0, 1.0,
            ],
            1e-3,
        )
        .unwrap();
        let pair = Pair {
            name: "a".into(),
            source: "views/s/1.ply".into(),
            target: "pairs/a.ply".into(),
            ground_truth: t,
            gt_quality: "exact".into(),
            voxel: 0.06,
        };
        let text = manifest_text(&["made by a test"], std::slice::from_ref(&pair));
        assert!(text.starts_with(HEADER));
        assert!(text.contains("\n# made by a test\n"));
        let back = parse_manifest(Path::new("m.tsv"), Path::new("/base"), &text).unwrap();
        assert_eq!(back.len(), 1);
        assert_eq!(back[0].name, "a");
        assert_eq!(back[0].source, Path::new("/base/views/s/1.ply"));
        assert_eq!(back[0].ground_truth.to_rows(), t.to_rows());
        assert_eq!(
            (back[0].voxel, back[0].gt_quality.as_str()),
            (0.06, "exact")
        );
    }

    const T: &str = "1 0 0 0.5 0 1 0 0 0 0 1 0 0 0 0 1";

    #[test]
    fn parses_and_resolves() {
        let text = format!("# header\nbun\ta/s.ply\t/abs/t.ply\t{T}\texact\t0.005\n");
        let p = parse_manifest(Path::new("m.tsv"), Path::new("/data"), &text).unwrap();
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].source, Path::new("/data/a/s.ply"));
        assert_eq!(p[0].target, Path::new("/abs/t.ply"));
        assert_eq!(p[0].ground_truth.translation.x, 0.5);
        assert_eq!(p[0].voxel, 0.005);
    }

    #[test]
    fn errors_name_line_and_field() {
        let m = Path::new("m.tsv");
        let e = parse_manifest(m, Path::new("."), "a\tb\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.tsv: line 1") && e.contains("6 tab-separated"),
            "{e}"
        );
        let bad_t = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0";
        let e = parse_manifest(
            m,
            Path::new("."),
            &format!("\nx\ts\tt\t{bad_t}\texact\t1\n"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("line 2") && e.contains("field T"), "{e}");
        let e = parse_manifest(m, Path::new("."), &format!("x\ts\tt\t{T}\texact\t-1\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("suggested_voxel"), "{e}");
    }
}
