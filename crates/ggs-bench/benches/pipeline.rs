//! Stage benchmarks on the bundled PCL bunny pair (tests/data, ~400 points each):
//! `cargo bench -p ggs-bench --bench pipeline`. For the large real pairs see docs/grid-search.md and
//! docs/refinement.md (whole-process timings with `ggs register --json`).

use criterion::{criterion_group, criterion_main, Criterion};
use ggs::io::read_cloud;
use ggs::refine::{refine, RefineConfig};
use ggs::rotations::RotationSet;
use ggs::search::{grid_search, SearchConfig};
use std::path::PathBuf;

fn data(name: &str) -> ggs::Cloud {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data")
        .join(name);
    read_cloud(&p, None).expect("bundled fixture").cloud
}

fn pipeline(c: &mut Criterion) {
    let source = data("bun0.pcd");
    let target = data("bun4.pcd");
    let set = RotationSet::named("limited15").unwrap();
    let mut g = c.benchmark_group("pcl_bun0_bun4");
    g.sample_size(10);
    g.bench_function("rotation set limited15", |b| {
        b.iter(|| RotationSet::named("limited15").unwrap())
    });
    for threads in [1, 2] {
        let cfg = SearchConfig {
            threads,
            ..SearchConfig::with_voxel(0.006)
        };
        g.bench_function(format!("coarse limited15 6mm, {threads} thread(s)"), |b| {
            b.iter(|| grid_search(&source, &target, &set, &cfg).unwrap())
        });
    }
    let coarse = grid_search(&source, &target, &set, &SearchConfig::with_voxel(0.006))
        .unwrap()
        .transform();
    g.bench_function("gicp from coarse", |b| {
        b.iter(|| refine(&source, &target, &coarse, &RefineConfig::default()).unwrap())
    });
    g.finish();
}

criterion_group!(benches, pipeline, partial_views);
criterion_main!(benches);

/// Hidden point removal of 200 000 points sampled on the bundled SMPL body, one camera.
fn partial_views(c: &mut Criterion) {
    use ggs_bench::generator::{hpr, sampling, viewpoints};
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/human_woman.obj");
    let bytes = std::fs::read(&p).expect("bundled mesh");
    let mesh = ggs::io::mesh::parse_obj(&p, &bytes).expect("mesh");
    let pts = sampling::sample_surface(&mesh, 200_000, 0).expect("samples");
    let off = viewpoints::floor_offset(&pts);
    let floor: Vec<[f64; 3]> = pts
        .iter()
        .map(|p| [p[0] + off[0], p[1] + off[1], p[2] + off[2]])
        .collect();
    let cams = viewpoints::cameras(&floor, &viewpoints::ViewConfig::default());
    let radius = hpr::flip_radius(&floor, 1000.0);
    let mut g = c.benchmark_group("human_woman_200k");
    g.sample_size(10);
    g.bench_function("sample 200k points", |b| {
        b.iter(|| sampling::sample_surface(&mesh, 200_000, 0).unwrap())
    });
    g.bench_function("hidden point removal, camera 0", |b| {
        b.iter(|| hpr::visible_points(&floor, &cams[0], radius).unwrap())
    });
    g.finish();
}
