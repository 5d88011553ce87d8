//! Times the neighbour searches behind refinement on one cloud, on one thread:
//! `cargo bench -p ggs --features internals --bench knn_probe -- CLOUD`.
mod common;

use ggs::refine::covariance::{local_shapes, Moments};
use ggs::refine::grid::{median_kth_distance, CellGrid};
use ggs::refine::neighbors::PointIndex;
use std::time::Instant;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Fastest of five runs, in ms.
fn min_of_5(mut f: impl FnMut()) -> f64 {
    (0..5)
        .map(|_| {
            let t = Instant::now();
            f();
            ms(t)
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let path = common::args().nth(1).expect("usage: knn_probe CLOUD");
    let c = ggs::io::read_cloud(path.as_ref(), None).unwrap().cloud;
    let pts = &c.to_points();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    pool.install(|| {
        let t = Instant::now();
        let idx = PointIndex::new(pts);
        println!("kd-tree build: {:.1} ms", ms(t));
        let best = min_of_5(|| {
            let mut s = 0;
            for p in pts {
                idx.for_k_nearest(p, 20, |j| s += j);
            }
            assert!(s > 0);
        });
        println!("kd-tree 20-NN: {best:.1} ms (min of 5)");
        let t = Instant::now();
        let s: usize = pts
            .iter()
            .map(|p| idx.nearest(&[p[0] + 1e-4, p[1], p[2]]).0)
            .sum();
        println!("kd-tree nearest: {:.1} ms ({s})", ms(t));
        let t = Instant::now();
        let r = median_kth_distance(pts, &idx, 20).unwrap();
        let h = r * 1.6;
        let g = CellGrid::new(pts, h).unwrap();
        println!("grid build: {:.1} ms", ms(t));
        for factor in [0.8, 1.0, 1.2, 1.4, 1.7] {
            let g = CellGrid::new(pts, h * factor).unwrap();
            let best = min_of_5(|| {
                let v = g.map_knn(pts, 20, 1.5 * r, &idx, |_, nb, _| nb.len());
                assert_eq!(v.len(), pts.len());
            });
            println!("grid 20-NN, cell × {factor}: {best:.1} ms (min of 5)");
        }
        let t = Instant::now();
        let s: usize = pts
            .iter()
            .map(|p| {
                g.nearest_within(&[p[0] + 1e-4, p[1], p[2]], 1e-6)
                    .map_or(0, |n| n.0)
            })
            .sum();
        println!("grid nearest within 1 mm: {:.1} ms ({s})", ms(t));
        let t = Instant::now();
        let n: usize = pts
            .chunks(20)
            .map(|ch| {
                let mut m = Moments::new(&ch[0]);
                ch.iter().for_each(|p| m.push(p));
                m.shape(1e-3).normal.len()
            })
            .sum();
        println!(
            "{n} shapes from 20 points each, moments + eigen: {:.1} ms",
            ms(t) * 20.0
        );
        if let Some(r) = common::args().nth(2).and_then(|a| a.parse::<f64>().ok()) {
            let g = CellGrid::new(pts, 2.0 * r).unwrap();
            println!(
                "cells of {}: mean occupancy {:.1}",
                2.0 * r,
                g.mean_occupancy()
            );
        }
        let t = Instant::now();
        let sh = local_shapes(pts, &idx, 20, 1e-3);
        println!("local shapes: {:.1} ms ({})", ms(t), sh.len());
    });
}
