//! The PLY body: rows of ascii text or binary records, vertices and face lists.

use super::header::{Element, Header, Property, Scalar};
use crate::cloud::Point;
use crate::cloud::PointStore;
use crate::error::{GgsError, Location, Result};
use crate::io::text::{parse_lines, Row, TextChunks, ASCII_SPACE};
use std::path::Path;

/// Where face polygons are collected: the face element, its index list property, and the
/// fan-triangulated output.
pub(super) struct FaceSink {
    pub(super) element: usize,
    pub(super) property: usize,
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) polygon: Vec<u32>,
}

impl FaceSink {
    fn push_index(&mut self, path: &Path, v: f64, at: Location) -> Result<()> {
        if !(v >= 0.0 && v < u32::MAX as f64 && v.fract() == 0.0) {
            return Err(GgsError::at(
                path,
                at,
                format!("face vertex index {v} is not a valid index (expected an integer ≥ 0)"),
            ));
        }
        self.polygon.push(v as u32);
        Ok(())
    }

    fn end_polygon(&mut self) {
        for k in 1..self.polygon.len().saturating_sub(1) {
            self.triangles
                .push([self.polygon[0], self.polygon[k], self.polygon[k + 1]]);
        }
        self.polygon.clear();
    }
}

/// Read the rows of elements `0..=vi`; the scalar properties at `xyz` of element `vi` are
/// returned as points (`usize::MAX`: none), and faces go to `faces` if given.
/// One text row of `el` (line `line_no`): the values at the property indices `xyz` (as x,
/// y, z), and the face list into `faces` when that sink collects one of its properties.
pub(super) fn ascii_row(
    path: &Path,
    line_no: usize,
    raw: &[u8],
    el: &Element,
    xyz: &[usize],
    mut faces: Option<&mut FaceSink>,
) -> Result<[f64; 3]> {
    let line =
        std::str::from_utf8(raw).map_err(|_| GgsError::at_line(path, line_no, "not valid text"))?;
    let mut tok = line.split_ascii_whitespace();
    let mut next = |what: &str| -> Result<f64> {
        let t = tok.next().ok_or_else(|| {
            GgsError::at_line(path, line_no, format!("missing value for '{what}'"))
        })?;
        t.parse::<f64>().map_err(|_| {
            GgsError::at_line(path, line_no, format!("'{t}' is not a number ('{what}')"))
        })
    };
    let mut vals = [0.0f64; 3];
    for (pi, prop) in el.props.iter().enumerate() {
        match prop {
            Property::Scalar(_, name) => {
                let v = next(name)?;
                if let Some(d) = xyz.iter().position(|&x| x == pi) {
                    vals[d] = v;
                }
            }
            Property::List(_, _, name) => {
                let n = next(name)?;
                let mut sink = faces.as_deref_mut().filter(|f| f.property == pi);
                for _ in 0..(n.max(0.0) as usize) {
                    let v = next(name)?;
                    if let Some(f) = sink.as_deref_mut() {
                        f.push_index(path, v, Location::Line(line_no))?;
                    }
                }
                if let Some(f) = sink {
                    f.end_polygon();
                }
            }
        }
    }
    Ok(vals)
}

/// The non-blank lines of an ascii body, one row each, with their positions.
struct RowCursor<'a> {
    text: &'a [u8],
    /// Where the next line starts (past the end: no line left).
    pos: usize,
    /// The index of that line among all lines of `text`, from 0.
    line: usize,
}

impl<'a> RowCursor<'a> {
    /// The next non-blank line: its index among the lines, its start and its bytes.
    fn next_row(&mut self) -> Option<(usize, usize, &'a [u8])> {
        while self.pos <= self.text.len() {
            let (start, rest) = (self.pos, &self.text[self.pos..]);
            let len = memchr::memchr(b'\n', rest).unwrap_or(rest.len());
            let li = self.line;
            self.pos += len + 1;
            self.line += 1;
            let raw = &rest[..len];
            if !raw.iter().all(|&b| ASCII_SPACE.has(b)) {
                return Some((li, start, raw));
            }
        }
        None
    }

    /// Step over up to `n` rows: the byte span from where the cursor stood to the end of the
    /// last row taken (blank lines before it included), and how many rows were taken (fewer
    /// than `n` at the end of the text).
    fn span(&mut self, n: usize) -> (std::ops::Range<usize>, usize) {
        let start = self.pos.min(self.text.len());
        let (mut end, mut taken) = (start, 0);
        while taken < n {
            let Some((_, at, raw)) = self.next_row() else {
                break;
            };
            (end, taken) = (at + raw.len(), taken + 1);
        }
        (start..end, taken)
    }

    /// The `k`-th row of `el` is missing.
    fn truncated(path: &Path, el: &Element, k: usize) -> GgsError {
        GgsError::in_file(
            path,
            format!(
                "truncated: element '{}' declares {} rows, the file ends after {k}",
                el.name, el.count
            ),
        )
    }
}

/// A vertex row whose properties are all numbers, read in stride: the values at `xyz`, or
/// `None` for anything else (a missing or malformed value, a non-ascii byte), which
/// [`ascii_row`] then reads and reports.
#[inline]
fn fast_row(raw: &[u8], props: usize, xyz: &[usize]) -> Option<Point> {
    let mut row = Row::new(raw, &ASCII_SPACE);
    let mut vals = [0.0f64; 3];
    for pi in 0..props {
        let v = row.number()?;
        if let Some(d) = xyz.iter().position(|&x| x == pi) {
            vals[d] = v;
        }
    }
    row.rest().is_ascii().then_some(vals)
}

pub(super) fn read_ascii(
    path: &Path,
    bytes: &[u8],
    h: &Header,
    vi: usize,
    xyz: &[usize],
    faces: &mut Option<FaceSink>,
) -> Result<Vec<Point>> {
    let text = &bytes[h.data_start..];
    let mut rows = RowCursor {
        text,
        pos: 0,
        line: 0,
    };
    let mut out = Vec::new();
    let last = faces.as_ref().map_or(vi, |f| f.element.max(vi));
    for (ei, el) in h.elements.iter().enumerate().take(last + 1) {
        let collect_faces = faces.as_ref().is_some_and(|f| f.element == ei);
        if ei == vi && el.scalars_only() && !collect_faces {
            out = read_vertex_rows(path, h, &mut rows, el, xyz)?;
            continue;
        }
        for k in 0..el.count {
            let (li, _, raw) = rows
                .next_row()
                .ok_or_else(|| RowCursor::truncated(path, el, k))?;
            if ei != vi && !collect_faces {
                continue;
            }
            let line_no = h.lines + li + 1;
            let wanted = if ei == vi { xyz } else { &[] };
            let sink = faces.as_mut().filter(|f| f.element == ei);
            let vals = ascii_row(path, line_no, raw, el, wanted, sink)?;
            if ei == vi {
                out.push(vals);
            }
        }
    }
    Ok(out)
}

/// The points of the lines of `body` (the first is line `first_line` of the file): vertex
/// rows of `el`, blank lines skipped, read in parallel pieces ([`parse_lines`]), each row in
/// stride where it can be ([`fast_row`]), else by [`ascii_row`].
fn vertex_lines(
    path: &Path,
    body: &[u8],
    first_line: usize,
    el: &Element,
    xyz: &[usize],
) -> Result<Vec<Point>> {
    let props = el.props.len();
    parse_lines(body, first_line, |line_no, raw| {
        if raw.iter().all(|&b| ASCII_SPACE.has(b)) {
            return Ok(None);
        }
        match fast_row(raw, props, xyz) {
            Some(p) => Ok(Some(p)),
            None => ascii_row(path, line_no, raw, el, xyz, None).map(Some),
        }
    })
}

/// The rows of the vertex element `el` (scalar properties only) from where `rows` stands:
/// found line by line, then read in chunks on the thread pool ([`parse_lines`]), each row in
/// stride where it can be ([`fast_row`]), else by [`ascii_row`].
fn read_vertex_rows(
    path: &Path,
    h: &Header,
    rows: &mut RowCursor,
    el: &Element,
    xyz: &[usize],
) -> Result<Vec<Point>> {
    let first_line = rows.line;
    let (span, k) = rows.span(el.count);
    let points = vertex_lines(path, &rows.text[span], h.lines + first_line + 1, el, xyz)?;
    // A bad row before the end is reported first, as a reader going row by row finds it.
    if k < el.count {
        return Err(RowCursor::truncated(path, el, k));
    }
    Ok(points)
}

/// The vertex rows of an ascii PLY streamed from `r` (positioned at the body, byte
/// `h.data_start`), when the vertex element has scalar properties only and no face is
/// wanted: the rows of the elements before it skipped, its rows parsed chunk by chunk as
/// [`read_vertex_rows`] parses them, nothing after them read. The memory beside the points
/// is a few MB of text ([`TextChunks`]).
pub(super) fn read_ascii_streamed<S: PointStore, R: std::io::Read>(
    path: &Path,
    r: R,
    h: &Header,
    vi: usize,
    xyz: &[usize],
    file_len: Option<u64>,
) -> Result<S::Out> {
    let remaining = file_len.map(|n| n.saturating_sub(h.data_start as u64));
    // At most the rows the file's size can hold (an ascii row takes at least 6 bytes).
    let reserve = remaining.map_or(1 << 20, |n| (n / 6) as usize);
    let mut chunks = TextChunks::new(r, h.data_start as u64, h.lines + 1, remaining);
    let vertex = &h.elements[vi];
    let mut out = S::with_capacity(vertex.count.min(reserve));
    // The element being read and the rows of it read so far.
    let (mut ei, mut k) = (0, 0);
    loop {
        while ei < vi && k == h.elements[ei].count {
            (ei, k) = (ei + 1, 0);
        }
        if ei == vi && k == vertex.count {
            break;
        }
        let Some(chunk) = chunks.next_chunk(path)? else {
            return Err(RowCursor::truncated(path, &h.elements[ei], k));
        };
        let mut rows = RowCursor {
            text: chunk.bytes,
            pos: 0,
            line: 0,
        };
        // The rows of the elements before `vertex`, skipped.
        while ei < vi {
            let (_, taken) = rows.span(h.elements[ei].count - k);
            k += taken;
            if k < h.elements[ei].count {
                break;
            }
            (ei, k) = (ei + 1, 0);
        }
        if ei < vi {
            continue;
        }
        let first_line = chunk.line + rows.line;
        let (span, taken) = rows.span(vertex.count - k);
        k += taken;
        let points = vertex_lines(path, &chunk.bytes[span], first_line, vertex, xyz)?;
        out.extend_from(&points);
    }
    Ok(out.finish())
}

pub(super) fn read_binary(
    path: &Path,
    bytes: &[u8],
    h: &Header,
    vi: usize,
    xyz: &[usize],
    little: bool,
    faces: &mut Option<FaceSink>,
) -> Result<Vec<Point>> {
    let mut cur = BinaryCursor {
        path,
        bytes,
        little,
        pos: h.data_start,
    };
    let mut out = Vec::new();
    let last = faces.as_ref().map_or(vi, |f| f.element.max(vi));
    for (ei, el) in h.elements.iter().enumerate().take(last + 1) {
        if ei == vi {
            let min_row: usize = el
                .props
                .iter()
                .map(|p| match p {
                    Property::Scalar(t, _) | Property::List(t, _, _) => t.size(),
                })
                .sum();
            out.reserve(
                el.count
                    .min(bytes.len().saturating_sub(cur.pos) / min_row.max(1)),
            );
        }
        let collect_faces = faces.as_ref().is_some_and(|f| f.element == ei);
        if ei != vi && !collect_faces && cur.skip_fixed(el)? {
            continue;
        }
        for row in 0..el.count {
            let wanted = if ei == vi { xyz } else { &[] };
            let sink = faces.as_mut().filter(|f| f.element == ei);
            let vals = cur.row(el, row, wanted, sink)?;
            if ei == vi {
                out.push(vals);
            }
        }
    }
    Ok(out)
}

/// A position in the binary body of a PLY file.
pub(super) struct BinaryCursor<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    little: bool,
    pos: usize,
}

impl BinaryCursor<'_> {
    fn truncated(&self, pos: usize, el: &Element, row: usize) -> GgsError {
        GgsError::at_byte(
            self.path,
            pos as u64,
            format!(
                "truncated: element '{}' row {row} of {} runs past the end of the file ({} bytes)",
                el.name,
                el.count,
                self.bytes.len()
            ),
        )
    }

    /// Skips a whole element of fixed-size rows at once; `false` when its rows hold lists.
    fn skip_fixed(&mut self, el: &Element) -> Result<bool> {
        let fixed: Option<usize> = el
            .props
            .iter()
            .map(|p| match p {
                Property::Scalar(t, _) => Some(t.size()),
                Property::List(..) => None,
            })
            .sum();
        let Some(size) = fixed else {
            return Ok(false);
        };
        let len = size
            .checked_mul(el.count)
            .filter(|&l| self.pos + l <= self.bytes.len())
            .ok_or_else(|| self.truncated(self.pos, el, 0))?;
        self.pos += len;
        Ok(true)
    }

    /// Reads row `row` of `el`: the scalars at the property indices `xyz` (as x, y, z), and
    /// the face list into `faces` when that sink collects one of its properties.
    fn row(
        &mut self,
        el: &Element,
        row: usize,
        xyz: &[usize],
        mut faces: Option<&mut FaceSink>,
    ) -> Result<[f64; 3]> {
        let mut vals = [0.0f64; 3];
        for (pi, prop) in el.props.iter().enumerate() {
            match prop {
                Property::Scalar(t, _) => {
                    let s = t.size();
                    let b = self
                        .bytes
                        .get(self.pos..self.pos + s)
                        .ok_or_else(|| self.truncated(self.pos, el, row))?;
                    if let Some(d) = xyz.iter().position(|&x| x == pi) {
                        vals[d] = t.decode(b, self.little);
                    }
                    self.pos += s;
                }
                Property::List(ct, it, _) => {
                    let sink = faces.as_deref_mut().filter(|f| f.property == pi);
                    self.list(el, row, *ct, *it, sink)?;
                }
            }
        }
        Ok(vals)
    }

    /// Reads one list (its count, then its items), pushing the items into `faces` if given.
    fn list(
        &mut self,
        el: &Element,
        row: usize,
        count_type: Scalar,
        item_type: Scalar,
        faces: Option<&mut FaceSink>,
    ) -> Result<()> {
        let s = count_type.size();
        let b = self
            .bytes
            .get(self.pos..self.pos + s)
            .ok_or_else(|| self.truncated(self.pos, el, row))?;
        let n = count_type.decode(b, self.little);
        if !(0.0..=1e9).contains(&n) {
            return Err(GgsError::at_byte(
                self.path,
                self.pos as u64,
                format!("invalid list length {n}"),
            ));
        }
        let start = self.pos + s;
        self.pos = start + n as usize * item_type.size();
        if self.pos > self.bytes.len() {
            return Err(self.truncated(start, el, row));
        }
        if let Some(f) = faces {
            for k in 0..n as usize {
                let at = start + k * item_type.size();
                let v = item_type.decode(&self.bytes[at..at + item_type.size()], self.little);
                f.push_index(self.path, v, Location::Byte(at as u64))?;
            }
            f.end_polygon();
        }
        Ok(())
    }
}
