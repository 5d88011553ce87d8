//! Times the neighbour searches behind refinement on one cloud:
//! `cargo run --release --example knn_probe -p ggs -- CLOUD`.
use ggs::refine::{covariance::local_shapes, neighbors::PointIndex};
use std::time::Instant;

fn main() {
    let path = std::env::args().nth(1).expect("usage: knn_probe CLOUD");
    let c = ggs::io::read_cloud(path.as_ref(), None).unwrap().cloud;
    let t = Instant::now();
    let idx = PointIndex::new(&c.points);
    println!("kd-tree build: {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    let t = Instant::now();
    let s: usize = c.points.iter().map(|p| idx.k_nearest(p, 20)[19]).sum();
    println!(
        "kd-tree 20-NN, 1 thread: {:.1} ms ({s})",
        t.elapsed().as_secs_f64() * 1e3
    );
    let t = Instant::now();
    let s: usize = c
        .points
        .iter()
        .map(|p| idx.nearest(&[p[0] + 1e-4, p[1], p[2]]).0)
        .sum();
    println!(
        "kd-tree nearest: {:.1} ms ({s})",
        t.elapsed().as_secs_f64() * 1e3
    );
    let t = Instant::now();
    let sh = local_shapes(&c.points, &idx, 20, 1e-3);
    println!(
        "local shapes, all threads: {:.1} ms ({})",
        t.elapsed().as_secs_f64() * 1e3,
        sh.len()
    );
}
