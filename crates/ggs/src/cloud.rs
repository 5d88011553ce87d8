//! The point cloud: an ordered list of 3-D points in the units of the input file.

use crate::error::{GgsError, Result};
pub use crate::transform::Point;
use crate::transform::Rigid;

/// An ordered point cloud. Order is kept from the file, so results are reproducible.
///
/// The points are held once, as `f32` offsets from an `f64` origin: a point is
/// `origin + offset`, in the units of the input file. The origin is the centre of the
/// bounding box of the first [`ORIGIN_POINTS`] points (their finite ones), so a reader can fix
/// it after its first chunk and store the rest as it decodes them; it lies within the
/// cloud's bounding box, so every offset is at most the diagonal. The frame is centred so
/// that `f32` keeps the precision: a coordinate rounds by at most half an `f32` ulp of its
/// offset, `|offset| · 2⁻²⁴ ≤ 2⁻²⁴ × diagonal ≈ 6·10⁻⁸ × diagonal` (6 µm on a 100 m scan,
/// 12 nm on a 20 cm part), whatever the coordinates' size (georeferenced clouds included). That is orders of magnitude below any voxel the search
/// uses and below scanner noise, and it halves the memory of `f64` points (12 bytes a
/// point). Every computation reads the points back as `f64` ([`Cloud::point`],
/// [`Cloud::iter`]). NaN and infinite coordinates are kept as they are until
/// [`Cloud::drop_non_finite`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cloud {
    origin: Point,
    offsets: Vec<[f32; 3]>,
}

/// Axis-aligned bounding box, `min` and `max` per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: Point,
    pub max: Point,
}

impl Aabb {
    /// `(min + max) / 2` per axis.
    pub fn centre(&self) -> Point {
        [0, 1, 2].map(|d| 0.5 * (self.min[d] + self.max[d]))
    }

    /// `max − min` per axis.
    pub fn extent(&self) -> Point {
        [
            self.max[0] - self.min[0],
            self.max[1] - self.min[1],
            self.max[2] - self.min[2],
        ]
    }

    /// Length of the box diagonal.
    pub fn diagonal(&self) -> f64 {
        let e = self.extent();
        (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()
    }
}

/// Axis-aligned bounding box of `points`; `None` if empty.
pub fn bounds(points: &[Point]) -> Option<Aabb> {
    bounds_of(points.iter().copied())
}

impl Cloud {
    /// The cloud of `points` (see [`Cloud`] for its frame).
    pub fn new(points: Vec<Point>) -> Self {
        CloudBuilder::from_vec(points)
    }

    /// The cloud with points `origin + offsets[i]`.
    pub fn from_offsets(origin: Point, offsets: Vec<[f32; 3]>) -> Self {
        Cloud { origin, offsets }
    }

    /// The frame's origin (world coordinates): every point is `origin + offset`.
    pub fn origin(&self) -> Point {
        self.origin
    }

    /// The points' offsets from [`Cloud::origin`], in file order.
    pub fn offsets(&self) -> &[[f32; 3]] {
        &self.offsets
    }

    pub fn len(&self) -> usize {
        self.offsets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.offsets.is_empty()
    }

    /// Point `i` in world coordinates (`origin + offset`, in `f64`).
    #[inline]
    pub fn point(&self, i: usize) -> Point {
        self.world(&self.offsets[i])
    }

    /// The world point of an offset of this cloud.
    #[inline]
    pub fn world(&self, d: &[f32; 3]) -> Point {
        [
            self.origin[0] + d[0] as f64,
            self.origin[1] + d[1] as f64,
            self.origin[2] + d[2] as f64,
        ]
    }

    /// The points in the frame whose origin is `frame` (world coordinates): point `i` is
    /// `(origin − frame) + offset_i`, one rounding for the whole cloud and none per point, so
    /// georeferenced clouds keep their shape exactly.
    pub fn in_frame(&self, frame: Point) -> Reframed<'_> {
        Reframed {
            cloud: self,
            shift: [0, 1, 2].map(|d| self.origin[d] - frame[d]),
        }
    }

    /// The points in world coordinates, in file order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Point> + Clone + '_ {
        self.offsets.iter().map(|d| self.world(d))
    }

    /// A copy of the points as `f64` (for small clouds, writers and tests: 24 bytes a point).
    pub fn to_points(&self) -> Vec<Point> {
        self.iter().collect()
    }

    /// At most `n` points, evenly strided over the file order (every point when `len ≤ n`).
    pub fn strided(&self, n: usize) -> Vec<Point> {
        let step = self.len().div_ceil(n.max(1)).max(1);
        self.offsets
            .iter()
            .step_by(step)
            .map(|d| self.world(d))
            .collect()
    }

    /// The points at `indices`, in their order.
    pub fn select(&self, indices: impl IntoIterator<Item = usize>) -> Cloud {
        Cloud {
            origin: self.origin,
            offsets: indices.into_iter().map(|i| self.offsets[i]).collect(),
        }
    }

    /// Error out, naming `what`, if the cloud has no point.
    pub fn ensure_not_empty(&self, what: &str) -> Result<()> {
        if self.offsets.is_empty() {
            return Err(GgsError::EmptyCloud {
                what: what.to_string(),
                detail: String::new(),
            });
        }
        Ok(())
    }

    /// Bounding box; `None` for an empty cloud.
    pub fn aabb(&self) -> Option<Aabb> {
        bounds_of(self.iter())
    }

    /// Arithmetic mean of the points, summed in file order (deterministic); `None` if empty.
    pub fn centroid(&self) -> Option<Point> {
        centroid_iter(self.iter())
    }

    /// Apply `p ↦ R·p + t` to every point (`m` is a row-major 4×4 rigid transform): the
    /// origin moves by `m`, the offsets turn by `R`.
    pub fn transformed(&self, m: &Rigid) -> Cloud {
        let r = Rigid::new(m.rotation, nalgebra::Vector3::zeros());
        Cloud {
            origin: m.apply(&self.origin),
            offsets: self
                .offsets
                .iter()
                .map(|d| {
                    let q = r.apply(&[d[0] as f64, d[1] as f64, d[2] as f64]);
                    [q[0] as f32, q[1] as f32, q[2] as f32]
                })
                .collect(),
        }
    }

    /// Drop points with a NaN or infinite coordinate; returns how many were dropped.
    pub fn drop_non_finite(&mut self) -> usize {
        let before = self.offsets.len();
        self.offsets.retain(|d| d.iter().all(|v| v.is_finite()));
        before - self.offsets.len()
    }
}

/// Random access to points in world coordinates, for algorithms that take either a plain
/// `f64` list or a [`Cloud`] without copying it.
pub trait PointAccess: Sync {
    /// Number of points.
    fn count(&self) -> usize;
    /// Point `i` (`i < count()`), in world coordinates.
    fn at(&self, i: usize) -> Point;
}

impl PointAccess for [Point] {
    fn count(&self) -> usize {
        self.len()
    }
    #[inline]
    fn at(&self, i: usize) -> Point {
        self[i]
    }
}

impl PointAccess for Vec<Point> {
    fn count(&self) -> usize {
        self.len()
    }
    #[inline]
    fn at(&self, i: usize) -> Point {
        self[i]
    }
}

impl<const N: usize> PointAccess for [Point; N] {
    fn count(&self) -> usize {
        N
    }
    #[inline]
    fn at(&self, i: usize) -> Point {
        self[i]
    }
}

impl PointAccess for Cloud {
    fn count(&self) -> usize {
        self.len()
    }
    #[inline]
    fn at(&self, i: usize) -> Point {
        self.point(i)
    }
}

/// Points that fix a cloud's origin (see [`Cloud`]).
pub const ORIGIN_POINTS: usize = 1 << 16;

/// Where a reader puts the points it decodes, chunk by chunk in file order: a plain `f64`
/// list (`Vec<Point>`, exact) or a [`Cloud`] ([`CloudBuilder`], 12 bytes a point).
pub trait PointStore: Send + Sized {
    type Out;
    /// An empty store with room for `n` points.
    fn with_capacity(n: usize) -> Self;
    /// Append `chunk`, in order.
    fn extend_from(&mut self, chunk: &[Point]);
    fn finish(self) -> Self::Out;
    /// The store's result for all of `points` at once.
    fn from_vec(points: Vec<Point>) -> Self::Out {
        let mut s = Self::with_capacity(points.len());
        s.extend_from(&points);
        s.finish()
    }
}

impl PointStore for Vec<Point> {
    type Out = Vec<Point>;
    fn with_capacity(n: usize) -> Self {
        Vec::with_capacity(n)
    }
    fn extend_from(&mut self, chunk: &[Point]) {
        self.extend_from_slice(chunk);
    }
    fn finish(self) -> Vec<Point> {
        self
    }
    fn from_vec(points: Vec<Point>) -> Vec<Point> {
        points
    }
}

/// Builds a [`Cloud`] from points given chunk by chunk: the first [`ORIGIN_POINTS`] are kept
/// as `f64` until they fix the origin, every later point is stored as its offset at once.
#[derive(Debug, Default)]
pub struct CloudBuilder {
    origin: Option<Point>,
    pending: Vec<Point>,
    offsets: Vec<[f32; 3]>,
}

impl CloudBuilder {
    fn fix_origin(&mut self) {
        let o = finite_centre(self.pending.iter());
        self.offsets
            .extend(self.pending.iter().map(|p| offset_of(p, &o)));
        self.pending = Vec::new();
        self.origin = Some(o);
    }
}

impl PointStore for CloudBuilder {
    type Out = Cloud;
    fn with_capacity(n: usize) -> Self {
        CloudBuilder {
            origin: None,
            pending: Vec::with_capacity(n.min(ORIGIN_POINTS)),
            offsets: Vec::with_capacity(n),
        }
    }
    fn extend_from(&mut self, mut chunk: &[Point]) {
        use rayon::prelude::*;
        if self.origin.is_none() {
            let take = (ORIGIN_POINTS - self.pending.len()).min(chunk.len());
            self.pending.extend_from_slice(&chunk[..take]);
            chunk = &chunk[take..];
            if self.pending.len() < ORIGIN_POINTS {
                return;
            }
            self.fix_origin();
        }
        let o = self.origin.expect("fixed above");
        self.offsets
            .par_extend(chunk.par_iter().map(|p| offset_of(p, &o)));
    }
    fn finish(mut self) -> Cloud {
        if self.origin.is_none() {
            self.fix_origin();
        }
        Cloud {
            origin: self.origin.expect("fixed above"),
            offsets: self.offsets,
        }
    }
}

/// A cloud seen from another frame (see [`Cloud::in_frame`]).
#[derive(Clone, Copy)]
pub struct Reframed<'a> {
    cloud: &'a Cloud,
    shift: Point,
}

impl Reframed<'_> {
    /// The points in this frame, in file order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Point> + '_ {
        (0..self.cloud.len()).map(|i| self.at(i))
    }
}

impl PointAccess for Reframed<'_> {
    fn count(&self) -> usize {
        self.cloud.len()
    }
    #[inline]
    fn at(&self, i: usize) -> Point {
        let d = &self.cloud.offsets[i];
        [
            self.shift[0] + d[0] as f64,
            self.shift[1] + d[1] as f64,
            self.shift[2] + d[2] as f64,
        ]
    }
}

/// `p − origin`, rounded to `f32`.
#[inline]
fn offset_of(p: &Point, origin: &Point) -> [f32; 3] {
    [
        (p[0] - origin[0]) as f32,
        (p[1] - origin[1]) as f32,
        (p[2] - origin[2]) as f32,
    ]
}

/// Centre of the bounding box of the finite points (the origin where there is none).
fn finite_centre<'a>(points: impl Iterator<Item = &'a Point>) -> Point {
    let finite = points.filter(|p| p.iter().all(|v| v.is_finite())).copied();
    match bounds_of(finite) {
        Some(b) => [0, 1, 2].map(|d| 0.5 * (b.min[d] + b.max[d])),
        None => [0.0; 3],
    }
}

/// Axis-aligned bounding box of the points `at(0..n)`; `None` if `n` is 0.
pub fn bounds_by(n: usize, at: impl Fn(usize) -> Point) -> Option<Aabb> {
    bounds_of((0..n).map(at))
}

/// Axis-aligned bounding box of `points`; `None` if empty.
fn bounds_of(mut points: impl Iterator<Item = Point>) -> Option<Aabb> {
    let first = points.next()?;
    let (mut min, mut max) = (first, first);
    for p in points {
        for d in 0..3 {
            min[d] = min[d].min(p[d]);
            max[d] = max[d].max(p[d]);
        }
    }
    Some(Aabb { min, max })
}

/// Arithmetic mean, summed in order; `None` if empty.
fn centroid_iter(points: impl ExactSizeIterator<Item = Point>) -> Option<Point> {
    let n = points.len();
    if n == 0 {
        return None;
    }
    let mut s = [0.0f64; 3];
    for p in points {
        s[0] += p[0];
        s[1] += p[1];
        s[2] += p[2];
    }
    let n = n as f64;
    Some([s[0] / n, s[1] / n, s[2] / n])
}

/// Remove the points with a NaN or infinite coordinate, in place; returns how many.
pub fn drop_non_finite(points: &mut Vec<Point>) -> usize {
    let before = points.len();
    points.retain(|p| p.iter().all(|v| v.is_finite()));
    before - points.len()
}

/// Arithmetic mean of `points`, summed in order (deterministic); `None` if empty.
pub fn centroid_of(points: &[Point]) -> Option<Point> {
    centroid_iter(points.iter().copied())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aabb_and_centroid() {
        let c = Cloud::new(vec![[0.0, 1.0, 2.0], [2.0, -1.0, 4.0]]);
        let b = c.aabb().unwrap();
        assert_eq!(b.min, [0.0, -1.0, 2.0]);
        assert_eq!(b.max, [2.0, 1.0, 4.0]);
        assert_eq!(c.centroid().unwrap(), [1.0, 0.0, 3.0]);
        assert!(Cloud::default().aabb().is_none());
        assert!(Cloud::default().ensure_not_empty("x").is_err());
    }

    #[test]
    fn a_cloud_built_chunk_by_chunk_is_the_cloud_of_all_points() {
        let mut r = crate::test_rng::uniform(5);
        let mut pts: Vec<Point> = (0..150_000)
            .map(|_| [5e5 + 80.0 * r(), 4e6 + 60.0 * r(), 20.0 * r()])
            .collect();
        pts[3] = [f64::NAN, 0.0, 0.0];
        let whole = Cloud::new(pts.clone());
        // Bits, so that the NaN point compares too.
        let bits = |c: &Cloud| -> (Vec<u64>, Vec<u32>) {
            let o = c.origin.iter().map(|v| v.to_bits()).collect();
            (o, c.offsets.iter().flatten().map(|v| v.to_bits()).collect())
        };
        for chunk in [1000, ORIGIN_POINTS - 1, ORIGIN_POINTS, 70_000, 150_000] {
            let mut b = CloudBuilder::with_capacity(10);
            for c in pts.chunks(chunk) {
                b.extend_from(c);
            }
            assert!(bits(&b.finish()) == bits(&whole), "chunk {chunk}");
        }
        // The origin is the centre of the first points' box; every point is within the
        // documented rounding of its f64 value.
        let b = bounds(&pts[4..ORIGIN_POINTS]).unwrap();
        assert_eq!(
            whole.origin(),
            [0, 1, 2].map(|d| 0.5 * (b.min[d] + b.max[d]))
        );
        let diagonal = bounds(&pts[4..]).unwrap().diagonal();
        for (i, p) in pts.iter().enumerate().skip(4) {
            let q = whole.point(i);
            for d in 0..3 {
                assert!((p[d] - q[d]).abs() <= diagonal / (1u64 << 24) as f64, "{i}");
            }
        }
    }

    #[test]
    fn moving_a_cloud_moves_its_points() {
        let c = Cloud::new(vec![
            [1e6, 2.0, 3.0],
            [1e6 + 1.0, 2.5, 3.25],
            [1e6 - 2.0, 0.0, 1.0],
        ]);
        let m = Rigid::new(
            *nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.1).matrix(),
            nalgebra::Vector3::new(5.0, -1.0, 2.0),
        );
        let moved = c.transformed(&m);
        for i in 0..3 {
            let (a, b) = (m.apply(&c.point(i)), moved.point(i));
            assert!((0..3).all(|d| (a[d] - b[d]).abs() < 1e-6), "{a:?} {b:?}");
        }
        assert_eq!(c.strided(2), vec![c.point(0), c.point(2)]);
        assert_eq!(c.select([2, 0]).to_points(), vec![c.point(2), c.point(0)]);
        let f = c.in_frame([1e6, 0.0, 0.0]);
        assert_eq!(f.at(1), [1.0, 2.5, 3.25]);
    }

    #[test]
    fn drops_non_finite() {
        let mut c = Cloud::new(vec![
            [0.0, f64::NAN, 0.0],
            [1.0, 1.0, 1.0],
            [f64::INFINITY, 0.0, 0.0],
        ]);
        assert_eq!(c.drop_non_finite(), 2);
        assert_eq!(c.to_points(), vec![[1.0, 1.0, 1.0]]);
    }
}
