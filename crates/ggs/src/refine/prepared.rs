//! A pair of clouds prepared once for any number of refinements: both moved into one frame,
//! their k-d trees and their local shapes (normals, GICP covariances) built on first use and
//! kept. Verifying several hypotheses of one pair, or refining one pose in stages, then pays
//! for the trees and the shapes once (a shape is a pure function of the cloud and the point,
//! so sharing it changes no result).
//!
//! The frame is centred on the target's origin `c` (the centre of its bounding box, see
//! [`Cloud`]): georeferenced clouds (UTM coordinates of 1e6 m) would otherwise lose precision
//! in the cross products and sums. Each point arrives as `(its cloud's origin − c) + offset`,
//! so the clouds' shapes are kept exactly. A transform `T` of
//! the clouds' frame is `T_local = Tr(−c)·T·Tr(c)` here, and `T = Tr(c)·T_local·Tr(−c)`.

use super::covariance::{LazyShapes, LocalShape};
use super::neighbors::PointIndex;
use crate::cloud::{Cloud, Point};
use crate::error::{GgsError, Result};
use crate::thin::cell_centroids;
use crate::transform::Rigid;
use nalgebra::Vector3;
use std::sync::{Arc, OnceLock};

/// One cloud of a [`PreparedPair`], in the pair's frame.
pub struct PreparedCloud {
    pub points: Vec<Point>,
    neighbors: usize,
    epsilon: f64,
    index: OnceLock<PointIndex>,
    shapes: OnceLock<LazyShapes>,
    /// Local shapes given with the points, one per point ([`PreparedCloud::with_shapes`]):
    /// the cloud then never computes its own.
    known: Option<Arc<[LocalShape]>>,
    median_kth: OnceLock<Option<f64>>,
}

impl PreparedCloud {
    /// `points` (in the frame of the pair they will join), their tree and shapes (of
    /// `neighbors` points, ε along the normal) built on first use.
    pub fn new(points: Vec<Point>, neighbors: usize, epsilon: f64) -> Self {
        PreparedCloud {
            points,
            neighbors,
            epsilon,
            index: OnceLock::new(),
            shapes: OnceLock::new(),
            known: None,
            median_kth: OnceLock::new(),
        }
    }

    /// `points` with their local shapes known already (`shapes[i]` of `points[i]`, shapes
    /// do not change when a cloud is translated, and turn with it): a cloud's shapes computed
    /// once serve every pair it joins.
    pub fn with_shapes(
        points: Vec<Point>,
        shapes: Arc<[LocalShape]>,
        neighbors: usize,
        epsilon: f64,
    ) -> Self {
        assert_eq!(points.len(), shapes.len(), "one shape per point");
        PreparedCloud {
            known: Some(shapes),
            ..Self::new(points, neighbors, epsilon)
        }
    }

    /// Neighbours of a local shape.
    pub fn neighbors(&self) -> usize {
        self.neighbors
    }

    /// GICP's ε along a local shape's normal.
    pub fn epsilon(&self) -> f64 {
        self.epsilon
    }

    /// Every point's local shape, computed now where not known (in point order).
    pub fn all_shapes(&self) -> Arc<[LocalShape]> {
        if let Some(k) = &self.known {
            return k.clone();
        }
        self.ensure_shapes(0..self.points.len());
        (0..self.points.len()).map(|i| *self.shape(i)).collect()
    }

    /// [`super::grid::median_kth_distance`] of the points to their `neighbors`-th nearest
    /// (computed on first use and kept: every refinement of the pair starts its correspondence
    /// distance's search there, and it costs 512 k-NN queries, half of that search on the
    /// bunny scans).
    pub fn median_kth_distance(&self) -> Option<f64> {
        *self.median_kth.get_or_init(|| {
            super::grid::median_kth_distance(&self.points, self.index(), self.neighbors)
        })
    }

    /// The k-d tree of the points (built on first use).
    pub fn index(&self) -> &PointIndex {
        self.index.get_or_init(|| PointIndex::new(&self.points))
    }

    /// The local shape of point `i` (its neighbourhood's normal and covariance).
    #[inline]
    pub fn shape(&self, i: usize) -> &LocalShape {
        if let Some(k) = &self.known {
            return &k[i];
        }
        let index = self.index();
        self.shapes
            .get_or_init(|| LazyShapes::new(&self.points, index, self.neighbors, self.epsilon))
            .get(&self.points, index, i)
    }

    /// Compute the local shapes of the points `needed` now, together (see
    /// [`LazyShapes::ensure`]); [`Self::shape`] then only reads them.
    pub fn ensure_shapes(&self, needed: impl IntoIterator<Item = usize>) {
        if self.known.is_some() {
            return;
        }
        let index = self.index();
        self.shapes
            .get_or_init(|| LazyShapes::new(&self.points, index, self.neighbors, self.epsilon))
            .ensure(&self.points, index, needed);
    }

    /// Build the tree and the shape cache now (both are built on first use otherwise); a
    /// cloud of known shapes builds its tree on first use only.
    pub fn prepare(&self) {
        if self.known.is_none() {
            self.shape(0);
        }
    }
}

/// Both clouds non-empty and enough neighbours for a normal.
fn check(source: &Cloud, target: &Cloud, neighbors: usize) -> Result<()> {
    source.ensure_not_empty("source")?;
    target.ensure_not_empty("target")?;
    if neighbors < 3 {
        return Err(GgsError::param(
            "neighbors",
            "need at least 3 neighbours for a normal",
        ));
    }
    Ok(())
}

/// A source and a target prepared for refinement (see the module documentation).
pub struct PreparedPair {
    /// The frame's origin in the clouds' frame: the target's origin.
    centre: Vector3<f64>,
    pub source: Arc<PreparedCloud>,
    pub target: Arc<PreparedCloud>,
    /// Neighbours and ε of the local shapes.
    pub neighbors: usize,
    pub epsilon: f64,
}

impl PreparedPair {
    /// Move both clouds into the target's frame; trees and shapes (of `neighbors` points,
    /// GICP's `epsilon` along the normal) are built on first use.
    pub fn new(source: &Cloud, target: &Cloud, neighbors: usize, epsilon: f64) -> Result<Self> {
        check(source, target, neighbors)?;
        let frame = target.origin();
        let pts = |c: &Cloud| c.in_frame(frame).iter().collect();
        Ok(Self::from_points(
            frame,
            pts(source),
            pts(target),
            neighbors,
            epsilon,
        ))
    }

    /// This pair's clouds thinned again to one point (the mean of this pair's points) per
    /// cell of edge `cell`, in the same frame: a coarser pair at the cost of thinning the
    /// thinned points only.
    pub fn coarsened(&self, cell: f64) -> Self {
        let thin = |c: &PreparedCloud| cell_centroids(&c.points[..], cell);
        let centre = [self.centre.x, self.centre.y, self.centre.z];
        Self::from_points(
            centre,
            thin(&self.source),
            thin(&self.target),
            self.neighbors,
            self.epsilon,
        )
    }

    /// Both clouds thinned to one point (the mean) per cell of edge `cell`, prepared.
    pub fn thinned(
        source: &Cloud,
        target: &Cloud,
        cell: f64,
        neighbors: usize,
        epsilon: f64,
    ) -> Result<Self> {
        check(source, target, neighbors)?;
        let frame = target.origin();
        let thin = |c: &Cloud| cell_centroids(&c.in_frame(frame), cell);
        Ok(Self::from_points(
            frame,
            thin(source),
            thin(target),
            neighbors,
            epsilon,
        ))
    }

    /// The pair of `source` and `target`, given in the frame at `centre`.
    fn from_points(
        centre: Point,
        source: Vec<Point>,
        target: Vec<Point>,
        neighbors: usize,
        epsilon: f64,
    ) -> Self {
        Self::from_clouds(
            centre,
            PreparedCloud::new(source, neighbors, epsilon).into(),
            PreparedCloud::new(target, neighbors, epsilon).into(),
        )
    }

    /// A pair of clouds prepared already, both given in the frame at `centre` (in the clouds'
    /// frame) and for the same neighbours and ε: a cloud shared by several pairs keeps its
    /// tree and shapes.
    pub fn from_clouds(
        centre: Point,
        source: Arc<PreparedCloud>,
        target: Arc<PreparedCloud>,
    ) -> Self {
        assert!(
            source.neighbors == target.neighbors && source.epsilon == target.epsilon,
            "both clouds prepared for the same shapes"
        );
        PreparedPair {
            centre: Vector3::from(centre),
            neighbors: target.neighbors,
            epsilon: target.epsilon,
            source,
            target,
        }
    }

    /// Build the trees and shape grids a refinement uses (each is built on first use
    /// otherwise): the target's always (normals serve every method: point-to-plane residuals,
    /// GICP covariances, the quality report's information matrix), the source's when
    /// `source_shapes` (GICP).
    pub fn prepare(&self, source_shapes: bool) {
        rayon::join(
            || self.target.prepare(),
            || source_shapes.then(|| self.source.prepare()),
        );
    }

    /// `T` of the clouds' frame in the pair's frame.
    pub fn to_local(&self, t: &Rigid) -> Rigid {
        let c = self.centre;
        Rigid::new(t.rotation, t.rotation * c + t.translation - c)
    }

    /// `T` of the pair's frame in the clouds' frame.
    pub fn to_global(&self, t: &Rigid) -> Rigid {
        let c = self.centre;
        Rigid::new(t.rotation, t.translation + c - t.rotation * c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn the_frame_change_round_trips_and_moves_points_alike() {
        let target = Cloud::new(vec![[1e6, 2e6, 3.0], [1e6 + 2.0, 2e6, 5.0]]);
        let source = Cloud::new(vec![[0.5, 0.25, 1.0]]);
        let pair = PreparedPair::new(&source, &target, 20, 1e-3).unwrap();
        let t = Rigid::new(
            *Rotation3::from_euler_angles(0.3, -0.2, 1.1).matrix(),
            Vector3::new(1e6, 2e6 + 1.0, -4.0),
        );
        let local = pair.to_local(&t);
        let back = pair.to_global(&local);
        assert!((back.rotation - t.rotation).amax() < 1e-15);
        assert!((back.translation - t.translation).amax() < 1e-6);
        // T·p in the clouds' frame, shifted by −c, equals T_local·(p − c).
        let p = source.point(0);
        let (g, l) = (t.apply(&p), local.apply(&pair.source.points[0]));
        let c = pair.centre;
        assert!(((g[0] - c.x) - l[0]).abs() < 1e-6 && ((g[2] - c.z) - l[2]).abs() < 1e-6);
        assert!(PreparedPair::new(&source, &target, 2, 1e-3).is_err());
    }
}
