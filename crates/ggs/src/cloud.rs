//! The point cloud: an ordered list of 3-D points in the units of the input file.

use crate::error::{GgsError, Result};
pub use crate::transform::Point;
use crate::transform::Rigid;

/// An ordered point cloud. Order is kept from the file, so results are reproducible.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cloud {
    pub points: Vec<Point>,
}

/// Axis-aligned bounding box, `min` and `max` per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: Point,
    pub max: Point,
}

impl Aabb {
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
    let first = *points.first()?;
    let mut min = first;
    let mut max = first;
    for p in points {
        for d in 0..3 {
            min[d] = min[d].min(p[d]);
            max[d] = max[d].max(p[d]);
        }
    }
    Some(Aabb { min, max })
}

impl Cloud {
    pub fn new(points: Vec<Point>) -> Self {
        Cloud { points }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Error out, naming `what`, if the cloud has no point.
    pub fn ensure_not_empty(&self, what: &str) -> Result<()> {
        if self.points.is_empty() {
            return Err(GgsError::EmptyCloud {
                what: what.to_string(),
                detail: String::new(),
            });
        }
        Ok(())
    }

    /// Bounding box; `None` for an empty cloud.
    pub fn aabb(&self) -> Option<Aabb> {
        bounds(&self.points)
    }

    /// Arithmetic mean of the points, summed in file order (deterministic); `None` if empty.
    pub fn centroid(&self) -> Option<Point> {
        centroid_of(&self.points)
    }

    /// Apply `p ↦ R·p + t` to every point (`m` is a row-major 4×4 rigid transform).
    pub fn transformed(&self, m: &Rigid) -> Cloud {
        Cloud {
            points: self.points.iter().map(|p| m.apply(p)).collect(),
        }
    }

    /// Drop points with a NaN or infinite coordinate; returns how many were dropped.
    pub fn drop_non_finite(&mut self) -> usize {
        drop_non_finite(&mut self.points)
    }
}

/// Remove the points with a NaN or infinite coordinate, in place; returns how many.
pub fn drop_non_finite(points: &mut Vec<Point>) -> usize {
    let before = points.len();
    points.retain(|p| p.iter().all(|v| v.is_finite()));
    before - points.len()
}

/// Arithmetic mean of `points`, summed in order (deterministic); `None` if empty.
pub fn centroid_of(points: &[Point]) -> Option<Point> {
    if points.is_empty() {
        return None;
    }
    let mut s = [0.0f64; 3];
    for p in points {
        s[0] += p[0];
        s[1] += p[1];
        s[2] += p[2];
    }
    let n = points.len() as f64;
    Some([s[0] / n, s[1] / n, s[2] / n])
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
    fn drops_non_finite() {
        let mut c = Cloud::new(vec![
            [0.0, f64::NAN, 0.0],
            [1.0, 1.0, 1.0],
            [f64::INFINITY, 0.0, 0.0],
        ]);
        assert_eq!(c.drop_non_finite(), 2);
        assert_eq!(c.points, vec![[1.0, 1.0, 1.0]]);
    }
}
