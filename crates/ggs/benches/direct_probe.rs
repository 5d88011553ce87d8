//! Times the three ways of scoring one rotation of a level, the transforms
//! (`CpuCorrelator::rounded_best` at the smallest plan that holds it), direct correlation
//! (`search::direct`) and sparse correlation (`search::sparse`), over every rotation of
//! `hopf15-id`, checks that all give the same best offset and score, and counts which one the
//! cost model (`Workspace::direct_best`) would pick:
//! `cargo bench -p ggs --features internals --bench direct_probe -- SOURCE TARGET VOXEL [FACTOR]`
//! (`FACTOR`, default 4: the level's voxel is `FACTOR × VOXEL`, the source thinned to one
//! point per cell of a quarter of it, as the default preset's coarse level does; 1: the
//! voxel-size level, on representatives as thinned).
mod common;

use ggs::rotations::RotationSet;
use ggs::search::cpu::{CpuCorrelator, Workspace};
use ggs::search::direct::{DirectKernel, DirectScratch};
use ggs::search::extents::{geometry_for, rotated_boxes, rows, target_kernel};
use ggs::search::rotated::RotatableCloud;
use ggs::search::sized::SizedPlans;
use ggs::search::sparse::{SparseKernel, SparseScratch};
use ggs::Cloud;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = common::args().collect();
    if args.len() < 4 {
        return Err("usage: direct_probe SOURCE TARGET VOXEL [FACTOR]".into());
    }
    let read = |p: &str| ggs::io::read_cloud(std::path::Path::new(p), None).map(|r| r.cloud);
    let (source, target) = (read(&args[1])?, read(&args[2])?);
    let factor: f64 = args.get(4).map_or(Ok(4.0), |a| a.parse())?;
    let s0 = args[3].parse::<f64>()? * factor;
    let points: Vec<ggs::Point> = source.iter().collect();
    let cloud = RotatableCloud::new(&Cloud::new(ggs::thin::cell_centroids(&points, s0 / 4.0)));
    let set = RotationSet::named("hopf15-id")?;
    let rs: Vec<[[f64; 3]; 3]> = set.matrices.iter().map(rows).collect();
    let all: Vec<usize> = (0..rs.len()).collect();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let boxes = rotated_boxes(&pool, &cloud, &rs, &all, s0)?;
    let min = target.aabb().ok_or("empty target")?.min;
    let kernel = target_kernel(&target, min, s0)?;
    let geo = geometry_for(kernel.dims, &boxes);
    let sized = SizedPlans::new(CpuCorrelator::new(geo, &kernel), kernel.clone().into());
    let assigned = sized.assign(&pool, &boxes, &all);
    let plans = assigned.plans(&sized);
    let direct = DirectKernel::new(&geo, &kernel).ok_or("kernel too long for direct")?;
    let mut ws: Vec<Workspace<f32>> = plans.iter().map(|p| p.workspace()).collect();
    let mut scratch = DirectScratch::default();
    let sparse = SparseKernel::new(&geo, &kernel).ok_or("grid too long")?;
    let (mut sparse_scratch, mut t_sparse, mut pairs) = (SparseScratch::default(), 0.0, 0.0);
    let mut volume = 0.0;
    let mut picks = [0usize; 3];
    let (mut t_fft, mut t_direct, mut runs) = (0.0, 0.0, 0usize);
    let mut cells_total = 0usize;
    let (mut adds, mut flops, mut bounded, mut rows_touched) = (0.0, 0.0, 0usize, 0.0);
    for &k in &all {
        let (b, p) = (boxes[k].ok_or("no box")?, assigned.plan_of[k]);
        let w = &mut ws[p];
        w.begin(b.dims);
        cloud.voxelize(&rs[k], &b.min, s0, w.grid_mut());
        let t = Instant::now();
        let (cells, strides, ns) = w.source_grid();
        let n = DirectKernel::gather(cells, strides, ns, &mut scratch);
        cells_total += scratch.cells();
        let by_direct = direct.best(ns, &mut scratch).ok_or("too many cells")?;
        t_direct += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (cells, strides, ns) = w.source_grid();
        DirectKernel::gather(cells, strides, ns, &mut scratch);
        let by_sparse = sparse.best(ns, &scratch, &mut sparse_scratch);
        t_sparse += t.elapsed().as_secs_f64();
        pairs += (n * sparse.runs()) as f64;
        let fft = plans[p].geometry().flops(ns);
        let (cd, cs) = (direct.cost(ns, n), sparse.cost(ns, n));
        picks[if cd < fft && cd <= cs {
            1
        } else if cs < fft && cs < cd {
            2
        } else {
            0
        }] += 1;
        volume += (ns[0] * ns[1] * ns[2]) as f64;
        if by_sparse != Some(by_direct) {
            return Err(format!("rotation {k}: sparse {by_sparse:?} against {by_direct:?}").into());
        }
        runs += n;
        adds += direct.additions(ns, n);
        rows_touched += direct.rows_touched(&scratch) as f64;
        flops += plans[p].geometry().flops(ns);
        let t = Instant::now();
        let by_fft = plans[p].rounded_best(w);
        t_fft += t.elapsed().as_secs_f64();
        // Where the f32 bound reaches ½ the transforms give an interval, which must hold the
        // exact score; below it, the same integer and offset.
        let exact = by_direct.match_score as f64;
        let agree = if by_fft.error_bound == 0.0 {
            by_fft.value == exact && by_fft.offset == by_direct.offset
        } else {
            bounded += 1;
            (by_fft.value - exact).abs() <= by_fft.error_bound
        };
        if !agree {
            return Err(format!("rotation {k}: {by_fft:?} against {by_direct:?}").into());
        }
    }
    let n = all.len() as f64;
    println!(
        "{} rotations at voxel {s0}: kernel {:?}, {:.0} occupied source cells a rotation in {:.0} runs along z",
        all.len(),
        kernel.dims,
        cells_total as f64 / n,
        runs as f64 / n
    );
    println!(
        "{:.0} additions of 16 offsets in {:.0} rows, {:.0} nominal FLOPs a rotation",
        adds / n,
        rows_touched / n,
        flops / n
    );
    println!(
        "transforms {:.2} µs a rotation, direct {:.2} µs (same bests; {bounded} f32 intervals, each holding the exact score)",
        t_fft / n * 1e6,
        t_direct / n * 1e6
    );
    println!(
        "sparse {:.2} µs a rotation ({:.0} run pairs, {} occupied kernel cells in {} runs, {:.0} offsets)",
        t_sparse / n * 1e6,
        pairs / n,
        sparse.occupied(),
        sparse.runs(),
        volume / n
    );
    println!(
        "the costs pick the transforms for {}, direct for {}, sparse for {} rotations",
        picks[0], picks[1], picks[2]
    );
    Ok(())
}
