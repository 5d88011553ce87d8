//! Triangle meshes: Wavefront OBJ and STL (binary and ASCII).
//!
//! As point clouds they give their vertices (STL: the distinct triangle corners, in order of
//! first appearance). The faces are kept for surface sampling; OBJ groups (`g`/`o`) are
//! kept so that a part can be selected (the MakeHuman base mesh's `body`).

use crate::cloud::Point;
use crate::error::{GgsError, Result};
use std::collections::HashMap;
use std::path::Path;

pub use crate::mesh::Mesh;

fn number(path: &Path, line: usize, tok: Option<&str>, what: &str) -> Result<f64> {
    let tok = tok.ok_or_else(|| GgsError::at_line(path, line, format!("missing {what}")))?;
    tok.parse()
        .map_err(|_| GgsError::at_line(path, line, format!("{what}: '{tok}' is not a number")))
}

/// Parse an OBJ file: `v` (x y z, an optional w or colour ignored), `f` (polygons of
/// `v`, `v/vt`, `v//vn` or `v/vt/vn` references, 1-based or negative = relative), `g`/`o`.
/// Other statements (`vt`, `vn`, `s`, `usemtl`, `mtllib`, `l`, ...) are skipped.
pub fn parse_obj(path: &Path, bytes: &[u8]) -> Result<Mesh> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| GgsError::at_byte(path, e.valid_up_to() as u64, "not UTF-8 text"))?;
    let mut mesh = Mesh::default();
    let mut group: Option<u32> = None;
    let mut poly: Vec<u32> = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let n = k + 1;
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut tok = line.split_whitespace();
        match tok.next() {
            Some("v") => {
                let x = number(path, n, tok.next(), "vertex x")?;
                let y = number(path, n, tok.next(), "vertex y")?;
                let z = number(path, n, tok.next(), "vertex z")?;
                mesh.vertices.push([x, y, z]);
            }
            Some("g") | Some("o") => {
                let name = tok.collect::<Vec<_>>().join(" ");
                let idx = match mesh.groups.iter().position(|g| *g == name) {
                    Some(i) => i,
                    None => {
                        mesh.groups.push(name);
                        mesh.groups.len() - 1
                    }
                };
                group = Some(idx as u32);
            }
            Some("f") => {
                poly.clear();
                for r in tok {
                    let first = r.split('/').next().unwrap_or("");
                    let i: i64 = first.parse().map_err(|_| {
                        GgsError::at_line(path, n, format!("face reference '{r}' is not an index"))
                    })?;
                    let nv = mesh.vertices.len() as i64;
                    let idx = if i > 0 { i - 1 } else { nv + i };
                    if i == 0 || idx < 0 || idx >= nv {
                        return Err(GgsError::at_line(
                            path,
                            n,
                            format!("face index {i} is out of range: {nv} vertices so far"),
                        ));
                    }
                    poly.push(idx as u32);
                }
                if poly.len() < 3 {
                    return Err(GgsError::at_line(
                        path,
                        n,
                        format!("a face needs at least 3 vertices, found {}", poly.len()),
                    ));
                }
                let g = *group.get_or_insert_with(|| {
                    mesh.groups.push(String::new());
                    (mesh.groups.len() - 1) as u32
                });
                for w in 1..poly.len() - 1 {
                    mesh.triangles.push([poly[0], poly[w], poly[w + 1]]);
                    mesh.triangle_group.push(g);
                }
            }
            _ => {}
        }
    }
    Ok(mesh)
}

/// Parse an STL file, binary (80-byte header, u32 count, 50 bytes per triangle) or ASCII
/// (`solid … facet … vertex x y z …`). ASCII needs text that starts with `solid` and has
/// `facet`/`endsolid`, and not exactly the binary size (many binary exporters write a
/// `solid` header).
pub fn parse_stl(path: &Path, bytes: &[u8]) -> Result<Mesh> {
    let binary_size = (bytes.len() >= 84).then(|| {
        84 + 50 * u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize
    });
    let text = match std::str::from_utf8(bytes) {
        Ok(t)
            if binary_size != Some(bytes.len())
                && t.trim_start().starts_with("solid")
                && (t.contains("facet") || t.contains("endsolid")) =>
        {
            t
        }
        _ => return parse_stl_binary(path, bytes),
    };
    let mut corners = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let mut tok = raw.split_whitespace();
        if tok.next() == Some("vertex") {
            let n = k + 1;
            corners.push([
                number(path, n, tok.next(), "vertex x")?,
                number(path, n, tok.next(), "vertex y")?,
                number(path, n, tok.next(), "vertex z")?,
            ]);
        }
    }
    if corners.len() % 3 != 0 {
        return Err(GgsError::in_file(
            path,
            format!(
                "{} vertices: not a whole number of triangles",
                corners.len()
            ),
        ));
    }
    Ok(indexed(corners))
}

fn parse_stl_binary(path: &Path, bytes: &[u8]) -> Result<Mesh> {
    if bytes.len() < 84 {
        return Err(GgsError::at_byte(
            path,
            bytes.len() as u64,
            "truncated: a binary STL starts with an 80-byte header and a triangle count",
        ));
    }
    let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
    let need = 84 + 50 * n;
    if bytes.len() < need {
        return Err(GgsError::at_byte(
            path,
            bytes.len() as u64,
            format!(
                "truncated: {n} triangles need {need} bytes, found {}",
                bytes.len()
            ),
        ));
    }
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64;
    let mut corners = Vec::with_capacity(3 * n);
    for t in bytes[84..need].chunks_exact(50) {
        for c in 0..3 {
            let o = 12 + 12 * c;
            corners.push([f(&t[o..]), f(&t[o + 4..]), f(&t[o + 8..])]);
        }
    }
    Ok(indexed(corners))
}

/// Triangles from a corner list, sharing bit-identical corners.
fn indexed(corners: Vec<Point>) -> Mesh {
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut mesh = Mesh {
        groups: vec![String::new()],
        ..Mesh::default()
    };
    let ids: Vec<u32> = corners
        .iter()
        .map(|p| {
            *index.entry(p.map(f64::to_bits)).or_insert_with(|| {
                mesh.vertices.push(*p);
                (mesh.vertices.len() - 1) as u32
            })
        })
        .collect();
    for t in ids.chunks_exact(3) {
        mesh.triangles.push([t[0], t[1], t[2]]);
        mesh.triangle_group.push(0);
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_faces_groups_and_relative_indices() {
        let p = Path::new("m.obj");
        let text = "# cube corner\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 1.0\nvt 0 0\ng a\nf 1/1 2/1 3/1 4/1\ng b\nf -4//1 -2//1 -1//1\ns off\n";
        let m = parse_obj(p, text.as_bytes()).unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        assert_eq!(m.groups, vec!["a", "b"]);
        let b = m.group("b").unwrap();
        assert_eq!(b.vertices, vec![[0.0; 3], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
        assert_eq!(b.triangles, vec![[0, 1, 2]]);
        assert!(m.group("c").unwrap_err().contains("groups: a, b"));
        for (bad, want) in [
            ("v 0 0\n", "line 1: missing vertex z"),
            ("v 0 x 0\n", "line 1: vertex y: 'x'"),
            ("v 0 0 0\nf 1 2 3\n", "line 2: face index 2 is out of range"),
            ("v 0 0 0\nf 1 1\n", "at least 3 vertices"),
            ("v 0 0 0\nf 1 a 1\n", "'a' is not an index"),
        ] {
            let e = parse_obj(p, bad.as_bytes()).unwrap_err().to_string();
            assert!(e.contains(want), "{bad:?}: {e}");
        }
    }

    fn binary_stl(tris: &[[[f32; 3]; 3]], header: &[u8]) -> Vec<u8> {
        let mut b = header.to_vec();
        b.resize(80, b' ');
        b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
        for t in tris {
            b.extend_from_slice(&[0u8; 12]);
            for c in t {
                for v in c {
                    b.extend_from_slice(&v.to_le_bytes());
                }
            }
            b.extend_from_slice(&[0u8; 2]);
        }
        b
    }

    #[test]
    fn stl_binary_and_ascii() {
        let p = Path::new("m.stl");
        let tris = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        ];
        // A binary file whose header starts with "solid" is still binary.
        let b = binary_stl(&tris, b"solid exported");
        let m = parse_stl(p, &b).unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [1, 3, 2]]);
        let e = parse_stl(p, &b[..120]).unwrap_err().to_string();
        assert!(e.contains("truncated: 2 triangles need 184 bytes"), "{e}");
        let ascii = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
        let m = parse_stl(p, ascii.as_bytes()).unwrap();
        assert_eq!(m.vertices, vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let e = parse_stl(p, ascii.replace("vertex 1 0 0", "vertex 1 q 0").as_bytes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 5") && e.contains("'q'"), "{e}");
    }
}

/// One unit test per error path.
#[cfg(test)]
mod error_paths {
    use super::*;
    use crate::error::Location::{Byte, File, Line};

    fn obj(path: &Path, b: &[u8]) -> Result<Mesh> {
        parse_obj(path, b)
    }

    fn stl(path: &Path, b: &[u8]) -> Result<Mesh> {
        parse_stl(path, b)
    }

    error_cases! { obj;
        obj_not_utf8: b"v 0 0 0\nv \xff\n" => Byte(10), "not UTF-8";
        obj_vertex_missing_z: b"v 0 0 0\nv 1 2\n" => Line(2), "missing";
        obj_vertex_not_a_number: b"v 0 0 zero\n" => Line(1), "'zero' is not a number";
        obj_face_not_an_index: b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 c\n" => Line(4), "face reference 'c' is not an index";
        obj_face_index_zero: b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n" => Line(4), "face index 0 is out of range";
        obj_face_index_ahead: b"v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n" => Line(3), "face index 3 is out of range: 2 vertices so far";
        obj_face_too_small: b"v 0 0 0\nv 1 0 0\nf 1 2\n" => Line(3), "at least 3 vertices, found 2";
    }

    error_cases! { stl;
        ascii_vertex_not_a_number: b"solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 x\n" => Line(4), "vertex z: 'x' is not a number";
        ascii_partial_triangle: b"solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n" => File, "2 vertices: not a whole number of triangles";
        binary_no_header: [0u8; 50] => Byte(50), "80-byte header and a triangle count";
        binary_truncated: {
            let mut b = vec![0u8; 84 + 60];
            b[80] = 2;
            b
        } => Byte(144), "truncated: 2 triangles need 184 bytes, found 144";
    }
}
