//! Triangle meshes as ggs holds them (read by `io::mesh`, sampled by [`sampling`]): below both
//! the readers and the benchmark generator, so that neither imports the other.

pub mod sampling;

use crate::cloud::Point;
use std::collections::HashMap;

/// A triangle mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<Point>,
    /// Triangles (polygons fan-triangulated), as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// The OBJ group (or object) of each triangle, an index into `groups`.
    pub triangle_group: Vec<u32>,
    /// Group names in order of first appearance; `""` before any `g`/`o` line.
    pub groups: Vec<String>,
}

impl Mesh {
    /// The mesh restricted to the triangles of the named group and the vertices they use
    /// (renumbered in order of first use); an unknown name is an error listing the groups.
    pub fn group(&self, name: &str) -> std::result::Result<Mesh, String> {
        let g = self
            .groups
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| format!("no group '{name}' (groups: {})", self.groups.join(", ")))?;
        let mut remap: HashMap<u32, u32> = HashMap::new();
        let mut out = Mesh {
            groups: vec![name.to_string()],
            ..Mesh::default()
        };
        for (t, &tg) in self.triangles.iter().zip(&self.triangle_group) {
            if tg as usize != g {
                continue;
            }
            let tri = t.map(|v| {
                *remap.entry(v).or_insert_with(|| {
                    out.vertices.push(self.vertices[v as usize]);
                    (out.vertices.len() - 1) as u32
                })
            });
            out.triangles.push(tri);
            out.triangle_group.push(0);
        }
        Ok(out)
    }
}
