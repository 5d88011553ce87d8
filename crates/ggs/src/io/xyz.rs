//! Delimited text point clouds: `.xyz`, `.txt`, `.csv`, `.pts`.
//!
//! Values are separated by commas, semicolons or whitespace (mixed is fine: `1 , 2 , 3`).
//! A first line whose leading values are not all numbers is a header: if it names columns
//! `x`, `y`, `z` (any case) those are read, otherwise the first three. A `.pts` first line
//! holding a single integer (the point count) is skipped. Lines starting with `#` or `//`
//! and blank lines are ignored.

use crate::cloud::{Point, PointStore};
use crate::error::{GgsError, Result};
use crate::io::text::{xyz_columns, SPACE, SPACE_COMMA_SEMICOLON};
use std::path::Path;

fn split(line: &str) -> impl Iterator<Item = &str> {
    line.split(|c: char| c == ',' || c == ';' || c.is_whitespace())
        .filter(|t| !t.is_empty())
}

/// Write points as text, one `x y z` line each, in the shortest form that reads back to the
/// same f64 values, atomically.
pub fn write_xyz(path: &Path, points: &[Point]) -> Result<()> {
    use std::fmt::Write as _;
    let mut out = String::with_capacity(points.len() * 40);
    for p in points {
        let _ = writeln!(out, "{} {} {}", p[0], p[1], p[2]);
    }
    super::write_atomic(path, out.as_bytes())
}

/// Read points from delimited text (see [`read_xyz_into`]).
pub fn parse_xyz(path: &Path, bytes: &[u8]) -> Result<Vec<Point>> {
    read_xyz_into::<Vec<Point>, _>(path, bytes, Some(bytes.len() as u64))
}

/// Read points from delimited text, streamed: the text is read a few MB at a time in whole
/// lines ([`crate::io::text::TextChunks`]), each chunk checked as UTF-8, then its lines from
/// the first point on (after a header or a `.pts` count) read in parallel chunks, each in
/// stride where it can be ([`crate::io::text::xyz_columns`]) and by the general line reader
/// otherwise. The error is the first in file order (of a chunk's lines, a UTF-8 error first).
/// `len`: the file's size, when known.
pub fn read_xyz_into<S: PointStore, R: std::io::Read>(
    path: &Path,
    r: R,
    len: Option<u64>,
) -> Result<S::Out> {
    let mut chunks = crate::io::text::TextChunks::new(r, 0, 1, len);
    let mut out = S::with_capacity(0);
    // The columns, once the first meaningful line has said where they are.
    let mut cols: Option<[usize; 3]> = None;
    while let Some(chunk) = chunks.next_chunk(path)? {
        let text = std::str::from_utf8(chunk.bytes).map_err(|e| {
            GgsError::at_byte(
                path,
                chunk.offset + e.valid_up_to() as u64,
                "not valid UTF-8 text",
            )
        })?;
        let (body, first_line, c) = match cols {
            Some(c) => (chunk.bytes, chunk.line, c),
            None => match header(path, text, chunk.line)? {
                Some((at, line, c)) => (&chunk.bytes[at..], line, c),
                None => continue,
            },
        };
        cols = Some(c);
        let points = crate::io::text::parse_lines(body, first_line, |line_no, raw| {
            let first = raw.iter().find(|&&b| !SPACE.has(b));
            let comment = matches!(first, Some(b'#' | b'/'));
            match (!comment)
                .then(|| xyz_columns(raw, &c, &SPACE_COMMA_SEMICOLON))
                .flatten()
            {
                Some(p) => Ok(Some(p)),
                None => {
                    let line = std::str::from_utf8(raw).expect("checked above");
                    data_line(path, line_no, line.trim(), &c)
                }
            }
        })?;
        out.extend_from(&points);
    }
    Ok(out.finish())
}

/// The first meaningful line of `text` (whose first line is line `line0` of the file): a
/// header naming `x y z` (their columns), another header or a `.pts` count (the first
/// three columns), or the first point. `Some((byte, line, columns))`: where the points
/// start; `None` when `text` holds no meaningful line.
fn header(path: &Path, text: &str, line0: usize) -> Result<Option<(usize, usize, [usize; 3])>> {
    for (i, line) in text.split('\n').enumerate() {
        let line_no = line0 + i;
        let t = line.trim();
        if skipped(t) {
            continue;
        }
        let at = line.as_ptr() as usize - text.as_ptr() as usize;
        let after = (at + line.len() + 1).min(text.len());
        let toks: Vec<&str> = split(t).collect();
        if toks.len() == 1 && toks[0].parse::<u64>().is_ok() {
            return Ok(Some((after, line_no + 1, [0, 1, 2]))); // .pts point count
        }
        let numeric = toks.len() >= 3 && toks[..3].iter().all(|s| s.parse::<f64>().is_ok());
        if numeric {
            return Ok(Some((at, line_no, [0, 1, 2])));
        }
        let lower: Vec<String> = toks
            .iter()
            .map(|s| s.trim_matches('"').to_ascii_lowercase())
            .collect();
        let find = |n: &str| lower.iter().position(|s| s == n);
        if let (Some(x), Some(y), Some(z)) = (find("x"), find("y"), find("z")) {
            return Ok(Some((after, line_no + 1, [x, y, z])));
        } else if toks.len() < 3 {
            return Err(GgsError::at_line(
                path,
                line_no,
                format!("expected at least 3 values (x y z), found {}", toks.len()),
            ));
        }
        return Ok(Some((after, line_no + 1, [0, 1, 2])));
    }
    Ok(None)
}

/// Whether a trimmed line holds no point: blank, or a `#` or `//` comment.
fn skipped(t: &str) -> bool {
    t.is_empty() || t.starts_with('#') || t.starts_with("//")
}

/// The point on trimmed line `t` (line `line_no`), its columns `cols`; `None` for a line
/// that holds none ([`skipped`]).
fn data_line(path: &Path, line_no: usize, t: &str, cols: &[usize; 3]) -> Result<Option<Point>> {
    if skipped(t) {
        return Ok(None);
    }
    let toks: Vec<&str> = split(t).collect();
    let expected =
        |col: usize, n: usize| format!("expected at least {} values, found {n}", col + 1);
    crate::io::text::token_columns(path, line_no, &toks, cols, expected).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: &str = "t.csv";

    #[test]
    fn header_with_commas_and_spaces() {
        let s = "x,y,z,nx,ny,nz\n-3.5 , 0.6 , -1.3 , 0,0,1\n1,2,3,0,0,1\n";
        assert_eq!(
            parse_xyz(Path::new(P), s.as_bytes()).unwrap(),
            vec![[-3.5, 0.6, -1.3], [1.0, 2.0, 3.0]]
        );
    }

    #[test]
    fn header_with_reordered_columns() {
        let s = "intensity z y x\n9 3 2 1\n";
        assert_eq!(
            parse_xyz(Path::new(P), s.as_bytes()).unwrap(),
            vec![[1.0, 2.0, 3.0]]
        );
    }

    #[test]
    fn headerless_whitespace_and_pts_count() {
        let s = "2\n   2.6e+00   5.2e-02  -1.0e+00\n1 2 3 4\n";
        assert_eq!(
            parse_xyz(Path::new("a.pts"), s.as_bytes()).unwrap(),
            vec![[2.6, 0.052, -1.0], [1.0, 2.0, 3.0]]
        );
    }

    #[test]
    fn comments_blank_lines_and_crlf_between_points_with_named_columns() {
        let s = "id;x;y;z\r\n# 1;2;3;4\r\n\r\n7;1;2;3\r\n  // 5 6 7 8\n8 ,4, 5 ,6\n";
        let points = parse_xyz(Path::new(P), s.as_bytes()).unwrap();
        assert_eq!(points, [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    }

    /// A body large enough to be read in several chunks reads as the lines say, and an error
    /// deep in it names its line.
    #[test]
    fn a_large_body_reads_in_order_and_names_a_bad_line() {
        let mut s = String::from("x y z\n");
        let mut want = Vec::new();
        for i in 0..150_000 {
            let p = [i as f64 / 7.0, -(i as f64) * 1e-3, 0.5];
            s.push_str(&format!("{} {} {}\n", p[0], p[1], p[2]));
            if i % 1000 == 0 {
                s.push_str("# a comment\n\n");
            }
            want.push(p);
        }
        assert!(s.len() > 4 * crate::io::text::CHUNK_BYTES);
        assert_eq!(parse_xyz(Path::new(P), s.as_bytes()).unwrap(), want);
        let lines: Vec<&str> = s.lines().collect();
        let bad = 120_000;
        let mut broken = lines.clone();
        broken[bad] = "1 2 oops";
        let e = parse_xyz(Path::new(P), broken.join("\n").as_bytes()).unwrap_err();
        assert_eq!(e.location(), Some(crate::error::Location::Line(bad + 1)));
        assert!(e.to_string().contains("'oops' is not a number"), "{e}");
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse_xyz(Path::new(P), b"1 2 3\n4 5\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("t.csv"), "{e}");
        let e = parse_xyz(Path::new(P), b"1 2 3\n4 5 zz\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("'zz'"), "{e}");
        let e = parse_xyz(Path::new(P), b"a b\n").unwrap_err().to_string();
        assert!(e.contains("line 1"), "{e}");
    }
}

/// One unit test per error path.
#[cfg(test)]
mod error_paths {
    use super::*;
    use crate::error::Location::{Byte, Line};

    error_cases! { parse_xyz;
        not_utf8: b"1 2 3\n4 5 \xff\n" => Byte(10), "not valid UTF-8";
        header_too_short: b"# comment\nx y\n1 2 3\n" => Line(2), "expected at least 3 values (x y z), found 2";
        row_too_short: b"1 2 3\n4 5\n" => Line(2), "expected at least 3 values, found 2";
        named_column_missing: b"a,x,y,z\n1,2,3,4\n5,6,7\n" => Line(3), "expected at least 4 values, found 3";
        not_a_number: b"1 2 3\n4 five 6\n" => Line(2), "'five' is not a number";
    }
}
