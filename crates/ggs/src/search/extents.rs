//! The exact box of every rotated copy of the source, hence its grid and the FFT geometry.

use super::geometry::Geometry;
use super::rotated::RotatableCloud;
use super::voxel::{self, Occupancy};
use crate::cloud::{Cloud, Point};
use crate::error::Result;
use nalgebra::Matrix3;

/// The rows of `m`, as the voxelization reads them.
pub fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// Per-rotation min corner and grid dims of the rotated, centred source.
#[derive(Debug, Clone, Copy)]
pub struct RotatedBox {
    /// Min corner of `R·(X − c)`.
    pub min: Point,
    /// Grid dims of that box at the voxel.
    pub dims: [usize; 3],
}

/// Extents of the rotated cloud for the rotations `indices` (entry `k` of the result is
/// `Some` for those, `None` for the others).
pub fn rotated_boxes(
    pool: &rayon::ThreadPool,
    cloud: &RotatableCloud,
    rows: &[[[f64; 3]; 3]],
    indices: &[usize],
    s: f64,
) -> Result<Vec<Option<RotatedBox>>> {
    use rayon::prelude::*;
    let computed: Vec<Result<RotatedBox>> = pool.install(|| {
        indices
            .par_iter()
            .map_init(Vec::new, |scratch, &k| {
                let r = &rows[k];
                let mut lo = [0.0; 3];
                let mut hi = [0.0; 3];
                for d in 0..3 {
                    (lo[d], hi[d]) = cloud.range_with(&r[d], scratch);
                }
                let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
                Ok(RotatedBox {
                    min: lo,
                    dims: voxel::grid_dims(ext, s)?,
                })
            })
            .collect()
    });
    let mut boxes = vec![None; rows.len()];
    for (&k, b) in indices.iter().zip(computed) {
        boxes[k] = Some(b?);
    }
    Ok(boxes)
}

/// FFT geometry for kernel dims `nr` and the largest of `boxes`.
pub fn geometry_for(nr: [usize; 3], boxes: &[Option<RotatedBox>]) -> Geometry {
    let mut ns_max = [1usize; 3];
    for b in boxes.iter().flatten() {
        for d in 0..3 {
            ns_max[d] = ns_max[d].max(b.dims[d]);
        }
    }
    Geometry::new(nr, ns_max)
}

/// Occupancy of `target` shifted by `-min`, at voxel `s`.
pub fn target_kernel(target: &Cloud, min: Point, s: f64) -> Result<Occupancy> {
    Occupancy::from_points(target, min, s)
}
