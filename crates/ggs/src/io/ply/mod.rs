//! PLY point clouds: ascii, binary little endian and binary big endian; any scalar property
//! types and order; extra elements (`range_grid`, faces, …), `comment` and `obj_info` lines
//! are skipped. Only the `vertex` element's `x`, `y`, `z` are read.

mod body;
mod header;

use super::{stream, write_atomic};
use crate::cloud::{Point, PointStore};
use crate::error::{GgsError, Result};
use body::*;
use header::*;
use std::io::BufRead;
use std::path::Path;

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
    read_ply_chunked::<Vec<Point>, R>(path, r, file_len, stream::CHUNK_BYTES)
}

/// [`read_ply`] into any [`PointStore`].
pub fn read_ply_into<S: PointStore, R: BufRead + Send>(
    path: &Path,
    r: &mut R,
    file_len: Option<u64>,
) -> Result<S::Out> {
    read_ply_chunked::<S, R>(path, r, file_len, stream::CHUNK_BYTES)
}

fn read_ply_chunked<S: PointStore, R: BufRead + Send>(
    path: &Path,
    r: &mut R,
    file_len: Option<u64>,
    chunk_bytes: usize,
) -> Result<S::Out> {
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
    if h.encoding == Encoding::Ascii && h.elements[vi].scalars_only() {
        let xyz = xyz_properties(path, &h, vi)?;
        return read_ascii_streamed::<S, _>(path, r, &h, vi, &xyz, file_len);
    }
    let fixed =
        h.encoding != Encoding::Ascii && h.elements[..=vi].iter().all(|e| row_size(e).is_some());
    if !fixed {
        stream::read_rest(path, r, &mut header, file_len)?;
        return Ok(S::from_vec(parse_ply(path, &header)?));
    }
    let pos = skip_to_vertices(path, r, &h, vi)?;
    let el = &h.elements[vi];
    let stride = row_size(el).unwrap_or(0);
    let offsets = xyz_offsets(el, &xyz_properties(path, &h, vi)?);
    let little = h.encoding == Encoding::BinaryLe;
    let room = file_len.map_or(1 << 20, |l| l.saturating_sub(pos) / stride.max(1) as u64);
    let (n, what) = (el.count as u64, "element 'vertex'");
    let at = offsets.map(|(o, _)| o);
    // The common layouts get a decoder without a per-value type dispatch.
    if little && offsets.iter().all(|&(_, t)| t == Scalar::F32) {
        let f = move |rec: &[u8]| at.map(|o| f32_le(&rec[o..o + 4]));
        stream::read_records::<S, R>(path, r, pos, stride, n, what, chunk_bytes, f, room)
    } else if little && offsets.iter().all(|&(_, t)| t == Scalar::F64) {
        let f = move |rec: &[u8]| at.map(|o| f64_le(&rec[o..o + 8]));
        stream::read_records::<S, R>(path, r, pos, stride, n, what, chunk_bytes, f, room)
    } else {
        let f = |rec: &[u8]| offsets.map(|(o, t)| t.decode(&rec[o..], little));
        stream::read_records::<S, R>(path, r, pos, stride, n, what, chunk_bytes, f, room)
    }
}

/// Bytes in one row of `e`, when every property is a scalar (`None` with a list).
fn row_size(e: &Element) -> Option<usize> {
    e.props
        .iter()
        .map(|p| match p {
            Property::Scalar(t, _) => Some(t.size()),
            Property::List(..) => None,
        })
        .sum()
}

/// Skip the binary elements before the vertex element `vi` (all of fixed row size); the byte
/// offset of its first row.
fn skip_to_vertices<R: BufRead>(path: &Path, r: &mut R, h: &Header, vi: usize) -> Result<u64> {
    let mut pos = h.data_start as u64;
    for e in &h.elements[..vi] {
        let len = (row_size(e).unwrap_or(0) as u64)
            .checked_mul(e.count as u64)
            .ok_or_else(|| {
                let why = format!(
                    "element '{}': {} rows overflow the file size",
                    e.name, e.count
                );
                GgsError::at_byte(path, pos, why)
            })?;
        stream::skip(path, r, pos, len, &format!("element '{}'", e.name))?;
        pos += len;
    }
    Ok(pos)
}

/// Byte offset and type of x, y and z (the properties `xyz`) within a row of `el`.
fn xyz_offsets(el: &Element, xyz: &[usize; 3]) -> [(usize, Scalar); 3] {
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
    offsets
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
        read_ply_chunked::<Vec<Point>, _>(
            path,
            &mut std::io::Cursor::new(b),
            Some(b.len() as u64),
            16,
        )
    }

    fn mesh(path: &Path, b: &[u8]) -> Result<crate::io::mesh::Mesh> {
        parse_ply_mesh(path, b)
    }

    proptest::proptest! {
        /// The streamed ascii reader (rows in chunks, `io::text`) reads what the in-memory
        /// parser reads, and fails with the same error, on ascii bodies with an element
        /// before `vertex`, blank and CRLF lines and a few bytes replaced by junk.
        #[test]
        fn streamed_and_whole_ascii_reads_agree(
            rows in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3, -1e3f64..1e3), 0..60),
            pre in 0usize..4,
            junk in proptest::collection::vec((0usize..4000, proptest::sample::select(
                vec![&b"x"[..], b"\xff", b"\r", b"\n", b"\n\n", b" ", b"\t", b"1e", b"-", b"nan", b"\xc2\xa0"])), 0..3),
        ) {
            let mut body = String::new();
            for k in 0..pre {
                body.push_str(&format!("{k} 7\n"));
            }
            for (i, (x, y, z)) in rows.iter().enumerate() {
                body.push_str(&format!("{x} {y} {z} {i}{}", if i % 5 == 0 { "\r\n\n" } else { "\n" }));
            }
            let header = format!(
                "element pre {pre}\nproperty int a\nproperty int b\nelement vertex {}\n{XYZ}property int i\n",
                rows.len()
            );
            let b = ascii(&header, &body);
            let start = b.len() - body.len();
            let b = crate::io::with_junk(b, start, &junk);
            let path = Path::new("p.ply");
            let (a, w) = (streamed(path, &b), parse_ply(path, &b));
            match (a, w) {
                (Ok(a), Ok(w)) => proptest::prop_assert_eq!(a, w),
                (Err(a), Err(w)) => proptest::prop_assert_eq!(a.to_string(), w.to_string()),
                (a, w) => proptest::prop_assert!(false, "{:?} against {:?}", a, w),
            }
        }
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
