//! Stage benchmarks of the grid search on a real 40k-point pair (tests/data/bun045.ply →
//! bun000.ply, Stanford bunny, 5 mm voxel, limited15): `cargo bench -p ggs --features internals --bench stages`.
//!
//! Per rotation: voxelize the rotated source, forward FFT (z, y), x stage (FFT, spectrum
//! product, inverse), inverse FFT (y, z) + argmax, each in f32 and f64; then all 1886
//! voxelizations, GICP from the coarse pose, and whole searches (exhaustive and
//! coarse-to-fine). docs/performance.md has the results and the FLOP counts.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use ggs::io::read_cloud;
use ggs::refine::{refine, RefineConfig};
use ggs::rotations::RotationSet;
use ggs::search::cpu::{CpuCorrelator, Geometry, Real, Workspace};
use ggs::search::rotated::RotatableCloud;
use ggs::search::voxel::{grid_dims, Occupancy};
use ggs::search::{grid_search, CoarseToFine, SearchConfig, SearchMode};
use ggs::Cloud;
use std::path::PathBuf;

const VOXEL: f64 = 0.005;

fn data(name: &str) -> Cloud {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data")
        .join(name);
    read_cloud(&p, None).expect("bundled fixture").cloud
}

/// Rotation rows, min corners and grid dims of the rotated source for every rotation.
struct Prepared {
    rows: Vec<[[f64; 3]; 3]>,
    mins: Vec<[f64; 3]>,
    dims: Vec<[usize; 3]>,
    geo: Geometry,
    kernel: Occupancy,
}

fn prepare(rc: &RotatableCloud, target: &Cloud, set: &RotationSet) -> Prepared {
    let rows: Vec<[[f64; 3]; 3]> = set
        .matrices
        .iter()
        .map(|m| std::array::from_fn(|r| [m[(r, 0)], m[(r, 1)], m[(r, 2)]]))
        .collect();
    let mut mins = Vec::new();
    let mut dims = Vec::new();
    let mut ns_max = [1; 3];
    for r in &rows {
        let ranges: [(f64, f64); 3] = std::array::from_fn(|d| rc.range(&r[d]));
        let d = grid_dims(std::array::from_fn(|a| ranges[a].1 - ranges[a].0), VOXEL).unwrap();
        for a in 0..3 {
            ns_max[a] = ns_max[a].max(d[a]);
        }
        mins.push(std::array::from_fn(|a| ranges[a].0));
        dims.push(d);
    }
    let min = target.aabb().unwrap().min;
    let kernel = Occupancy::from_points(target, min, VOXEL).unwrap();
    let geo = Geometry::new(kernel.dims, ns_max);
    Prepared {
        rows,
        mins,
        dims,
        geo,
        kernel,
    }
}

fn voxelized<T: Real>(
    rc: &RotatableCloud,
    p: &Prepared,
    corr: &CpuCorrelator<T>,
    k: usize,
) -> Workspace<T> {
    let mut ws = corr.workspace();
    ws.begin(p.dims[k]);
    rc.voxelize(&p.rows[k], &p.mins[k], VOXEL, ws.grid_mut());
    ws
}

fn per_rotation_stages<T: Real>(c: &mut Criterion, label: &str, rc: &RotatableCloud, p: &Prepared) {
    let corr = CpuCorrelator::<T>::new(p.geo, &p.kernel);
    // The winner of the pair: a typical, fully sized rotated source.
    let k = 52;
    let mut g = c.benchmark_group(format!("bunny 5mm stages {label}"));
    g.bench_function("voxelize one rotation (40k points)", |b| {
        let mut ws = corr.workspace();
        b.iter(|| {
            ws.begin(p.dims[k]);
            rc.voxelize(&p.rows[k], &p.mins[k], VOXEL, ws.grid_mut());
        })
    });
    let fresh = voxelized(rc, p, &corr, k);
    g.bench_function("forward FFT z,y", |b| {
        b.iter_batched_ref(
            || fresh.clone(),
            |ws| corr.stage_forward(ws),
            BatchSize::LargeInput,
        )
    });
    let mut after_forward = fresh.clone();
    corr.stage_forward(&mut after_forward);
    g.bench_function("FFT x, spectrum product, inverse x", |b| {
        b.iter_batched_ref(
            || after_forward.clone(),
            |ws| corr.stage_product(ws),
            BatchSize::LargeInput,
        )
    });
    let mut after_product = after_forward.clone();
    corr.stage_product(&mut after_product);
    g.bench_function("inverse FFT y,z + argmax", |b| {
        b.iter_batched_ref(
            || after_product.clone(),
            |ws| {
                let mut best = T::neg_infinity();
                corr.stage_inverse(ws, |v, _| {
                    if v > best {
                        best = v
                    }
                });
                best
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

fn stages(c: &mut Criterion) {
    let source = data("bun045.ply");
    let target = data("bun000.ply");
    let set = RotationSet::named("limited15").unwrap();
    let rc = RotatableCloud::new(&source);
    let p = prepare(&rc, &target, &set);
    per_rotation_stages::<f32>(c, "f32", &rc, &p);
    per_rotation_stages::<f64>(c, "f64", &rc, &p);

    let mut g = c.benchmark_group("bunny 5mm limited15");
    g.sample_size(10);
    let corr = CpuCorrelator::<f32>::new(p.geo, &p.kernel);
    g.bench_function("voxelize all 1886 rotations, 1 thread", |b| {
        let mut ws = corr.workspace();
        b.iter(|| {
            for k in 0..p.rows.len() {
                ws.begin(p.dims[k]);
                rc.voxelize(&p.rows[k], &p.mins[k], VOXEL, ws.grid_mut());
            }
        })
    });
    for (name, mode) in [
        ("exhaustive", SearchMode::Exhaustive),
        (
            "coarse-to-fine",
            SearchMode::CoarseToFine(CoarseToFine::default()),
        ),
    ] {
        let cfg = SearchConfig {
            threads: 2,
            mode,
            ..SearchConfig::with_voxel(VOXEL)
        };
        g.bench_function(format!("grid search {name}, 2 threads"), |b| {
            b.iter(|| grid_search(&source, &target, &set, &cfg).unwrap())
        });
    }
    let coarse = grid_search(&source, &target, &set, &SearchConfig::with_voxel(VOXEL))
        .unwrap()
        .transform();
    let refine_cfg = RefineConfig {
        threads: 2,
        ..RefineConfig::default()
    };
    g.bench_function("gicp from the coarse pose, 2 threads", |b| {
        b.iter(|| refine(&source, &target, &coarse, &refine_cfg).unwrap())
    });
    g.finish();
}

/// What rustfft reaches on this machine outside ggs: one large transform (2^20) and a batch
/// of 64-point transforms (the length of the bunny's x and y axes), f32 and f64. GFLOP/s =
/// 5·N·log2(N) per transform / time.
fn fft_reference(c: &mut Criterion) {
    use rustfft::{num_complex::Complex, FftPlanner};
    fn bench<T: rustfft::FftNum + Default>(c: &mut Criterion, label: &str) {
        let mut g = c.benchmark_group(format!("fft reference {label}"));
        g.sample_size(20);
        let mut planner = FftPlanner::<T>::new();
        for (name, len, lines) in [
            ("one 2^20-point transform", 1 << 20, 1),
            ("16384 transforms of 64 points", 64, 16384),
        ] {
            let fft = planner.plan_fft_forward(len);
            let mut buf = vec![Complex::<T>::default(); len * lines];
            let mut scratch = vec![Complex::<T>::default(); fft.get_inplace_scratch_len()];
            g.bench_function(name, |b| {
                b.iter(|| fft.process_with_scratch(&mut buf, &mut scratch))
            });
        }
        g.finish();
    }
    bench::<f32>(c, "f32");
    bench::<f64>(c, "f64");
}

criterion_group!(benches, stages, fft_reference);
criterion_main!(benches);
