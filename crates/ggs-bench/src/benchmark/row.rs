//! One pair's benchmark result and the resumable per-pair CSV.
//!
//! Each finished pair is appended to `pairs.csv` as one line and flushed to disk, so a crash
//! or Ctrl-C loses at most the pair in progress. On a restart the complete lines are read
//! back (a torn last line is dropped), those pairs are skipped, and the run continues. Floats
//! are written in Rust's shortest round-trip form, so a row read back is bit-identical to the
//! row written, and a resumed run ends with the same file as an uninterrupted one (except the
//! `*_ms` timing columns).

use ggs::error::{GgsError, Result};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The result of one pair. Angles in degrees, distances in the clouds' units, times in ms.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PairRow {
    pub id: String,
    /// The protocol's overlap of the pair (fraction), if it has one.
    pub overlap: Option<f64>,
    pub source_points: usize,
    pub target_points: usize,
    pub voxel: f64,
    /// Final errors (after refinement, if any) against the ground truth.
    pub rre: f64,
    pub rte: f64,
    /// `rre < max_rre_deg && rte < max_rte`, false for a pair that failed to run.
    pub success: bool,
    pub max_rre_deg: f64,
    pub max_rte: f64,
    /// Errors of the grid search alone.
    pub coarse_rre: f64,
    pub coarse_rte: f64,
    /// Score `Σ S_pad·K` of the coarse pick and the ambiguity ratio.
    pub score: i64,
    pub ambiguity: Option<f64>,
    /// Quality report of the refinement (absent with `--refine none`).
    pub fitness_source: Option<f64>,
    pub fitness_target: Option<f64>,
    pub inlier_rmse: Option<f64>,
    pub iterations: Option<usize>,
    pub converged: Option<bool>,
    pub degenerate: Option<bool>,
    /// Rank of the chosen coarse hypothesis (0: the coarse winner) and how many were verified
    /// (absent without verification).
    pub chosen_rank: Option<usize>,
    pub verified: Option<usize>,
    /// Coarse rank of the first hypothesis whose pose meets the success thresholds
    /// ([`super::right_pose_rank`]; absent: none did): why a failed pair failed.
    pub right_rank: Option<usize>,
    /// The pipeline's confidence in [0, 1] and its ambiguity flag.
    pub confidence: f64,
    pub ambiguous: bool,
    /// Verification score of the chosen pose and of the best distinct runner-up.
    pub verify_score: Option<f64>,
    pub runner_up_score: Option<f64>,
    /// Whether the first look settled the pair (true) or the whole search ran (false); absent
    /// where it did not run.
    pub first_look: Option<bool>,
    /// The estimate, 16 numbers row-major (empty when the pair failed).
    pub transform: Vec<f64>,
    pub read_ms: f64,
    pub coarse_ms: f64,
    pub verify_ms: f64,
    pub refine_ms: f64,
    pub total_ms: f64,
    /// Why the pair could not be registered.
    pub error: Option<String>,
    /// The registration's warnings, joined by `" | "` (empty: none).
    pub warnings: String,
}

/// Column names, in file order.
pub const COLUMNS: [&str; N] = [
    "id",
    "overlap",
    "source_points",
    "target_points",
    "voxel",
    "rre",
    "rte",
    "success",
    "max_rre_deg",
    "max_rte",
    "coarse_rre",
    "coarse_rte",
    "score",
    "ambiguity",
    "fitness_source",
    "fitness_target",
    "inlier_rmse",
    "iterations",
    "converged",
    "degenerate",
    "chosen_rank",
    "verified",
    "right_rank",
    "confidence",
    "ambiguous",
    "verify_score",
    "runner_up_score",
    "first_look",
    "transform",
    "read_ms",
    "coarse_ms",
    "verify_ms",
    "refine_ms",
    "total_ms",
    "error",
    "warnings",
];

/// The number of columns.
const N: usize = 36;

impl PairRow {
    /// An empty row for a pair (errors NaN until measured).
    pub fn new(id: &str, overlap: Option<f64>) -> Self {
        PairRow {
            id: id.to_string(),
            overlap,
            source_points: 0,
            target_points: 0,
            voxel: f64::NAN,
            rre: f64::NAN,
            rte: f64::NAN,
            success: false,
            max_rre_deg: f64::NAN,
            max_rte: f64::NAN,
            coarse_rre: f64::NAN,
            coarse_rte: f64::NAN,
            score: 0,
            ambiguity: None,
            fitness_source: None,
            fitness_target: None,
            inlier_rmse: None,
            iterations: None,
            converged: None,
            degenerate: None,
            chosen_rank: None,
            verified: None,
            right_rank: None,
            confidence: f64::NAN,
            ambiguous: false,
            verify_score: None,
            runner_up_score: None,
            first_look: None,
            transform: Vec::new(),
            read_ms: 0.0,
            coarse_ms: 0.0,
            verify_ms: 0.0,
            refine_ms: 0.0,
            total_ms: 0.0,
            error: None,
            warnings: String::new(),
        }
    }

    /// The CSV line (no newline).
    pub fn to_csv(&self) -> String {
        fn opt<T: ToString>(v: &Option<T>) -> String {
            v.as_ref().map_or(String::new(), T::to_string)
        }
        let fields: [String; N] = [
            self.id.clone(),
            opt(&self.overlap),
            self.source_points.to_string(),
            self.target_points.to_string(),
            self.voxel.to_string(),
            self.rre.to_string(),
            self.rte.to_string(),
            self.success.to_string(),
            self.max_rre_deg.to_string(),
            self.max_rte.to_string(),
            self.coarse_rre.to_string(),
            self.coarse_rte.to_string(),
            self.score.to_string(),
            opt(&self.ambiguity),
            opt(&self.fitness_source),
            opt(&self.fitness_target),
            opt(&self.inlier_rmse),
            opt(&self.iterations),
            opt(&self.converged),
            opt(&self.degenerate),
            opt(&self.chosen_rank),
            opt(&self.verified),
            opt(&self.right_rank),
            self.confidence.to_string(),
            self.ambiguous.to_string(),
            opt(&self.verify_score),
            opt(&self.runner_up_score),
            opt(&self.first_look),
            self.transform
                .iter()
                .map(f64::to_string)
                .collect::<Vec<_>>()
                .join(" "),
            self.read_ms.to_string(),
            self.coarse_ms.to_string(),
            self.verify_ms.to_string(),
            self.refine_ms.to_string(),
            self.total_ms.to_string(),
            // One line per row, whatever the message.
            opt(&self.error).replace(['\n', '\r'], " "),
            self.warnings.replace(['\n', '\r'], " "),
        ];
        fields
            .iter()
            .map(|f| quote(f))
            .collect::<Vec<_>>()
            .join(",")
    }

    /// Parse a line written by [`Self::to_csv`]; the error says which column is wrong.
    pub fn from_csv(line: &str) -> std::result::Result<Self, String> {
        let f = split_csv(line)?;
        if f.len() != N {
            return Err(format!("expected {N} columns, found {}", f.len()));
        }
        fn p<T: std::str::FromStr>(f: &[String], k: usize) -> std::result::Result<T, String> {
            f[k].parse()
                .map_err(|_| format!("column '{}': cannot read '{}'", COLUMNS[k], f[k]))
        }
        fn o<T: std::str::FromStr>(
            f: &[String],
            k: usize,
        ) -> std::result::Result<Option<T>, String> {
            if f[k].is_empty() {
                Ok(None)
            } else {
                p(f, k).map(Some)
            }
        }
        const TRANSFORM: usize = 28;
        let transform = if f[TRANSFORM].is_empty() {
            Vec::new()
        } else {
            f[TRANSFORM]
                .split(' ')
                .map(|s| s.parse::<f64>())
                .collect::<std::result::Result<Vec<_>, _>>()
                .map_err(|_| format!("column 'transform': cannot read '{}'", f[TRANSFORM]))?
        };
        Ok(PairRow {
            id: f[0].clone(),
            overlap: o(&f, 1)?,
            source_points: p(&f, 2)?,
            target_points: p(&f, 3)?,
            voxel: p(&f, 4)?,
            rre: p(&f, 5)?,
            rte: p(&f, 6)?,
            success: p(&f, 7)?,
            max_rre_deg: p(&f, 8)?,
            max_rte: p(&f, 9)?,
            coarse_rre: p(&f, 10)?,
            coarse_rte: p(&f, 11)?,
            score: p(&f, 12)?,
            ambiguity: o(&f, 13)?,
            fitness_source: o(&f, 14)?,
            fitness_target: o(&f, 15)?,
            inlier_rmse: o(&f, 16)?,
            iterations: o(&f, 17)?,
            converged: o(&f, 18)?,
            degenerate: o(&f, 19)?,
            chosen_rank: o(&f, 20)?,
            verified: o(&f, 21)?,
            right_rank: o(&f, 22)?,
            confidence: p(&f, 23)?,
            ambiguous: p(&f, 24)?,
            verify_score: o(&f, 25)?,
            runner_up_score: o(&f, 26)?,
            first_look: o(&f, 27)?,
            transform,
            read_ms: p(&f, 29)?,
            coarse_ms: p(&f, 30)?,
            verify_ms: p(&f, 31)?,
            refine_ms: p(&f, 32)?,
            total_ms: p(&f, 33)?,
            error: o(&f, 34)?,
            warnings: f[35].clone(),
        })
    }
}

impl PairRow {
    /// Whether the result says it may be wrong: ambiguous, warned, or no result at all.
    pub fn flagged(&self) -> bool {
        self.ambiguous || !self.warnings.is_empty() || self.error.is_some()
    }
}

/// The header line.
pub fn header() -> String {
    COLUMNS.join(",")
}

fn quote(s: &str) -> String {
    if s.contains([',', '"']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Split one CSV line (fields optionally quoted, `""` inside quotes).
fn split_csv(line: &str) -> std::result::Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    while let Some(c) = chars.next() {
        match (quoted, c) {
            (true, '"') if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            (true, '"') => quoted = false,
            (false, '"') if cur.is_empty() => quoted = true,
            (false, ',') => out.push(std::mem::take(&mut cur)),
            _ => cur.push(c),
        }
    }
    if quoted {
        return Err("unterminated quoted field".into());
    }
    out.push(cur);
    Ok(out)
}

/// The rows of a results file's complete lines, and those lines (a torn last line dropped).
fn parse<'a>(path: &Path, text: &'a str) -> Result<(Vec<PairRow>, &'a str)> {
    let complete = match text.rfind('\n') {
        Some(end) => &text[..=end],
        None => "",
    };
    let mut lines = complete.lines();
    if lines.next() != Some(header().as_str()) {
        return Err(GgsError::at_line(
            path,
            1,
            "not a ggs results file of this version (header differs): choose another --out",
        ));
    }
    let mut rows = Vec::new();
    for (k, line) in lines.enumerate() {
        rows.push(PairRow::from_csv(line).map_err(|m| GgsError::at_line(path, k + 2, m))?);
    }
    Ok((rows, complete))
}

/// The per-pair CSV of a run, open for appending.
pub struct ResultsCsv {
    path: PathBuf,
    file: File,
}

impl ResultsCsv {
    /// Open `path`, creating it with a header, or resume it: the rows of its complete
    /// lines are returned (a torn last line, from a crash mid-write, is dropped from the
    /// file). A file that is not a ggs results CSV is an error, never overwritten.
    pub fn open(path: &Path) -> Result<(ResultsCsv, Vec<PairRow>)> {
        let rows = match std::fs::read_to_string(path) {
            Ok(text) => {
                let (rows, complete) = parse(path, &text)?;
                if complete.len() != text.len() {
                    ggs::io::write_atomic(path, complete.as_bytes())?;
                }
                rows
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                ggs::io::write_atomic(path, format!("{}\n", header()).as_bytes())?;
                Vec::new()
            }
            Err(e) => return Err(GgsError::io(path, e)),
        };
        let file = OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(|e| GgsError::io(path, e))?;
        Ok((
            ResultsCsv {
                path: path.to_path_buf(),
                file,
            },
            rows,
        ))
    }

    /// The rows of the complete lines of `path`, which is left as it is.
    pub fn read(path: &Path) -> Result<Vec<PairRow>> {
        let text = std::fs::read_to_string(path).map_err(|e| GgsError::io(path, e))?;
        Ok(parse(path, &text)?.0)
    }

    /// Append one row and flush it to disk.
    pub fn append(&mut self, row: &PairRow) -> Result<()> {
        let line = format!("{}\n", row.to_csv());
        self.file
            .write_all(line.as_bytes())
            .and_then(|_| self.file.sync_data())
            .map_err(|e| GgsError::io(&self.path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> PairRow {
        let mut r = PairRow::new("scene, \"a\"/0_1", Some(0.42));
        r.voxel = 0.06;
        r.rre = 1.0 / 3.0;
        r.rte = 0.1 + 0.2;
        r.success = true;
        r.max_rre_deg = 15.0;
        r.max_rte = 0.3;
        r.coarse_rre = 8.5;
        r.coarse_rte = 0.25;
        r.score = -12345;
        r.ambiguity = Some(0.66);
        r.fitness_source = Some(0.9);
        r.iterations = Some(7);
        r.converged = Some(true);
        r.chosen_rank = Some(2);
        r.verified = Some(4);
        r.confidence = 0.25;
        r.ambiguous = true;
        r.verify_score = Some(0.5);
        r.runner_up_score = Some(0.375);
        r.first_look = Some(true);
        r.transform = (0..16).map(|k| k as f64 / 7.0).collect();
        r.total_ms = 12.5;
        r.error = Some("line one\nline two".into());
        r.warnings = "ambiguous: a pose 90° away, verifies at 0.5 | free space: 4.0 %".into();
        r
    }

    #[test]
    fn rows_round_trip_bit_for_bit() {
        let r = sample();
        let back = PairRow::from_csv(&r.to_csv()).unwrap();
        let mut want = r.clone();
        want.error = Some("line one line two".into());
        assert_eq!(back, want);
        assert_eq!(back.rte.to_bits(), r.rte.to_bits());
        let e = PairRow::from_csv(&r.to_csv().replacen("0.06", "x", 1)).unwrap_err();
        assert!(e.contains("column 'voxel'"), "{e}");
    }

    #[test]
    fn resume_drops_a_torn_line_and_refuses_foreign_files() {
        let dir = std::env::temp_dir().join(format!("ggs-rows-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("pairs.csv");
        let _ = std::fs::remove_file(&path);
        let (mut f, rows) = ResultsCsv::open(&path).unwrap();
        assert!(rows.is_empty());
        f.append(&sample()).unwrap();
        drop(f);
        // A crash mid-write leaves half a line.
        let mut text = std::fs::read_to_string(&path).unwrap();
        text.push_str("half,a,li");
        std::fs::write(&path, &text).unwrap();
        let (_, rows) = ResultsCsv::open(&path).unwrap();
        assert_eq!(rows.len(), 1);
        assert!(!std::fs::read_to_string(&path).unwrap().contains("half"));
        std::fs::write(&path, "x,y\n1,2\n").unwrap();
        let e = ResultsCsv::open(&path).err().unwrap().to_string();
        assert!(e.contains("not a ggs results file"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
