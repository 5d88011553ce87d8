//! PLY point clouds: ascii, binary little endian and binary big endian; any scalar property
//! types and order; extra elements (`range_grid`, faces, …), `comment` and `obj_info` lines
//! are skipped. Only the `vertex` element's `x`, `y`, `z` are read.

use super::{stream, write_atomic};
use crate::cloud::Point;
use crate::error::{GgsError, Location, Result};
use std::io::BufRead;
use std::path::Path;

/// The longest header accepted (comments included).
const MAX_HEADER_BYTES: usize = 16 << 20;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// Decode one value from the first `self.size()` bytes of `b`.
    #[inline(always)]
    fn decode(self, b: &[u8], little: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("caller passes enough bytes");
                if little {
                    <$t>::from_le_bytes(a)
                } else {
                    <$t>::from_be_bytes(a)
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2) as f64,
            Scalar::U16 => get!(u16, 2) as f64,
            Scalar::I32 => get!(i32, 4) as f64,
            Scalar::U32 => get!(u32, 4) as f64,
            Scalar::F32 => get!(f32, 4) as f64,
            Scalar::F64 => get!(f64, 8),
        }
    }
}

#[derive(Debug, Clone)]
enum Property {
    Scalar(Scalar, String),
    List(Scalar, Scalar, String),
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    BinaryLe,
    BinaryBe,
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the first data byte.
    data_start: usize,
    /// Number of header lines (so ascii data line numbers can be reported).
    lines: usize,
}

/// The encoding named by a `format` line.
fn parse_format(path: &Path, line_no: usize, word: Option<&str>) -> Result<Encoding> {
    match word {
        Some("ascii") => Ok(Encoding::Ascii),
        Some("binary_little_endian") => Ok(Encoding::BinaryLe),
        Some("binary_big_endian") => Ok(Encoding::BinaryBe),
        other => Err(GgsError::at_line(
            path,
            line_no,
            format!("unknown format {other:?} (expected ascii, binary_little_endian or binary_big_endian)"),
        )),
    }
}

/// The rest of a `property` line: `TYPE NAME` or `list COUNT_TYPE ITEM_TYPE NAME`.
fn parse_property<'a>(
    path: &Path,
    line_no: usize,
    tok: &mut impl Iterator<Item = &'a str>,
) -> Result<Property> {
    let t = tok.next().unwrap_or("");
    if t == "list" {
        let ct = tok.next().and_then(Scalar::parse);
        let it = tok.next().and_then(Scalar::parse);
        return match (ct, it, tok.next()) {
            (Some(c), Some(i), Some(n)) => Ok(Property::List(c, i, n.to_string())),
            _ => Err(GgsError::at_line(
                path,
                line_no,
                "expected 'property list COUNT_TYPE ITEM_TYPE NAME'",
            )),
        };
    }
    let ty = Scalar::parse(t)
        .ok_or_else(|| GgsError::at_line(path, line_no, format!("unknown property type '{t}'")))?;
    let name = tok
        .next()
        .ok_or_else(|| GgsError::at_line(path, line_no, "property without a name"))?;
    Ok(Property::Scalar(ty, name.to_string()))
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(GgsError::at_line(
                path,
                line_no + 1,
                "the header ends before 'end_header'",
            ));
        };
        let raw = &bytes[pos..pos + nl];
        pos += nl + 1;
        line_no += 1;
        let line = String::from_utf8_lossy(raw);
        let line = line.trim();
        let mut tok = line.split_whitespace();
        let key = tok.next().unwrap_or("");
        if line_no == 1 {
            if key != "ply" {
                return Err(GgsError::at_line(path, 1, "expected 'ply' magic line"));
            }
            continue;
        }
        match key {
            "format" => encoding = Some(parse_format(path, line_no, tok.next())?),
            "element" => {
                let name = tok.next().unwrap_or("").to_string();
                let count = tok
                    .next()
                    .and_then(|c| c.parse::<usize>().ok())
                    .ok_or_else(|| {
                        GgsError::at_line(path, line_no, "expected 'element NAME COUNT'")
                    })?;
                elements.push(Element {
                    name,
                    count,
                    props: Vec::new(),
                });
            }
            "property" => {
                let el = elements.last_mut().ok_or_else(|| {
                    GgsError::at_line(path, line_no, "'property' before any 'element'")
                })?;
                el.props.push(parse_property(path, line_no, &mut tok)?);
            }
            "end_header" => break,
            // comment, obj_info and anything unknown: skipped.
            _ => {}
        }
    }
    let encoding =
        encoding.ok_or_else(|| GgsError::in_file(path, "the header has no 'format' line"))?;
    Ok(Header {
        encoding,
        elements,
        data_start: pos,
        lines: line_no,
    })
}

/// Read the vertices of a PLY file from a stream positioned at its first byte; `file_len`
/// (when known) bounds what an overstated count may reserve.
///
/// Binary files whose elements up to `vertex` have fixed-size rows (no lists: the usual
/// case) are streamed: the elements before `vertex` are skipped, the vertex rows decoded
/// [`stream::CHUNK_BYTES`] at a time and the elements after it never read, so the memory
/// beside the output is one chunk. Ascii files and rows with lists are read whole, then
/// parsed by [`parse_ply`].
pub fn read_ply<R: BufRead + Send>(
    path: &Path,
    r: &mut R,
    file_len: Option<u64>,
) -> Result<Vec<Point>> {
    read_ply_chunked(path, r, file_len, stream::CHUNK_BYTES)
}

fn read_ply_chunked<R: BufRead + Send>(
    path: &Path,
    r: &mut R,
    file_len: Option<u64>,
    chunk_bytes: usize,
) -> Result<Vec<Point>> {
    // Refuse a file that is not PLY at its first line, before looking for 'end_header'.
    let head = r.fill_buf().map_err(|e| GgsError::io(path, e))?;
    let first = head.split(|&b| b == b'\n').next().unwrap_or(&[]);
    let whole_line = first.len() < head.len() || head.len() >= 64;
    if whole_line && String::from_utf8_lossy(first).split_whitespace().next() != Some("ply") {
        return Err(GgsError::at_line(path, 1, "expected 'ply' magic line"));
    }
    let mut header = stream::read_header(path, r, MAX_HEADER_BYTES, "'end_header'", |l| {
        l.split_whitespace().next() == Some("end_header")
    })?;
    let h = parse_header(path, &header)?;
    let vi = vertex_element(path, &h)?;
    let row_size = |e: &Element| -> Option<usize> {
        e.props
            .iter()
            .map(|p| match p {
                Property::Scalar(t, _) => Some(t.size()),
                Property::List(..) => None,
            })
            .sum()
    };
    let fixed =
        h.encoding != Encoding::Ascii && h.elements[..=vi].iter().all(|e| row_size(e).is_some());
    if !fixed {
        r.read_to_end(&mut header)
            .map_err(|e| GgsError::io(path, e))?;
        return parse_ply(path, &header);
    }
    let mut pos = h.data_start as u64;
    for e in &h.elements[..vi] {
        let len = (row_size(e).unwrap_or(0) as u64)
            .checked_mul(e.count as u64)
            .ok_or_else(|| {
                GgsError::at_byte(
                    path,
                    pos,
                    format!(
                        "element '{}': {} rows overflow the file size",
                        e.name, e.count
                    ),
                )
            })?;
        stream::skip(path, r, pos, len, &format!("element '{}'", e.name))?;
        pos += len;
    }
    let el = &h.elements[vi];
    let stride = row_size(el).unwrap_or(0);
    let xyz = xyz_properties(path, &h, vi)?;
    let mut offsets = [(0usize, Scalar::F32); 3];
    for (d, &pi) in xyz.iter().enumerate() {
        let off: usize = el.props[..pi]
            .iter()
            .map(|p| match p {
                Property::Scalar(t, _) | Property::List(t, _, _) => t.size(),
            })
            .sum();
        if let Property::Scalar(t, _) = el.props[pi] {
            offsets[d] = (off, t);
        }
    }
    let little = h.encoding == Encoding::BinaryLe;
    let room = file_len.map_or(1 << 20, |l| l.saturating_sub(pos) / stride.max(1) as u64);
    let (n, what) = (el.count as u64, "element 'vertex'");
    let at = offsets.map(|(o, _)| o);
    // The common layouts get a decoder without a per-value type dispatch.
    if little && offsets.iter().all(|&(_, t)| t == Scalar::F32) {
        let f = move |rec: &[u8]| at.map(|o| f32_le(&rec[o..o + 4]));
        stream::read_records(path, r, pos, stride, n, what, chunk_bytes, f, room)
    } else if little && offsets.iter().all(|&(_, t)| t == Scalar::F64) {
        let f = move |rec: &[u8]| at.map(|o| f64_le(&rec[o..o + 8]));
        stream::read_records(path, r, pos, stride, n, what, chunk_bytes, f, room)
    } else {
        let f = |rec: &[u8]| offsets.map(|(o, t)| t.decode(&rec[o..], little));
        stream::read_records(path, r, pos, stride, n, what, chunk_bytes, f, room)
    }
}

/// A little-endian f32 from 4 bytes, as f64.
#[inline(always)]
pub(crate) fn f32_le(b: &[u8]) -> f64 {
    f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64
}

/// A little-endian f64 from 8 bytes.
#[inline(always)]
pub(crate) fn f64_le(b: &[u8]) -> f64 {
    f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
}

/// Read the vertices of a PLY file held in memory.
pub fn parse_ply(path: &Path, bytes: &[u8]) -> Result<Vec<Point>> {
    let h = parse_header(path, bytes)?;
    read_vertices(path, bytes, &h, &mut None)
}

/// One pass over the data: the vertex element's `x y z`, and the faces if `faces` asks.
fn read_vertices(
    path: &Path,
    bytes: &[u8],
    h: &Header,
    faces: &mut Option<FaceSink>,
) -> Result<Vec<Point>> {
    let vi = vertex_element(path, h)?;
    let xyz = xyz_properties(path, h, vi)?;
    match h.encoding {
        Encoding::Ascii => read_ascii(path, bytes, h, vi, &xyz, faces),
        Encoding::BinaryLe => read_binary(path, bytes, h, vi, &xyz, true, faces),
        Encoding::BinaryBe => read_binary(path, bytes, h, vi, &xyz, false, faces),
    }
}

fn vertex_element(path: &Path, h: &Header) -> Result<usize> {
    h.elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| GgsError::in_file(path, "no 'vertex' element in the header"))
}

/// Indices of the vertex element's scalar properties `x`, `y`, `z`.
fn xyz_properties(path: &Path, h: &Header, vi: usize) -> Result<[usize; 3]> {
    let find = |n: &str| {
        h.elements[vi]
            .props
            .iter()
            .position(|p| matches!(p, Property::Scalar(_, name) if name == n))
            .ok_or_else(|| {
                GgsError::in_file(
                    path,
                    format!("the vertex element has no scalar property '{n}'"),
                )
            })
    };
    Ok([find("x")?, find("y")?, find("z")?])
}

/// Where face polygons are collected: the face element, its index list property, and the
/// fan-triangulated output.
struct FaceSink {
    element: usize,
    property: usize,
    triangles: Vec<[u32; 3]>,
    polygon: Vec<u32>,
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

/// Read a PLY file as a mesh: its vertices and the `face` element's `vertex_indices` (or
/// `vertex_index`) polygons, fan-triangulated. A file without faces gives no triangles.
pub fn parse_ply_mesh(path: &Path, bytes: &[u8]) -> Result<crate::io::mesh::Mesh> {
    let h = parse_header(path, bytes)?;
    let face = h.elements.iter().enumerate().find_map(|(ei, e)| {
        (e.name == "face").then(|| {
            e.props.iter().position(|p| {
                matches!(p, Property::List(_, _, n) if n == "vertex_indices" || n == "vertex_index")
            })
            .map(|pi| (ei, pi))
        })?
    });
    let mut sink = face.map(|(element, property)| FaceSink {
        element,
        property,
        triangles: Vec::new(),
        polygon: Vec::new(),
    });
    let mut mesh = crate::io::mesh::Mesh {
        vertices: read_vertices(path, bytes, &h, &mut sink)?,
        groups: vec![String::new()],
        ..Default::default()
    };
    let triangles = sink.map(|s| s.triangles).unwrap_or_default();
    let n = mesh.vertices.len() as u32;
    if let Some((k, t)) = triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&v| v >= n))
    {
        return Err(GgsError::in_file(
            path,
            format!("face triangle {k} uses vertex {t:?}, but there are only {n} vertices"),
        ));
    }
    mesh.triangle_group = vec![0; triangles.len()];
    mesh.triangles = triangles;
    Ok(mesh)
}

/// Read the rows of elements `0..=vi`; the scalar properties at `xyz` of element `vi` are
/// returned as points (`usize::MAX`: none), and faces go to `faces` if given.
/// One text row of `el` (line `line_no`): the values at the property indices `xyz` (as x,
/// y, z), and the face list into `faces` when that sink collects one of its properties.
fn ascii_row(
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

fn read_ascii(
    path: &Path,
    bytes: &[u8],
    h: &Header,
    vi: usize,
    xyz: &[usize],
    faces: &mut Option<FaceSink>,
) -> Result<Vec<Point>> {
    let text = &bytes[h.data_start..];
    let mut lines = text
        .split(|&b| b == b'\n')
        .enumerate()
        .filter(|(_, l)| !l.iter().all(|b| b.is_ascii_whitespace()));
    // A header may declare more rows than the file holds: reserve no more than the bytes
    // could hold (an ascii vertex takes at least 6 bytes).
    let mut out = Vec::with_capacity(h.elements[vi].count.min(text.len() / 6));
    let last = faces.as_ref().map_or(vi, |f| f.element.max(vi));
    for (ei, el) in h.elements.iter().enumerate().take(last + 1) {
        for k in 0..el.count {
            let (li, raw) = lines.next().ok_or_else(|| {
                GgsError::in_file(
                    path,
                    format!(
                        "truncated: element '{}' declares {} rows, the file ends after {k}",
                        el.name, el.count
                    ),
                )
            })?;
            let collect_faces = faces.as_ref().is_some_and(|f| f.element == ei);
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

fn read_binary(
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
struct BinaryCursor<'a> {
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

/// Options of the PLY writer.
#[derive(Debug, Clone, Copy, Default)]
pub struct PlyWriteOptions {
    /// Text instead of binary little endian.
    pub ascii: bool,
}

/// Write points (as `double x y z`) with an optional per-point colour (`uchar red green blue`),
/// atomically (temporary file, then rename).
pub fn write_ply(
    path: &Path,
    points: &[Point],
    colors: Option<&[[u8; 3]]>,
    opts: PlyWriteOptions,
) -> Result<()> {
    if let Some(c) = colors {
        if c.len() != points.len() {
            return Err(GgsError::param(
                "colors",
                format!("{} colours for {} points", c.len(), points.len()),
            ));
        }
    }
    let mut out = Vec::with_capacity(points.len() * 27 + 256);
    let fmt = if opts.ascii {
        "ascii"
    } else {
        "binary_little_endian"
    };
    out.extend_from_slice(
        format!(
            "ply\nformat {fmt} 1.0\ncomment written by ggs\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\n",
            points.len()
        )
        .as_bytes(),
    );
    if colors.is_some() {
        out.extend_from_slice(b"property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    out.extend_from_slice(b"end_header\n");
    for (i, p) in points.iter().enumerate() {
        if opts.ascii {
            let mut line = format!("{} {} {}", p[0], p[1], p[2]);
            if let Some(c) = colors {
                line.push_str(&format!(" {} {} {}", c[i][0], c[i][1], c[i][2]));
            }
            line.push('\n');
            out.extend_from_slice(line.as_bytes());
        } else {
            for v in p {
                out.extend_from_slice(&v.to_le_bytes());
            }
            if let Some(c) = colors {
                out.extend_from_slice(&c[i]);
            }
        }
    }
    write_atomic(path, &out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: &str = "t.ply";

    #[test]
    fn ascii_with_extra_elements_and_obj_info() {
        let s = "ply\nformat ascii 1.0\nobj_info num_cols 2\ncomment hi\nelement vertex 2\nproperty float y\nproperty float x\nproperty float z\nproperty uchar red\nelement range_grid 3\nproperty list uchar int vertex_indices\nwhatever unknown line\nend_header\n1 2 3 255\n4 5 6 0\n1 0\n0\n2 0 1\n";
        let pts = parse_ply(Path::new(P), s.as_bytes()).unwrap();
        assert_eq!(pts, vec![[2.0, 1.0, 3.0], [5.0, 4.0, 6.0]]);
    }

    #[test]
    fn binary_both_endians_with_element_before_vertex() {
        for little in [true, false] {
            let fmt = if little {
                "binary_little_endian"
            } else {
                "binary_big_endian"
            };
            let mut b = format!("ply\nformat {fmt} 1.0\nelement camera 1\nproperty list uchar int idx\nelement vertex 2\nproperty double x\nproperty float y\nproperty short z\nend_header\n").into_bytes();
            // camera: list of 2 ints
            b.push(2);
            for v in [7i32, 8] {
                b.extend_from_slice(&if little {
                    v.to_le_bytes()
                } else {
                    v.to_be_bytes()
                });
            }
            for (x, y, z) in [(1.5f64, 2.5f32, -3i16), (4.0, 5.0, 6)] {
                b.extend_from_slice(&if little {
                    x.to_le_bytes()
                } else {
                    x.to_be_bytes()
                });
                b.extend_from_slice(&if little {
                    y.to_le_bytes()
                } else {
                    y.to_be_bytes()
                });
                b.extend_from_slice(&if little {
                    z.to_le_bytes()
                } else {
                    z.to_be_bytes()
                });
            }
            let pts = parse_ply(Path::new(P), &b).unwrap();
            assert_eq!(pts, vec![[1.5, 2.5, -3.0], [4.0, 5.0, 6.0]]);
        }
    }

    #[test]
    fn errors() {
        let p = Path::new(P);
        let e = parse_ply(p, b"plx\n").unwrap_err().to_string();
        assert!(e.contains("line 1"), "{e}");
        let e = parse_ply(p, b"ply\nformat ascii 1.0\nelement vertex 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("end_header"), "{e}");
        let e = parse_ply(p, b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no scalar property 'z'"), "{e}");
        let e = parse_ply(p, b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n1 b 3\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 9") && e.contains("'b' is not a number"),
            "{e}"
        );
        let e = parse_ply(p, b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated"), "{e}");
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
        b.extend_from_slice(&[0u8; 16]);
        let e = parse_ply(p, &b).unwrap_err().to_string();
        assert!(e.contains("truncated") && e.contains("byte"), "{e}");
        let e = parse_ply(p, b"ply\nformat binary 1.0\nend_header\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown format"), "{e}");
    }

    #[test]
    fn overstated_counts_fail_cleanly() {
        let p = Path::new(P);
        for fmt in ["ascii", "binary_little_endian"] {
            let h = format!("ply\nformat {fmt} 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n");
            let e = parse_ply(p, h.as_bytes()).unwrap_err().to_string();
            assert!(e.contains("truncated"), "{e}");
        }
    }

    #[test]
    fn write_read_round_trip() {
        let dir = std::env::temp_dir().join(format!("ggs-ply-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pts = vec![[0.1, -2.0, 3.25], [1e-9, 7.0, -0.0]];
        for ascii in [false, true] {
            let p = dir.join(format!("a{ascii}.ply"));
            write_ply(
                &p,
                &pts,
                Some(&[[255, 0, 0], [0, 255, 0]]),
                PlyWriteOptions { ascii },
            )
            .unwrap();
            let back = parse_ply(&p, &std::fs::read(&p).unwrap()).unwrap();
            assert_eq!(back, pts);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn mesh_faces_ascii_and_binary() {
        let p = Path::new("m.ply");
        // A quad (fan-triangulated) and a triangle, with a vertex colour and a face flag.
        let ascii = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 2\nproperty uchar flags\nproperty list uchar int vertex_indices\nend_header\n0 0 0 1\n1 0 0 1\n1 1 0 1\n0 1 0 1\n0 0 1 1\n7 4 0 1 2 3\n7 3 0 1 4\n";
        let m = parse_ply_mesh(p, ascii.as_bytes()).unwrap();
        assert_eq!(m.vertices.len(), 5);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
        assert_eq!(m.triangle_group, vec![0; 3]);
        for little in [true, false] {
            let fmt = if little {
                "binary_little_endian"
            } else {
                "binary_big_endian"
            };
            let mut b = format!("ply\nformat {fmt} 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\nelement face 1\nproperty list uchar uint vertex_index\nend_header\n").into_bytes();
            for v in [
                [0.0f64, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ] {
                for c in v {
                    b.extend(if little {
                        c.to_le_bytes()
                    } else {
                        c.to_be_bytes()
                    });
                }
            }
            b.push(4);
            for i in [3u32, 2, 1, 0] {
                b.extend(if little {
                    i.to_le_bytes()
                } else {
                    i.to_be_bytes()
                });
            }
            let m = parse_ply_mesh(p, &b).unwrap();
            assert_eq!(m.triangles, vec![[3, 2, 1], [3, 1, 0]]);
            // A face index past the vertices is an error naming the face.
            let n = b.len();
            b[n - 4..].copy_from_slice(&if little {
                9u32.to_le_bytes()
            } else {
                9u32.to_be_bytes()
            });
            let e = parse_ply_mesh(p, &b).unwrap_err().to_string();
            assert!(e.contains("vertex") && e.contains("only 4 vertices"), "{e}");
        }
        // No face element: a mesh without triangles.
        let cloud = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
        assert!(parse_ply_mesh(p, cloud.as_bytes())
            .unwrap()
            .triangles
            .is_empty());
        // A negative index is refused with its line.
        let bad = ascii.replace("7 3 0 1 4", "7 3 0 -1 4");
        let e = parse_ply_mesh(p, bad.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("line 18") && e.contains("-1"), "{e}");
    }
}

/// One unit test per error path (streamed reader, in-memory parser and mesh reader).
#[cfg(test)]
mod error_paths {
    use super::*;
    use crate::error::Location::{Byte, File, Line};

    const XYZ: &str = "property float x\nproperty float y\nproperty float z\n";

    fn ascii(body_header: &str, data: &str) -> Vec<u8> {
        format!("ply\nformat ascii 1.0\n{body_header}end_header\n{data}").into_bytes()
    }

    fn binary(body_header: &str, data: &[u8]) -> Vec<u8> {
        let mut b =
            format!("ply\nformat binary_little_endian 1.0\n{body_header}end_header\n").into_bytes();
        b.extend_from_slice(data);
        b
    }

    fn streamed(path: &Path, b: &[u8]) -> Result<Vec<Point>> {
        read_ply_chunked(path, &mut std::io::Cursor::new(b), Some(b.len() as u64), 16)
    }

    fn mesh(path: &Path, b: &[u8]) -> Result<crate::io::mesh::Mesh> {
        parse_ply_mesh(path, b)
    }

    error_cases! { streamed;
        header_without_end: b"ply\nformat ascii 1.0\nelement vertex 1\n" => Line(4), "end_header";
        not_ply: b"plx\nformat ascii 1.0\nend_header\n" => Line(1), "expected 'ply'";
        unknown_encoding: b"ply\nformat binary 1.0\nend_header\n" => Line(2), "unknown format";
        element_without_count: ascii("element vertex\n", "") => Line(3), "element NAME COUNT";
        property_before_element: ascii("property float x\n", "") => Line(3), "before any 'element'";
        list_without_types: ascii("element face 1\nproperty list uchar\n", "") => Line(4), "property list COUNT_TYPE";
        unknown_property_type: ascii("element vertex 1\nproperty float128 x\n", "") => Line(4), "unknown property type 'float128'";
        property_without_name: ascii("element vertex 1\nproperty float\n", "") => Line(4), "without a name";
        no_format_line: b"ply\nelement vertex 0\nend_header\n" => File, "no 'format' line";
        no_vertex_element: ascii("element face 0\n", "") => File, "no 'vertex' element";
        no_z: ascii("element vertex 1\nproperty float x\nproperty float y\n", "1 2\n") => File, "no scalar property 'z'";
        ascii_truncated: ascii(&format!("element vertex 3\n{XYZ}"), "1 2 3\n") => File, "declares 3 rows, the file ends after 1";
        ascii_not_text: [ascii(&format!("element vertex 1\n{XYZ}"), ""), vec![0xff, 0xfe, b'\n']].concat() => Line(8), "not valid text";
        ascii_missing_value: ascii(&format!("element vertex 1\n{XYZ}"), "1 2\n") => Line(8), "missing value for 'z'";
        ascii_not_a_number: ascii(&format!("element vertex 1\n{XYZ}"), "1 two 3\n") => Line(8), "'two' is not a number ('y')";
        binary_truncated_vertex: binary(&format!("element vertex 2\n{XYZ}"), &[0u8; 20]) => Byte(135), "record 1 (at byte 127) runs past the end";
        binary_skipped_element_truncated: binary(&format!("element camera 4\nproperty double t\nelement vertex 1\n{XYZ}"), &[0u8; 9]) => Byte(159), "element 'camera' needs 32 bytes, the file ends after 9";
        binary_skipped_element_overflows: binary(&format!("element camera 18446744073709551615\nproperty double t\nelement vertex 1\n{XYZ}"), &[]) => Byte(169), "overflow";
    }

    error_cases! { parse_ply;
        whole_binary_truncated: binary(&format!("element vertex 2\n{XYZ}"), &[0u8; 20]) => Byte(135), "truncated: element 'vertex' row 1 of 2";
        whole_list_length_negative: binary(&format!("element vertex 1\n{XYZ}property list char int idx\n"), &[0u8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff]) => Byte(154), "invalid list length -1";
        whole_list_past_end: binary(&format!("element vertex 1\n{XYZ}property list uchar int idx\n"), &[0u8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 3, 1, 0, 0, 0]) => Byte(156), "truncated: element 'vertex' row 0";
    }

    error_cases! { mesh;
        face_index_negative: ascii(&format!("element vertex 3\n{XYZ}element face 1\nproperty list uchar int vertex_indices\n"), "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n") => Line(13), "face vertex index -1";
        face_index_past_vertices: ascii(&format!("element vertex 3\n{XYZ}element face 1\nproperty list uchar int vertex_indices\n"), "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n") => File, "only 3 vertices";
        binary_face_index_fraction: {
            let mut d = vec![0u8; 36];
            d.push(3);
            for v in [0.0f32, 1.0, 1.5] { d.extend(v.to_le_bytes()); }
            binary(&format!("element vertex 3\n{XYZ}element face 1\nproperty list uchar float vertex_indices\n"), &d)
        } => Byte(216), "face vertex index 1.5";
    }
}
