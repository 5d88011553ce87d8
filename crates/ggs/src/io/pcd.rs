//! PCD point clouds (PCL): `VERSION .5`/`0.6`/`0.7` headers, with or without `VIEWPOINT`;
//! `DATA ascii`, `binary` and `binary_compressed` (LZF). Only fields `x`, `y`, `z` are read.

use super::{ply, stream};
use crate::cloud::{Point, PointStore};
use crate::error::{GgsError, Result};
use std::io::BufRead;
use std::path::Path;

#[derive(Debug, Clone)]
struct Field {
    name: String,
    size: usize,
    kind: u8,
    count: usize,
}

/// What a PCD header says.
struct PcdHeader {
    fields: Vec<Field>,
    /// Indices of the fields `x`, `y`, `z`.
    xyz: Vec<usize>,
    /// Number of points.
    n: usize,
    /// `ascii`, `binary` or `binary_compressed` (lower case).
    data_kind: String,
    /// Byte offset of the first data byte.
    data_start: usize,
    /// Header lines, the DATA line included.
    lines: usize,
}

/// The longest header accepted (comments included).
const MAX_HEADER_BYTES: usize = 1 << 20;

/// Read the points of a PCD file from a stream positioned at its first byte; `file_len`
/// (when known) bounds what an overstated POINTS may reserve. `DATA binary` files are
/// decoded [`stream::CHUNK_BYTES`] at a time (bounded memory beside the output); ascii and
/// binary_compressed files are read whole, then parsed by [`parse_pcd`].
pub fn read_pcd<R: BufRead + Send>(
    path: &Path,
    r: &mut R,
    file_len: Option<u64>,
) -> Result<Vec<Point>> {
    read_pcd_into::<Vec<Point>, R>(path, r, file_len)
}

/// [`read_pcd`] into any [`PointStore`].
pub fn read_pcd_into<S: PointStore, R: BufRead + Send>(
    path: &Path,
    r: &mut R,
    file_len: Option<u64>,
) -> Result<S::Out> {
    let mut header = stream::read_header(path, r, MAX_HEADER_BYTES, "DATA", |l| {
        l.split_whitespace()
            .next()
            .is_some_and(|k| k.eq_ignore_ascii_case("DATA"))
    })?;
    let h = parse_header(path, &header)?;
    if h.data_kind == "ascii" {
        return read_ascii_streamed::<S, _>(path, r, &h, file_len);
    }
    if h.data_kind != "binary" {
        stream::read_rest(path, r, &mut header, file_len)?;
        return Ok(S::from_vec(parse_pcd(path, &header)?));
    }
    let (field_off, stride) = row_layout(&h.fields);
    let room = file_len.map_or(1 << 20, |l| {
        l.saturating_sub(h.data_start as u64) / stride.max(1) as u64
    });
    let fx: [(&Field, usize); 3] =
        std::array::from_fn(|d| (&h.fields[h.xyz[d]], field_off[h.xyz[d]]));
    let (n, start, what, chunk) = (
        h.n as u64,
        h.data_start as u64,
        "POINTS",
        stream::CHUNK_BYTES,
    );
    let at = fx.map(|(_, o)| o);
    // x y z as float32 or float64 (PCD data is little endian): no per-value type dispatch.
    if fx.iter().all(|(f, _)| (f.kind, f.size) == (b'F', 4)) {
        let f = move |rec: &[u8]| at.map(|o| ply::f32_le(&rec[o..o + 4]));
        stream::read_records::<S, R>(path, r, start, stride, n, what, chunk, f, room)
    } else if fx.iter().all(|(f, _)| (f.kind, f.size) == (b'F', 8)) {
        let f = move |rec: &[u8]| at.map(|o| ply::f64_le(&rec[o..o + 8]));
        stream::read_records::<S, R>(path, r, start, stride, n, what, chunk, f, room)
    } else {
        let f = |rec: &[u8]| fx.map(|(f, o)| decode(f, &rec[o..]));
        stream::read_records::<S, R>(path, r, start, stride, n, what, chunk, f, room)
    }
}

/// Byte offset of each field in a row, and the row size.
fn row_layout(fields: &[Field]) -> (Vec<usize>, usize) {
    let mut field_off = Vec::with_capacity(fields.len());
    let mut stride = 0;
    for f in fields {
        field_off.push(stride);
        stride += f.size * f.count;
    }
    (field_off, stride)
}

/// Read the points of a PCD file held in memory.
pub fn parse_pcd(path: &Path, bytes: &[u8]) -> Result<Vec<Point>> {
    let h = parse_header(path, bytes)?;
    let data = &bytes[h.data_start..];
    let (fields, xyz, n, pos) = (&h.fields, &h.xyz, h.n, h.data_start);
    match h.data_kind.as_str() {
        "ascii" => read_ascii(path, data, h.lines, fields, xyz, n),
        "binary" => read_binary(path, data, pos, fields, xyz, n),
        // parse_header accepts these three only.
        _ => read_compressed(path, data, pos, fields, xyz, n),
    }
}

/// The header's lines as written, before they are checked against each other.
#[derive(Default)]
struct RawHeader {
    names: Vec<String>,
    sizes: Vec<usize>,
    types: Vec<u8>,
    counts: Vec<usize>,
    width: Option<usize>,
    height: Option<usize>,
    points: Option<usize>,
    data_kind: String,
    /// Byte offset of the first byte after the `DATA` line.
    data_start: usize,
    /// Number of the `DATA` line (1-based).
    lines: usize,
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<PcdHeader> {
    let raw = read_header_lines(path, bytes)?;
    let fields = header_fields(path, &raw)?;
    let n = point_count(path, &raw, &fields)?;
    let xyz: Vec<usize> = ["x", "y", "z"]
        .iter()
        .map(|name| {
            fields
                .iter()
                .position(|f| f.name == *name)
                .ok_or_else(|| GgsError::in_file(path, format!("no field '{name}' in FIELDS")))
        })
        .collect::<Result<_>>()?;
    if !matches!(
        raw.data_kind.as_str(),
        "ascii" | "binary" | "binary_compressed"
    ) {
        return Err(GgsError::at_line(
            path,
            raw.lines,
            format!(
                "unknown DATA '{}' (expected ascii, binary or binary_compressed)",
                raw.data_kind
            ),
        ));
    }
    Ok(PcdHeader {
        fields,
        xyz,
        n,
        data_kind: raw.data_kind,
        data_start: raw.data_start,
        lines: raw.lines,
    })
}

/// Reads the header up to and including its `DATA` line; each value is parsed where it
/// stands, so an error names its line.
fn read_header_lines(path: &Path, bytes: &[u8]) -> Result<RawHeader> {
    let mut raw = RawHeader::default();
    let mut pos = 0usize;
    let mut line_no = 0usize;
    loop {
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(GgsError::at_line(
                path,
                line_no + 1,
                "the header ends before its 'DATA' line",
            ));
        };
        let line = String::from_utf8_lossy(&bytes[pos..pos + nl])
            .trim()
            .to_string();
        pos += nl + 1;
        line_no += 1;
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if header_line(path, line_no, &line, &mut raw)? {
            raw.data_start = pos;
            raw.lines = line_no;
            return Ok(raw);
        }
    }
}

/// One keyword line into `raw`; `true` for the `DATA` line, the last.
fn header_line(path: &Path, line_no: usize, line: &str, raw: &mut RawHeader) -> Result<bool> {
    let mut tok = line.split_whitespace();
    let key = tok.next().unwrap_or("").to_ascii_uppercase();
    let rest: Vec<&str> = tok.collect();
    let parse_usize = |t: &str| {
        t.parse::<usize>().map_err(|_| {
            GgsError::at_line(
                path,
                line_no,
                format!("'{t}' is not a non-negative integer ({key})"),
            )
        })
    };
    let first = rest.first().copied().unwrap_or("");
    match key.as_str() {
        "VERSION" | "VIEWPOINT" => {}
        "FIELDS" | "COLUMNS" => raw.names = rest.iter().map(|s| s.to_string()).collect(),
        "SIZE" => raw.sizes = rest.iter().map(|t| parse_usize(t)).collect::<Result<_>>()?,
        "TYPE" => {
            raw.types = rest
                .iter()
                .map(|t| match *t {
                    "F" | "I" | "U" => Ok(t.as_bytes()[0]),
                    _ => Err(GgsError::at_line(
                        path,
                        line_no,
                        format!("unknown TYPE '{t}' (expected F, I or U)"),
                    )),
                })
                .collect::<Result<_>>()?
        }
        "COUNT" => raw.counts = rest.iter().map(|t| parse_usize(t)).collect::<Result<_>>()?,
        "WIDTH" => raw.width = Some(parse_usize(first)?),
        "HEIGHT" => raw.height = Some(parse_usize(first)?),
        "POINTS" => raw.points = Some(parse_usize(first)?),
        "DATA" => {
            raw.data_kind = first.to_ascii_lowercase();
            return Ok(true);
        }
        _ => {
            return Err(GgsError::at_line(
                path,
                line_no,
                format!("unknown header keyword '{key}'"),
            ));
        }
    }
    Ok(false)
}

/// The fields: one name, size, type and count each (COUNT defaults to 1), of a type and size
/// ggs decodes.
fn header_fields(path: &Path, raw: &RawHeader) -> Result<Vec<Field>> {
    let names = &raw.names;
    if names.is_empty() {
        return Err(GgsError::in_file(path, "the header has no FIELDS line"));
    }
    let ones = vec![1; names.len()];
    let counts = if raw.counts.is_empty() {
        &ones
    } else {
        &raw.counts
    };
    let (sizes, types) = (&raw.sizes, &raw.types);
    if sizes.len() != names.len() || types.len() != names.len() || counts.len() != names.len() {
        return Err(GgsError::in_file(
            path,
            format!(
                "FIELDS has {} entries but SIZE {}, TYPE {}, COUNT {}",
                names.len(),
                sizes.len(),
                types.len(),
                counts.len()
            ),
        ));
    }
    let fields: Vec<Field> = (0..names.len())
        .map(|i| Field {
            name: names[i].clone(),
            size: sizes[i],
            kind: types[i],
            count: counts[i],
        })
        .collect();
    for f in &fields {
        let ok = matches!(
            (f.kind, f.size),
            (b'F', 4 | 8) | (b'I' | b'U', 1 | 2 | 4 | 8)
        );
        if !ok {
            return Err(GgsError::in_file(
                path,
                format!(
                    "field '{}': unsupported TYPE {} with SIZE {}",
                    f.name, f.kind as char, f.size
                ),
            ));
        }
        if f.count == 0 {
            return Err(GgsError::in_file(
                path,
                format!(
                    "field '{}': COUNT 0 (every field holds at least one value)",
                    f.name
                ),
            ));
        }
    }
    Ok(fields)
}

/// POINTS, or WIDTH × HEIGHT (HEIGHT defaults to 1); refused when the points' bytes could not
/// fit in a file.
fn point_count(path: &Path, raw: &RawHeader, fields: &[Field]) -> Result<usize> {
    let height = raw.height.unwrap_or(1);
    let n = match (raw.points, raw.width) {
        (Some(p), _) => p,
        (None, Some(w)) => w.checked_mul(height).ok_or_else(|| {
            GgsError::in_file(path, format!("WIDTH {w} × HEIGHT {height} overflows"))
        })?,
        (None, None) => {
            return Err(GgsError::in_file(
                path,
                "the header has neither POINTS nor WIDTH",
            ))
        }
    };
    fields
        .iter()
        .try_fold(0usize, |acc, f| {
            acc.checked_add(f.size.checked_mul(f.count)?)
        })
        .and_then(|row| row.checked_mul(n))
        .ok_or_else(|| {
            GgsError::in_file(
                path,
                format!("{n} points of the declared fields need more bytes than a file can hold"),
            )
        })?;
    Ok(n)
}

fn decode(f: &Field, b: &[u8]) -> f64 {
    match (f.kind, f.size) {
        (b'F', 4) => f32::from_le_bytes(b[..4].try_into().unwrap()) as f64,
        (b'F', _) => f64::from_le_bytes(b[..8].try_into().unwrap()),
        (b'I', 1) => b[0] as i8 as f64,
        (b'I', 2) => i16::from_le_bytes(b[..2].try_into().unwrap()) as f64,
        (b'I', 4) => i32::from_le_bytes(b[..4].try_into().unwrap()) as f64,
        (b'I', _) => i64::from_le_bytes(b[..8].try_into().unwrap()) as f64,
        (_, 1) => b[0] as f64,
        (_, 2) => u16::from_le_bytes(b[..2].try_into().unwrap()) as f64,
        (_, 4) => u32::from_le_bytes(b[..4].try_into().unwrap()) as f64,
        (_, _) => u64::from_le_bytes(b[..8].try_into().unwrap()) as f64,
    }
}

/// The token columns of x, y, z in an ascii row, and the number of values a row holds.
fn ascii_columns(fields: &[Field], xyz: &[usize]) -> ([usize; 3], usize) {
    // Token index of the first value of each field.
    let mut first = Vec::with_capacity(fields.len());
    let mut t = 0;
    for f in fields {
        first.push(t);
        t += f.count;
    }
    ([first[xyz[0]], first[xyz[1]], first[xyz[2]]], t)
}

/// Read the points of the ascii lines of `data` (whose first line is line `first_line` of
/// the file) into `out` until it holds `n`; blank lines are skipped.
fn ascii_rows(
    path: &Path,
    data: &[u8],
    first_line: usize,
    (cols, t): ([usize; 3], usize),
    n: usize,
    out: &mut Vec<Point>,
) -> Result<()> {
    for (li, raw) in crate::io::text::lines(data) {
        if out.len() == n {
            break;
        }
        // In stride where it can be (crate::io::text), else as below, which says what is wrong.
        if let Some(p) = crate::io::text::xyz_columns(raw, &cols, &crate::io::text::ASCII_SPACE) {
            out.push(p);
            continue;
        }
        let line_no = first_line + li;
        let line = std::str::from_utf8(raw)
            .map_err(|_| GgsError::at_line(path, line_no, "not valid text"))?;
        if line.trim().is_empty() {
            continue;
        }
        // PCL writes `nan` in ascii files; `str::parse` takes it, and `NaN` too.
        let toks: Vec<&str> = line.split_ascii_whitespace().collect();
        let expected = |_, n: usize| format!("expected {t} values, found {n}");
        let p = crate::io::text::token_columns(path, line_no, &toks, &cols, expected)?;
        out.push(p);
    }
    Ok(())
}

/// The error of a file that holds `got` of the header's `n` points.
fn truncated(path: &Path, n: usize, got: usize) -> GgsError {
    GgsError::in_file(
        path,
        format!("truncated: the header declares {n} points, the file holds {got}"),
    )
}

fn read_ascii(
    path: &Path,
    data: &[u8],
    header_lines: usize,
    fields: &[Field],
    xyz: &[usize],
    n: usize,
) -> Result<Vec<Point>> {
    // The header may overstate POINTS: an ascii point takes at least 6 bytes.
    let mut out = Vec::with_capacity(n.min(data.len() / 6));
    let columns = ascii_columns(fields, xyz);
    ascii_rows(path, data, header_lines + 1, columns, n, &mut out)?;
    if out.len() < n {
        return Err(truncated(path, n, out.len()));
    }
    Ok(out)
}

/// [`read_ascii`] streamed from `r` (positioned at the data, byte `h.data_start`) a few MB
/// at a time ([`crate::io::text::TextChunks`]); nothing after the `n`-th point is read.
fn read_ascii_streamed<S: PointStore, R: std::io::Read>(
    path: &Path,
    r: R,
    h: &PcdHeader,
    file_len: Option<u64>,
) -> Result<S::Out> {
    let remaining = file_len.map(|l| l.saturating_sub(h.data_start as u64));
    let mut chunks =
        crate::io::text::TextChunks::new(r, h.data_start as u64, h.lines + 1, remaining);
    let columns = ascii_columns(&h.fields, &h.xyz);
    let reserve = remaining.map_or(1 << 20, |l| (l / 6) as usize);
    let mut out = S::with_capacity(h.n.min(reserve));
    let (mut got, mut part) = (0, Vec::new());
    while got < h.n {
        let Some(chunk) = chunks.next_chunk(path)? else {
            return Err(truncated(path, h.n, got));
        };
        part.clear();
        ascii_rows(path, chunk.bytes, chunk.line, columns, h.n - got, &mut part)?;
        got += part.len();
        out.extend_from(&part);
    }
    Ok(out.finish())
}

fn read_binary(
    path: &Path,
    data: &[u8],
    offset: usize,
    fields: &[Field],
    xyz: &[usize],
    n: usize,
) -> Result<Vec<Point>> {
    let (field_off, stride) = row_layout(fields);
    // parse_header checked that n rows fit in a usize.
    let need = stride * n;
    if data.len() < need {
        return Err(GgsError::at_byte(
            path,
            (offset + data.len()) as u64,
            format!(
                "truncated: {n} points of {stride} bytes need {need} bytes of data, found {}",
                data.len()
            ),
        ));
    }
    // Row layout: point i's record starts at i·stride.
    Ok(gather_xyz(&data[..need], fields, xyz, n, |d, i| {
        field_off[xyz[d]] + i * stride
    }))
}

/// Decode x, y, z of `n` points from `bytes`, where `at(d, i)` is the byte position of
/// coordinate `d` (0, 1, 2) of point `i` (in bounds: the callers checked the length).
fn gather_xyz(
    bytes: &[u8],
    fields: &[Field],
    xyz: &[usize],
    n: usize,
    at: impl Fn(usize, usize) -> usize,
) -> Vec<Point> {
    (0..n)
        .map(|i| std::array::from_fn(|d| decode(&fields[xyz[d]], &bytes[at(d, i)..])))
        .collect()
}

fn read_compressed(
    path: &Path,
    data: &[u8],
    offset: usize,
    fields: &[Field],
    xyz: &[usize],
    n: usize,
) -> Result<Vec<Point>> {
    if data.len() < 8 {
        return Err(GgsError::at_byte(
            path,
            offset as u64,
            "truncated: binary_compressed data needs an 8-byte size header",
        ));
    }
    let csize = u32::from_le_bytes(data[0..4].try_into().unwrap()) as usize;
    let usize_ = u32::from_le_bytes(data[4..8].try_into().unwrap()) as usize;
    let comp = data.get(8..8 + csize).ok_or_else(|| {
        GgsError::at_byte(
            path,
            (offset + 8) as u64,
            format!(
                "truncated: compressed block of {csize} bytes, {} present",
                data.len() - 8
            ),
        )
    })?;
    let raw = lzf_decompress(comp, usize_).map_err(|m| {
        GgsError::at_byte(path, (offset + 8) as u64, format!("corrupt LZF data: {m}"))
    })?;
    // Column layout: every field's values for all points, field after field.
    let mut field_off = Vec::with_capacity(fields.len());
    let mut o = 0usize;
    for f in fields {
        field_off.push(o);
        o += f.size * f.count * n;
    }
    if raw.len() < o {
        return Err(GgsError::in_file(
            path,
            format!(
                "decompressed data holds {} bytes, {n} points need {o}",
                raw.len()
            ),
        ));
    }
    Ok(gather_xyz(&raw, fields, xyz, n, |d, i| {
        let f = &fields[xyz[d]];
        field_off[xyz[d]] + i * f.size * f.count
    }))
}

/// Write points as a PCD v0.7 `binary` file (`x y z` as 8-byte floats, full precision),
/// atomically.
pub fn write_pcd(path: &Path, points: &[Point]) -> Result<()> {
    let mut out = format!(
        "# .PCD v0.7 - Point Cloud Data file format (written by ggs)\nVERSION 0.7\n\
         FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\n\
         VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n",
        n = points.len()
    )
    .into_bytes();
    out.reserve(points.len() * 24);
    for p in points {
        for v in p {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    super::write_atomic(path, &out)
}

/// LZF decompression (the format of liblzf, used by PCL's `binary_compressed`).
pub fn lzf_decompress(input: &[u8], out_len: usize) -> std::result::Result<Vec<u8>, String> {
    // One input byte expands to at most ~88 output bytes: never trust `out_len` for the
    // allocation.
    let mut out: Vec<u8> = Vec::with_capacity(out_len.min(input.len().saturating_mul(90)));
    let mut i = 0usize;
    while i < input.len() {
        let ctrl = input[i] as usize;
        i += 1;
        if ctrl < 32 {
            let len = ctrl + 1;
            let lit = input
                .get(i..i + len)
                .ok_or("literal run past the end of the input")?;
            if out.len() + len > out_len {
                return Err("output longer than declared".into());
            }
            out.extend_from_slice(lit);
            i += len;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                len += *input.get(i).ok_or("truncated back-reference")? as usize;
                i += 1;
            }
            len += 2;
            let low = *input.get(i).ok_or("truncated back-reference")? as usize;
            i += 1;
            let back = ((ctrl & 0x1f) << 8) + low + 1;
            if back > out.len() {
                return Err("back-reference before the start of the output".into());
            }
            if out.len() + len > out_len {
                return Err("output longer than declared".into());
            }
            let start = out.len() - back;
            for k in 0..len {
                let b = out[start + k];
                out.push(b);
            }
        }
    }
    if out.len() != out_len {
        return Err(format!(
            "decompressed {} bytes, header says {out_len}",
            out.len()
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: &str = "t.pcd";

    #[test]
    fn ascii_v5_without_viewpoint() {
        let s = "# .PCD v.5\nVERSION .5\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
        assert_eq!(
            parse_pcd(Path::new(P), s.as_bytes()).unwrap(),
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
        );
    }

    #[test]
    fn binary_with_extra_fields() {
        let mut b = b"VERSION 0.7\nFIELDS intensity x y z\nSIZE 4 4 4 8\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA binary\n".to_vec();
        for (i, x, y, z) in [(9.0f32, 1.0f32, 2.0f32, 3.0f64), (9.0, 4.0, 5.0, 6.0)] {
            b.extend_from_slice(&i.to_le_bytes());
            b.extend_from_slice(&x.to_le_bytes());
            b.extend_from_slice(&y.to_le_bytes());
            b.extend_from_slice(&z.to_le_bytes());
        }
        assert_eq!(
            parse_pcd(Path::new(P), &b).unwrap(),
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
        );
        b.truncate(b.len() - 3);
        let e = parse_pcd(Path::new(P), &b).unwrap_err().to_string();
        assert!(e.contains("truncated") && e.contains("byte"), "{e}");
    }

    #[test]
    fn binary_compressed_literal_only() {
        // Column layout for 2 points, fields x y z (f32): x0 x1 y0 y1 z0 z1.
        let vals = [1.0f32, 4.0, 2.0, 5.0, 3.0, 6.0];
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        // LZF literal runs of at most 32 bytes: 24 bytes fit in one.
        let mut comp = vec![(raw.len() - 1) as u8];
        comp.extend_from_slice(&raw);
        let mut b = b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary_compressed\n".to_vec();
        b.extend_from_slice(&(comp.len() as u32).to_le_bytes());
        b.extend_from_slice(&(raw.len() as u32).to_le_bytes());
        b.extend_from_slice(&comp);
        assert_eq!(
            parse_pcd(Path::new(P), &b).unwrap(),
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
        );
    }

    #[test]
    fn overstated_sizes_fail_cleanly() {
        let p = Path::new(P);
        let e = parse_pcd(p, b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1000000000000\nDATA ascii\n1 2 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated"), "{e}");
        // A compressed block claiming 4 GB of output from 2 bytes.
        let mut b = b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA binary_compressed\n".to_vec();
        b.extend_from_slice(&2u32.to_le_bytes());
        b.extend_from_slice(&u32::MAX.to_le_bytes());
        b.extend_from_slice(&[0, 7]);
        let e = parse_pcd(p, &b).unwrap_err().to_string();
        assert!(e.contains("LZF"), "{e}");
    }

    #[test]
    fn lzf_back_reference() {
        // "abcabcabc": literal "abc", then copy 6 bytes from distance 3.
        let comp = [2u8, b'a', b'b', b'c', (4 << 5) as u8, 2];
        assert_eq!(lzf_decompress(&comp, 9).unwrap(), b"abcabcabc");
        assert!(lzf_decompress(&[(1 << 5) as u8, 10], 3).is_err());
    }

    #[test]
    fn errors() {
        let p = Path::new(P);
        let e = parse_pcd(
            p,
            b"FIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nPOINTS 1\nDATA ascii\n1 2\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("no field 'z'"), "{e}");
        let e = parse_pcd(
            p,
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 0\nPOINTS 1\nDATA binary\n\0\0\0\0\0\0\0\0",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("field 'z': COUNT 0"), "{e}");
        let e = parse_pcd(p, b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 3") && e.contains("unknown TYPE"), "{e}");
        let e = parse_pcd(
            p,
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 2\nDATA ascii\n1 2 3\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("truncated"), "{e}");
        let e = parse_pcd(
            p,
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA ascii\n1 x 3\n",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("line 7") && e.contains("'x' is not a number"),
            "{e}"
        );
        let e = parse_pcd(p, b"FIELDS x y z\nBOGUS 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2"), "{e}");
    }
}

/// One unit test per error path (streamed reader and in-memory parser).
#[cfg(test)]
mod error_paths {
    use super::*;
    use crate::error::Location::{Byte, File, Line};

    /// A v0.7 header with fields x y z (F 4) and `n` points, then `data`.
    fn pcd(kind: &str, n: usize, data: &[u8]) -> Vec<u8> {
        let mut b = format!("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nPOINTS {n}\nDATA {kind}\n").into_bytes();
        b.extend_from_slice(data);
        b
    }

    fn header(lines: &str) -> Vec<u8> {
        format!("{lines}DATA ascii\n").into_bytes()
    }

    fn streamed(path: &Path, b: &[u8]) -> Result<Vec<Point>> {
        read_pcd(path, &mut std::io::Cursor::new(b), Some(b.len() as u64))
    }

    proptest::proptest! {
        /// The streamed ascii reader reads what the in-memory parser reads, and fails with
        /// the same error, on ascii bodies with blank and CRLF lines, a declared count off by
        /// a little, and a few bytes replaced by junk.
        #[test]
        fn streamed_and_whole_ascii_reads_agree(
            rows in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3, -1e3f64..1e3), 0..60),
            extra in 0usize..3,
            fewer in 0usize..3,
            junk in proptest::collection::vec((0usize..4000, proptest::sample::select(
                vec![&b"x"[..], b"\xff", b"\r", b"\n", b"\n\n", b" ", b"\x0b", b"1e", b"nan", b"\xc2\xa0"])), 0..3),
        ) {
            let mut body = String::new();
            for (i, (x, y, z)) in rows.iter().enumerate() {
                body.push_str(&format!("{x} {y} {z}{}", if i % 5 == 0 { "\r\n\n" } else { "\n" }));
            }
            let n = (rows.len() + extra).saturating_sub(fewer);
            let b = pcd("ascii", n, body.as_bytes());
            let start = b.len() - body.len();
            let b = crate::io::with_junk(b, start, &junk);
            let path = Path::new("p.pcd");
            match (streamed(path, &b), parse_pcd(path, &b)) {
                (Ok(a), Ok(w)) => proptest::prop_assert_eq!(a, w),
                (Err(a), Err(w)) => proptest::prop_assert_eq!(a.to_string(), w.to_string()),
                (a, w) => proptest::prop_assert!(false, "{:?} against {:?}", a, w),
            }
        }
    }

    error_cases! { streamed;
        no_data_line: b"VERSION 0.7\nFIELDS x y z\n" => Line(3), "DATA";
        count_not_an_integer: header("FIELDS x y z\nSIZE 4 4 four\n") => Line(2), "'four' is not a non-negative integer (SIZE)";
        unknown_type: header("FIELDS x y z\nSIZE 4 4 4\nTYPE F F D\n") => Line(3), "unknown TYPE 'D'";
        unknown_keyword: header("FIELDS x y z\nCOLOUR 1\n") => Line(2), "unknown header keyword 'COLOUR'";
        no_fields: header("POINTS 1\n") => File, "no FIELDS line";
        field_lists_differ: header("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nPOINTS 1\n") => File, "FIELDS has 3 entries but SIZE 2";
        unsupported_size: header("FIELDS x y z\nSIZE 4 4 2\nTYPE F F F\nPOINTS 1\n") => File, "field 'z': unsupported TYPE F with SIZE 2";
        zero_count: header("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 0 1\nPOINTS 1\n") => File, "field 'y': COUNT 0";
        width_times_height_overflows: header("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 18446744073709551615\nHEIGHT 2\n") => File, "overflows";
        no_point_count: header("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n") => File, "neither POINTS nor WIDTH";
        rows_overflow: header("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 18446744073709551615\n") => File, "more bytes than a file can hold";
        no_z_field: header("FIELDS x y w\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\n") => File, "no field 'z'";
        unknown_data: pcd("packed", 1, b"") => Line(9), "unknown DATA 'packed'";
        ascii_not_text: pcd("ascii", 1, &[0xff, 0xfe, b'\n']) => Line(10), "not valid text";
        ascii_short_row: pcd("ascii", 1, b"1 2\n") => Line(10), "expected 3 values, found 2";
        ascii_not_a_number: pcd("ascii", 1, b"1 2 x3\n") => Line(10), "'x3' is not a number";
        ascii_truncated: pcd("ascii", 3, b"1 2 3\n") => File, "declares 3 points, the file holds 1";
        binary_truncated: pcd("binary", 2, &[0u8; 20]) => Byte(117), "record 1 (at byte 109) runs past the end";
        compressed_no_size_header: pcd("binary_compressed", 1, &[1, 2, 3]) => Byte(108), "8-byte size header";
        compressed_block_truncated: pcd("binary_compressed", 1, &[9, 0, 0, 0, 12, 0, 0, 0, 1]) => Byte(116), "compressed block of 9 bytes, 1 present";
        compressed_corrupt_lzf: pcd("binary_compressed", 1, &[2, 0, 0, 0, 12, 0, 0, 0, 0x20, 5]) => Byte(116), "corrupt LZF data: back-reference before the start";
        compressed_too_short: pcd("binary_compressed", 1, &[2, 0, 0, 0, 1, 0, 0, 0, 0, 7]) => File, "decompressed data holds 1 bytes, 1 points need 12";
    }

    error_cases! { parse_pcd;
        whole_binary_truncated: pcd("binary", 2, &[0u8; 20]) => Byte(117), "need 24 bytes of data, found 20";
    }
}
