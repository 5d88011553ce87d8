//! Times the exact extents of a rotated source (`RotatableCloud::range`, three rows per
//! rotation of `hopf15-id`) and its voxelization, and checks every extent against a plain
//! loop over the points, bit for bit:
//! `cargo bench -p ggs --features internals --bench range_probe -- CLOUD VOXEL [THIN]`
//! (`THIN` > 0: the cloud first thinned to one point per cell of `VOXEL / THIN`, as the
//! coarse level does with 4).
mod common;

use ggs::rotations::RotationSet;
use ggs::search::extents::rows;
use ggs::search::rotated::{dot_row, GridView, RotatableCloud};
use ggs::{Cloud, Point};
use std::time::Instant;

/// Best of `reps` runs of `f`, in µs per rotation.
fn best_us(reps: usize, rotations: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
        / rotations as f64
        * 1e6
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = common::args().collect();
    if args.len() < 3 {
        return Err("usage: range_probe CLOUD VOXEL [THIN]".into());
    }
    let cloud = ggs::io::read_cloud(std::path::Path::new(&args[1]), None)?.cloud;
    let s: f64 = args[2].parse()?;
    let thin: f64 = args.get(3).map_or(Ok(0.0), |a| a.parse())?;
    let points: Vec<Point> = cloud.iter().collect();
    let points = if thin > 0.0 {
        ggs::thin::cell_centroids(&points, s / thin)
    } else {
        points
    };
    let rc = RotatableCloud::new(&Cloud::new(points));
    let set = RotationSet::named("hopf15-id")?;
    let rs: Vec<[[f64; 3]; 3]> = set.matrices.iter().map(rows).collect();
    let mut boxes = vec![[(0.0, 0.0); 3]; rs.len()];
    let mut scratch = Vec::new();
    let range_us = best_us(7, rs.len(), || {
        for (r, b) in rs.iter().zip(boxes.iter_mut()) {
            *b = std::array::from_fn(|d| rc.range_with(&r[d], &mut scratch));
        }
    });
    let mut mismatches = 0;
    for (r, b) in rs.iter().zip(&boxes) {
        for d in 0..3 {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for p in &rc.points {
                let v = dot_row(&r[d], p);
                lo = lo.min(v);
                hi = hi.max(v);
            }
            mismatches += usize::from(b[d] != (lo, hi));
        }
    }
    let dims: [usize; 3] = std::array::from_fn(|d| {
        boxes
            .iter()
            .map(|b| ((b[d].1 - b[d].0) / s) as usize + 2)
            .max()
            .unwrap_or(1)
    });
    let mut grid = vec![0f32; dims.iter().product()];
    let voxelize_us = best_us(3, rs.len(), || {
        for (r, b) in rs.iter().zip(&boxes) {
            let min = [b[0].0, b[1].0, b[2].0];
            let view = GridView {
                cells: &mut grid,
                sx: dims[1] * dims[2],
                sy: dims[2],
            };
            rc.voxelize(r, &min, s, view);
        }
    });
    println!(
        "{} points, {} rotations: range {range_us:.1} µs, voxelize {voxelize_us:.1} µs a rotation; {mismatches} extents differ from the plain loop",
        rc.points.len(),
        rs.len()
    );
    Ok(())
}
