//! 3-D convex hull by Quickhull (Barber, Dobkin, Huhdanpaa 1996), for hidden point removal.
//!
//! Why not a crate: `parry3d-f64` 0.25 (the maintained Rust hull) took 1.35 s for the
//! 200 000 flipped points of one view on this project's 2-core machine, single-threaded, and
//! pulls a second nalgebra version; hidden point removal needs "well under a second" per view.
//! This implementation takes about a tenth of that (see `docs/generator.md`).
//!
//! The algorithm: a starting tetrahedron; every other point is filed in the outside set of the
//! first face it lies above (by more than `eps`); repeatedly the furthest point of some
//! outside set (the "eye") is added: the faces it sees are found by a depth-first walk that
//! also yields their boundary (the horizon) as one ordered loop, a fan of new faces joins the
//! horizon to the eye, and the seen faces' outside points are refiled among the new faces
//! (or dropped: they are inside). Points within `eps` of a face count as on it, not above
//! it, so only vertices that stick out by more than rounding noise are reported.
//!
//! `eps = 8 · ε_f64 · (max|x| + max|y| + max|z|)`, the scale of the rounding error of a
//! plane distance. If rounding ever makes the seen region non-simple (its boundary is not
//! one loop), that eye is treated as lying on the hull and skipped; [`Hull::skipped`] counts
//! these (0 in every test and real view so far).

const NONE: u32 = u32::MAX;

/// Why no hull could be built.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HullError {
    /// Fewer than four points not on one plane (within rounding).
    Degenerate(&'static str),
    /// A coordinate is NaN or infinite.
    NonFinite,
}

impl std::fmt::Display for HullError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HullError::Degenerate(w) => write!(f, "no 3-D convex hull: {w}"),
            HullError::NonFinite => write!(f, "no 3-D convex hull: a coordinate is not finite"),
        }
    }
}

/// A convex hull: its vertices and outward-oriented triangles (counter-clockwise seen from
/// outside), both as indices into the input.
#[derive(Debug, Clone)]
pub struct Hull {
    /// Indices of the points that are hull vertices, ascending.
    pub vertices: Vec<u32>,
    pub triangles: Vec<[u32; 3]>,
    /// Eyes skipped because rounding made their seen region non-simple.
    pub skipped: usize,
}

#[derive(Clone)]
struct Face {
    v: [u32; 3],
    /// `adj[k]` is the face across the edge `v[k] → v[(k + 1) % 3]`.
    adj: [u32; 3],
    normal: [f64; 3],
    offset: f64,
    /// Head of the linked list of outside points (`next` links them).
    outside: u32,
    furthest: u32,
    furthest_dist: f64,
    alive: bool,
    /// Visit stamp of the last horizon search that found this face visible.
    seen: u32,
}

fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: &[f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

struct Builder<'a> {
    pts: &'a [[f64; 3]],
    eps: f64,
    faces: Vec<Face>,
    free: Vec<u32>,
    next: Vec<u32>,
    stamp: u32,
    skipped: usize,
}

impl<'a> Builder<'a> {
    fn dist(&self, f: u32, p: u32) -> f64 {
        let face = &self.faces[f as usize];
        dot(&face.normal, &self.pts[p as usize]) - face.offset
    }

    fn new_face(&mut self, v: [u32; 3]) -> u32 {
        let (a, b, c) = (
            &self.pts[v[0] as usize],
            &self.pts[v[1] as usize],
            &self.pts[v[2] as usize],
        );
        let n = cross(&sub(b, a), &sub(c, a));
        let len = norm(&n);
        // A zero-area face (its corners collinear within rounding) gets a zero normal: no
        // point is ever above it, and its neighbours still link through it.
        let normal = if len > 0.0 {
            [n[0] / len, n[1] / len, n[2] / len]
        } else {
            [0.0; 3]
        };
        let face = Face {
            v,
            adj: [NONE; 3],
            normal,
            offset: dot(&normal, a),
            outside: NONE,
            furthest: NONE,
            furthest_dist: 0.0,
            alive: true,
            seen: 0,
        };
        match self.free.pop() {
            Some(slot) => {
                self.faces[slot as usize] = face;
                slot
            }
            None => {
                self.faces.push(face);
                (self.faces.len() - 1) as u32
            }
        }
    }

    fn push_outside(&mut self, f: u32, p: u32, d: f64) {
        let face = &mut self.faces[f as usize];
        self.next[p as usize] = face.outside;
        face.outside = p;
        if face.furthest == NONE || d > face.furthest_dist {
            face.furthest = p;
            face.furthest_dist = d;
        }
    }

    /// File `p` with the first of `candidates` it lies above; false if none (inside).
    fn file_point(&mut self, p: u32, candidates: &[u32]) -> bool {
        for &f in candidates {
            let d = self.dist(f, p);
            if d > self.eps {
                self.push_outside(f, p, d);
                return true;
            }
        }
        false
    }

    /// Remove `p` from face `f`'s outside list and recompute its furthest point.
    fn drop_outside(&mut self, f: u32, p: u32) {
        let mut prev = NONE;
        let mut cur = self.faces[f as usize].outside;
        while cur != NONE {
            let nx = self.next[cur as usize];
            if cur == p {
                if prev == NONE {
                    self.faces[f as usize].outside = nx;
                } else {
                    self.next[prev as usize] = nx;
                }
                break;
            }
            prev = cur;
            cur = nx;
        }
        let (mut best, mut best_d) = (NONE, 0.0);
        let mut cur = self.faces[f as usize].outside;
        while cur != NONE {
            let d = self.dist(f, cur);
            if best == NONE || d > best_d {
                best = cur;
                best_d = d;
            }
            cur = self.next[cur as usize];
        }
        let face = &mut self.faces[f as usize];
        face.furthest = best;
        face.furthest_dist = best_d;
    }

    /// Faces seen from `eye` reachable from `start`, and the horizon as an ordered list of
    /// `(a, b, beyond_face, edge_index_in_beyond)`.
    fn horizon(
        &mut self,
        start: u32,
        eye: u32,
        visible: &mut Vec<u32>,
        horizon: &mut Vec<(u32, u32, u32, usize)>,
    ) {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            for f in &mut self.faces {
                f.seen = 0;
            }
            self.stamp = 1;
        }
        let stamp = self.stamp;
        visible.clear();
        horizon.clear();
        self.faces[start as usize].seen = stamp;
        visible.push(start);
        // (face, first edge to look at, edges looked at so far)
        let mut stack: Vec<(u32, usize, usize)> = vec![(start, 0, 0)];
        while let Some(top) = stack.last_mut() {
            let (f, first, count) = *top;
            if count == 3 || (count == 2 && f != start) {
                stack.pop();
                continue;
            }
            top.2 += 1;
            let k = (first + count) % 3;
            let g = self.faces[f as usize].adj[k];
            if self.faces[g as usize].seen == stamp {
                continue;
            }
            let back = (0..3)
                .find(|&j| self.faces[g as usize].adj[j] == f)
                .expect("hull adjacency is symmetric");
            if self.dist(g, eye) > self.eps {
                self.faces[g as usize].seen = stamp;
                visible.push(g);
                stack.push((g, (back + 1) % 3, 0));
            } else {
                let fv = self.faces[f as usize].v;
                horizon.push((fv[k], fv[(k + 1) % 3], g, back));
            }
        }
    }

    fn build(mut self, simplex: [u32; 4]) -> Hull {
        let ids = self.tetrahedron(simplex);
        for p in 0..self.pts.len() as u32 {
            if simplex.contains(&p) {
                continue;
            }
            self.file_point(p, &ids);
        }
        let mut pending: Vec<u32> = ids;
        let mut step = Step::default();
        while let Some(f) = pending.pop() {
            let face = &self.faces[f as usize];
            if !face.alive || face.outside == NONE {
                continue;
            }
            let eye = face.furthest;
            self.horizon(f, eye, &mut step.visible, &mut step.horizon);
            let h = &step.horizon;
            let m = h.len();
            if !(m >= 3 && (0..m).all(|i| h[i].1 == h[(i + 1) % m].0)) {
                // The horizon is not one closed loop (rounding): give up on this eye.
                self.skipped += 1;
                self.drop_outside(f, eye);
                pending.push(f);
                continue;
            }
            self.add_cone(eye, &mut step);
            for &nf in step.new_faces.iter() {
                if self.faces[nf as usize].outside != NONE {
                    pending.push(nf);
                }
            }
        }
        self.into_hull()
    }

    /// The four faces of the starting simplex, oriented outwards and linked.
    fn tetrahedron(&mut self, simplex: [u32; 4]) -> Vec<u32> {
        let [a, mut b, mut c, d] = simplex;
        // Orient outwards: with d below the plane of (a, b, c), the four faces below are
        // counter-clockwise seen from outside.
        let pa = self.pts[a as usize];
        let n = cross(
            &sub(&self.pts[b as usize], &pa),
            &sub(&self.pts[c as usize], &pa),
        );
        if dot(&n, &sub(&self.pts[d as usize], &pa)) > 0.0 {
            std::mem::swap(&mut b, &mut c);
        }
        let mut ids = Vec::with_capacity(4);
        for v in [[a, b, c], [a, d, b], [b, d, c], [c, d, a]] {
            ids.push(self.new_face(v));
        }
        // Adjacency of the tetrahedron by matching reversed edges.
        for &f in &ids {
            for k in 0..3 {
                let v = self.faces[f as usize].v;
                let (p, q) = (v[k], v[(k + 1) % 3]);
                let g = ids
                    .iter()
                    .copied()
                    .find(|&g| {
                        let w = self.faces[g as usize].v;
                        (0..3).any(|j| w[j] == q && w[(j + 1) % 3] == p)
                    })
                    .expect("tetrahedron edges pair up");
                self.faces[f as usize].adj[k] = g;
            }
        }
        ids
    }

    /// Replaces the visible faces by a cone from `eye` over the horizon: new faces linked to
    /// the faces beyond the horizon and to each other, the visible faces' outside points
    /// filed to the new faces, the visible faces freed.
    fn add_cone(&mut self, eye: u32, step: &mut Step) {
        let m = step.horizon.len();
        step.new_faces.clear();
        for &(p, q, beyond, back) in step.horizon.iter() {
            let nf = self.new_face([p, q, eye]);
            self.faces[nf as usize].adj[0] = beyond;
            self.faces[beyond as usize].adj[back] = nf;
            step.new_faces.push(nf);
        }
        for i in 0..m {
            let nf = step.new_faces[i] as usize;
            self.faces[nf].adj[1] = step.new_faces[(i + 1) % m];
            self.faces[nf].adj[2] = step.new_faces[(i + m - 1) % m];
        }
        for &vf in step.visible.iter() {
            let mut cur = self.faces[vf as usize].outside;
            while cur != NONE {
                let nx = self.next[cur as usize];
                if cur != eye {
                    self.file_point(cur, &step.new_faces);
                }
                cur = nx;
            }
            let face = &mut self.faces[vf as usize];
            face.alive = false;
            face.outside = NONE;
        }
        self.free.extend_from_slice(&step.visible);
    }

    /// The live faces and the points they use.
    fn into_hull(self) -> Hull {
        let mut is_vertex = vec![false; self.pts.len()];
        let mut triangles = Vec::new();
        for f in self.faces.iter().filter(|f| f.alive) {
            for &v in &f.v {
                is_vertex[v as usize] = true;
            }
            triangles.push(f.v);
        }
        let vertices = (0..self.pts.len() as u32)
            .filter(|&i| is_vertex[i as usize])
            .collect();
        Hull {
            vertices,
            triangles,
            skipped: self.skipped,
        }
    }
}

/// Buffers of one step of the hull's growth, reused across steps.
#[derive(Default)]
struct Step {
    visible: Vec<u32>,
    /// Horizon edges `(p, q, face beyond, its edge index)`, in loop order.
    horizon: Vec<(u32, u32, u32, usize)>,
    new_faces: Vec<u32>,
}

/// The convex hull of `pts`.
pub fn convex_hull(pts: &[[f64; 3]]) -> Result<Hull, HullError> {
    if pts.iter().any(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(HullError::NonFinite);
    }
    if pts.len() < 4 {
        return Err(HullError::Degenerate("fewer than 4 points"));
    }
    if pts.len() >= NONE as usize {
        return Err(HullError::Degenerate("too many points (at most 2^32 - 2)"));
    }
    let mut scale = [0.0f64; 3];
    for p in pts {
        for k in 0..3 {
            scale[k] = scale[k].max(p[k].abs());
        }
    }
    let eps = 8.0 * f64::EPSILON * (scale[0] + scale[1] + scale[2]);
    // Extreme points along the axes; the two furthest apart start the simplex.
    let mut ext = [0u32; 6];
    for (i, p) in pts.iter().enumerate() {
        for k in 0..3 {
            if p[k] < pts[ext[2 * k] as usize][k] {
                ext[2 * k] = i as u32;
            }
            if p[k] > pts[ext[2 * k + 1] as usize][k] {
                ext[2 * k + 1] = i as u32;
            }
        }
    }
    let (mut a, mut b, mut best) = (0u32, 0u32, -1.0);
    for i in 0..6 {
        for j in i + 1..6 {
            let d = norm(&sub(&pts[ext[i] as usize], &pts[ext[j] as usize]));
            if d > best {
                (a, b, best) = (ext[i], ext[j], d);
            }
        }
    }
    if best <= eps {
        return Err(HullError::Degenerate("all points coincide"));
    }
    let pa = pts[a as usize];
    let ab = sub(&pts[b as usize], &pa);
    let (mut c, mut best) = (0u32, -1.0);
    for (i, p) in pts.iter().enumerate() {
        let d = norm(&cross(&sub(p, &pa), &ab)) / norm(&ab);
        if d > best {
            (c, best) = (i as u32, d);
        }
    }
    if best <= eps {
        return Err(HullError::Degenerate("all points lie on one line"));
    }
    let n = cross(&ab, &sub(&pts[c as usize], &pa));
    let nl = norm(&n);
    let (mut d, mut best) = (0u32, -1.0);
    for (i, p) in pts.iter().enumerate() {
        let h = (dot(&n, &sub(p, &pa)) / nl).abs();
        if h > best {
            (d, best) = (i as u32, h);
        }
    }
    if best <= eps {
        return Err(HullError::Degenerate("all points lie on one plane"));
    }
    let builder = Builder {
        pts,
        eps,
        faces: Vec::with_capacity(pts.len().min(1 << 20)),
        free: Vec::new(),
        next: vec![NONE; pts.len()],
        stamp: 0,
        skipped: 0,
    };
    Ok(builder.build([a, b, c, d]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ggs::test_rng::uniform;

    fn check_convex(pts: &[[f64; 3]], hull: &Hull) {
        let scale = pts
            .iter()
            .flat_map(|p| p.iter())
            .fold(0.0f64, |m, c| m.max(c.abs()));
        for t in &hull.triangles {
            let (a, b, c) = (pts[t[0] as usize], pts[t[1] as usize], pts[t[2] as usize]);
            let n = cross(&sub(&b, &a), &sub(&c, &a));
            let l = norm(&n);
            if l == 0.0 {
                continue;
            }
            for p in pts {
                let h = dot(&n, &sub(p, &a)) / l;
                assert!(h <= 1e-9 * scale, "point above a hull face by {h}");
            }
        }
        // Closed 2-manifold: V − E + F = 2 with E = 3F/2.
        let f = hull.triangles.len() as i64;
        assert_eq!(hull.vertices.len() as i64 - 3 * f / 2 + f, 2);
    }

    #[test]
    fn cube_corners_and_interior() {
        let mut pts = vec![];
        for i in 0..8 {
            pts.push([(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64]);
        }
        let mut r = uniform(3);
        for _ in 0..500 {
            pts.push([0.01 + 0.98 * r(), 0.01 + 0.98 * r(), 0.01 + 0.98 * r()]);
        }
        let hull = convex_hull(&pts).unwrap();
        assert_eq!(hull.vertices, (0..8).collect::<Vec<u32>>());
        assert_eq!(hull.skipped, 0);
        check_convex(&pts, &hull);
    }

    #[test]
    fn points_on_a_sphere_are_all_vertices() {
        let mut r = uniform(11);
        let pts: Vec<[f64; 3]> = (0..3000)
            .map(|_| loop {
                let v = [2.0 * r() - 1.0, 2.0 * r() - 1.0, 2.0 * r() - 1.0];
                let l = norm(&v);
                if l > 0.1 && l < 1.0 {
                    break [v[0] / l, v[1] / l, v[2] / l];
                }
            })
            .collect();
        let hull = convex_hull(&pts).unwrap();
        assert_eq!(hull.vertices.len(), pts.len());
        assert_eq!(hull.skipped, 0);
        check_convex(&pts, &hull);
    }

    #[test]
    fn random_ball_matches_brute_force_extremes() {
        let mut r = uniform(5);
        let pts: Vec<[f64; 3]> = (0..2000)
            .map(|_| [r() - 0.5, 2.0 * r() - 1.0, 0.3 * r()])
            .collect();
        let hull = convex_hull(&pts).unwrap();
        check_convex(&pts, &hull);
        // Every point extreme in some direction is a vertex.
        let mut dirs = uniform(6);
        for _ in 0..200 {
            let d = [dirs() - 0.5, dirs() - 0.5, dirs() - 0.5];
            let best = (0..pts.len())
                .max_by(|&i, &j| dot(&pts[i], &d).total_cmp(&dot(&pts[j], &d)))
                .unwrap();
            assert!(hull.vertices.contains(&(best as u32)));
        }
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let plane: Vec<[f64; 3]> = (0..20).map(|i| [i as f64, (i * i) as f64, 0.0]).collect();
        assert!(matches!(
            convex_hull(&plane),
            Err(HullError::Degenerate(m)) if m.contains("plane")
        ));
        let line: Vec<[f64; 3]> = (0..20).map(|i| [i as f64; 3]).collect();
        assert!(matches!(convex_hull(&line), Err(HullError::Degenerate(_))));
        assert!(convex_hull(&[[0.0; 3]; 3]).is_err());
        assert_eq!(
            convex_hull(&[
                [0.0; 3],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, f64::NAN]
            ])
            .unwrap_err(),
            HullError::NonFinite
        );
    }

    #[test]
    fn duplicates_and_coplanar_grid_points() {
        // A cube sampled on a grid, with repeated points: the 8 corners are vertices, and
        // nothing inside is (coplanar boundary points may be, as ties decide).
        let mut pts = vec![];
        for i in 0..=4 {
            for j in 0..=4 {
                for k in 0..=4 {
                    pts.push([i as f64, j as f64, k as f64]);
                }
            }
        }
        pts.extend_from_within(0..10);
        let hull = convex_hull(&pts).unwrap();
        for corner in [0u32, 4, 20, 24, 100, 104, 120, 124] {
            assert!(hull.vertices.contains(&corner));
        }
        for &v in &hull.vertices {
            assert!(pts[v as usize].iter().any(|&c| c == 0.0 || c == 4.0));
        }
        assert_eq!(hull.skipped, 0);
        check_convex(&pts, &hull);
    }
}
