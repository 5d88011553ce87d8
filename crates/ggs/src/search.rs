//! The coarse search of Greedy Grid Search (SPEC §2): every rotation of a set, the best
//! translation of each by FFT correlation, the best (rotation, translation) overall.
//!
//! Determinism: each rotation is scored independently into its own slot and the winner is
//! chosen by a sequential scan, so the result is bit-identical whatever the thread count.
//! Ties go to the lowest rotation index, then the lowest offset in x-major C order; scores
//! are exact integers, so float noise never decides a tie.

use crate::cloud::{Cloud, Point};
use crate::correlate::{BestOffset, CpuCorrelator, Geometry};
use crate::error::{GgsError, Result};
use crate::memory;
use crate::rotated::{dot_row, RotatableCloud};
use crate::rotations::RotationSet;
use crate::transform::{rotation_angle_deg, Rigid};
use crate::voxel::{self, Occupancy};
use nalgebra::{Matrix3, Vector3};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Callback told how many rotations have been scored so far.
pub type ProgressFn = Arc<dyn Fn(usize) + Send + Sync>;

/// Parameters of a coarse search.
#[derive(Clone)]
pub struct SearchConfig {
    /// Voxel edge length `s`, in the clouds' units.
    pub voxel: f64,
    /// Worker threads; 0 means one per available core.
    pub threads: usize,
    /// Number of distinct hypotheses to return (≥ 1).
    pub top_k: usize,
    /// Rotations closer than this (degrees, geodesic) to a better one are not distinct: they
    /// are skipped for `top_k` and for the ambiguity. Default: 2 × the set's step.
    pub distinct_radius_deg: Option<f64>,
    /// Memory budget in bytes; default half of physical memory.
    pub max_memory: Option<u64>,
    /// Called after each scored rotation with the number scored so far.
    pub progress: Option<ProgressFn>,
    /// Set to `true` from another thread to stop the search ([`GgsError::Cancelled`]).
    pub cancel: Option<Arc<AtomicBool>>,
}

impl std::fmt::Debug for SearchConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SearchConfig")
            .field("voxel", &self.voxel)
            .field("threads", &self.threads)
            .field("top_k", &self.top_k)
            .field("distinct_radius_deg", &self.distinct_radius_deg)
            .field("max_memory", &self.max_memory)
            .finish_non_exhaustive()
    }
}

impl SearchConfig {
    /// Defaults with the given voxel size.
    pub fn with_voxel(voxel: f64) -> Self {
        SearchConfig {
            voxel,
            threads: 0,
            top_k: 1,
            distinct_radius_deg: None,
            max_memory: None,
            progress: None,
            cancel: None,
        }
    }
}

/// Voxel size for which the target grid spans about `cells` voxels along its longest side,
/// rounded to 2 significant digits (so it reads well in reports).
pub fn auto_voxel(target: &Cloud, cells: usize) -> Option<f64> {
    let e = target.aabb()?.extent();
    let longest = e[0].max(e[1]).max(e[2]);
    if longest <= 0.0 || !longest.is_finite() {
        return None;
    }
    let raw = longest / cells.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor() - 1.0);
    Some((raw / mag).round() * mag)
}

/// One (rotation, translation) candidate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Hypothesis {
    /// Index of the rotation in the set.
    pub rotation_index: usize,
    /// SPEC §2 score `Σ S_pad·K` (PV = 5, NV = PPV = −1), an exact integer.
    pub score: i64,
    /// Offset-free match score `5·n11 − n01` (SPEC §4); same argmax as `score`.
    pub match_score: i64,
    /// Best offset `a` in cells (x, y, z).
    pub offset: [usize; 3],
    /// The transform, `p_target = T · p_source`.
    #[serde(serialize_with = "ser_rigid")]
    pub transform: Rigid,
}

fn ser_rigid<S: serde::Serializer>(t: &Rigid, s: S) -> std::result::Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&t.to_rows(), s)
}

/// Wall-clock and CPU times of the stages, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// Target voxelization and kernel spectrum (wall).
    pub target_ms: f64,
    /// Rotated source extents for all rotations (wall).
    pub extents_ms: f64,
    /// Scoring all rotations (wall).
    pub search_ms: f64,
    /// Everything in `coarse_register` (wall).
    pub total_ms: f64,
    /// CPU time summed over workers: voxelizing rotated sources.
    pub cpu_voxelize_ms: f64,
    /// CPU time: forward FFTs along z and y.
    pub cpu_forward_ms: f64,
    /// CPU time: FFT along x, product with the kernel spectrum, inverse along x.
    pub cpu_product_ms: f64,
    /// CPU time: inverse FFTs along y and z and the argmax.
    pub cpu_inverse_ms: f64,
}

/// Result of a coarse search.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SearchResult {
    /// Best transform, `p_target = T · p_source`.
    #[serde(serialize_with = "ser_rigid")]
    pub transform: Rigid,
    pub rotation_index: usize,
    /// SPEC score of the winner.
    pub score: i64,
    /// Match score `5·n11 − n01` of the winner.
    pub match_score: i64,
    pub offset: [usize; 3],
    /// Best hypothesis whose rotation is more than `distinct_radius_deg` from the winner's.
    pub runner_up: Option<Hypothesis>,
    /// `runner_up.match_score / match_score` (when the winner's is positive): near 1, another
    /// pose explains the data about as well; near 0 or below, the answer is clear.
    pub ambiguity: Option<f64>,
    pub distinct_radius_deg: f64,
    /// The `top_k` best distinct hypotheses, best first (the first is the winner).
    pub hypotheses: Vec<Hypothesis>,
    pub voxel: f64,
    pub rotation_set: String,
    pub rotations: usize,
    pub source_points: usize,
    pub target_points: usize,
    /// Occupied target voxels.
    pub target_occupied: usize,
    pub geometry: Geometry,
    pub threads: usize,
    /// Estimated peak of the search's large buffers, in bytes.
    pub memory_estimate_bytes: u64,
    /// Largest distance of an FFT output from its integer (exactness check; ≪ 0.5).
    pub max_rounding_error: f64,
    pub timings: Timings,
}

fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// Per-rotation min corner and grid dims of the rotated, centred source.
#[derive(Debug, Clone, Copy)]
struct RotatedBox {
    min: Point,
    dims: [usize; 3],
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Run the coarse search of `source` against `target` over `set`.
pub fn coarse_register(
    source: &Cloud,
    target: &Cloud,
    set: &RotationSet,
    cfg: &SearchConfig,
) -> Result<SearchResult> {
    let t_start = Instant::now();
    let s = cfg.voxel;
    if !(s.is_finite() && s > 0.0) {
        return Err(GgsError::param(
            "voxel",
            format!("must be a positive number, got {s}"),
        ));
    }
    if cfg.top_k == 0 {
        return Err(GgsError::param("top_k", "must be at least 1"));
    }
    if set.is_empty() {
        return Err(GgsError::param("rotations", "the rotation set is empty"));
    }
    source.ensure_not_empty("source")?;
    target.ensure_not_empty("target")?;
    let threads = crate::threads::resolve(cfg.threads);
    let budget = cfg.max_memory.unwrap_or_else(memory::default_budget);

    // Target: shift to min 0, kernel dims.
    let t0 = Instant::now();
    let tb = target.aabb().expect("non-empty");
    let m_y = tb.min;
    let nr = voxel::grid_dims(tb.extent(), s)?;
    // Source: centre on its mean.
    let rc = RotatableCloud::new(source);
    let c_x = rc.centroid;
    let centred = &rc.points;
    let radius = centred
        .iter()
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .fold(0.0, f64::max);
    let sizes = MemoryModel {
        target_extent: tb.extent(),
        source_radius: radius,
        threads,
        points: centred.len(),
    };
    let early = Geometry::new(nr, [1, 1, 1]);
    let early_bytes = sizes.bytes(&early);
    if early_bytes > budget {
        return Err(sizes.error(&early, early_bytes, budget, s));
    }
    let rot_rows: Vec<[[f64; 3]; 3]> = set.matrices.iter().map(rows).collect();

    let (pool, _) = crate::threads::pool(threads)?;

    // Pass 1: extents of every rotated source (fixes the FFT lengths for the whole pair).
    let t1 = Instant::now();
    let boxes: Vec<Result<RotatedBox>> = pool.install(|| {
        use rayon::prelude::*;
        rot_rows
            .par_iter()
            .map(|r| {
                let mut lo = [0.0; 3];
                let mut hi = [0.0; 3];
                for d in 0..3 {
                    (lo[d], hi[d]) = rc.range(&r[d]);
                }
                let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
                Ok(RotatedBox {
                    min: lo,
                    dims: voxel::grid_dims(ext, s)?,
                })
            })
            .collect()
    });
    let boxes: Vec<RotatedBox> = boxes.into_iter().collect::<Result<_>>()?;
    let mut ns_max = [1usize; 3];
    for b in &boxes {
        for d in 0..3 {
            ns_max[d] = ns_max[d].max(b.dims[d]);
        }
    }
    let t_extents = t1.elapsed();

    let geo = Geometry::new(nr, ns_max);
    let estimate = sizes.bytes(&geo);
    if estimate > budget {
        return Err(sizes.error(&geo, estimate, budget, s));
    }

    // Kernel.
    let shifted: Vec<Point> = target
        .points
        .iter()
        .map(|p| [p[0] - m_y[0], p[1] - m_y[1], p[2] - m_y[2]])
        .collect();
    let kernel = Occupancy::from_points(&shifted, [0.0; 3], s)?;
    debug_assert_eq!(kernel.dims, nr);
    drop(shifted);
    let corr = CpuCorrelator::new(geo, &kernel);
    let t_target = t0.elapsed() - t_extents;

    // Pass 2: score every rotation. One workspace per worker; rotations are handed out by an
    // atomic counter; each result lands in its own slot.
    let t2 = Instant::now();
    let n_rot = set.len();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let slots: Mutex<Vec<Option<BestOffset>>> = Mutex::new(vec![None; n_rot]);
    let stats: Mutex<(Duration, Duration, Duration, Duration, f64)> = Mutex::new((
        Duration::ZERO,
        Duration::ZERO,
        Duration::ZERO,
        Duration::ZERO,
        0.0,
    ));
    let cancelled = AtomicBool::new(false);
    pool.scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|_| {
                let mut ws = corr.workspace();
                let mut t_vox = Duration::ZERO;
                let mut local: Vec<(usize, BestOffset)> = Vec::new();
                loop {
                    if cfg
                        .cancel
                        .as_ref()
                        .is_some_and(|c| c.load(Ordering::Relaxed))
                    {
                        cancelled.store(true, Ordering::Relaxed);
                        break;
                    }
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    if k >= n_rot {
                        break;
                    }
                    let tv = Instant::now();
                    let b = boxes[k];
                    let r = &rot_rows[k];
                    ws.begin(b.dims);
                    let (grid, sy, sx) = ws.grid_mut();
                    let inv = 1.0 / s;
                    for p in centred {
                        let i = voxel::cell_fast(dot_row(&r[0], p) - b.min[0], s, inv);
                        let j = voxel::cell_fast(dot_row(&r[1], p) - b.min[1], s, inv);
                        let l = voxel::cell_fast(dot_row(&r[2], p) - b.min[2], s, inv);
                        grid[i * sx + j * sy + l] = 1.0;
                    }
                    t_vox += tv.elapsed();
                    local.push((k, corr.best_offset(&mut ws)));
                    let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                    if let Some(p) = &cfg.progress {
                        p(n);
                    }
                }
                let mut sl = slots
                    .lock()
                    .expect("no worker panics while holding the lock");
                for (k, b) in local {
                    sl[k] = Some(b);
                }
                let mut st = stats
                    .lock()
                    .expect("no worker panics while holding the lock");
                st.0 += t_vox;
                st.1 += ws.t_forward;
                st.2 += ws.t_product;
                st.3 += ws.t_inverse;
                st.4 = st.4.max(ws.max_rounding_error);
            });
        }
    });
    if cancelled.load(Ordering::Relaxed) {
        return Err(GgsError::Cancelled);
    }
    let best: Vec<BestOffset> = slots
        .into_inner()
        .expect("workers finished")
        .into_iter()
        .map(|b| b.expect("every rotation scored"))
        .collect();
    let (cpu_vox, cpu_fwd, cpu_prod, cpu_inv, max_err) =
        stats.into_inner().expect("workers finished");
    let t_search = t2.elapsed();

    // Winner: highest match score, lowest index on ties.
    let constant = corr.kernel_cells - 6 * corr.kernel_occupied;
    let hypothesis = |k: usize| -> Hypothesis {
        let b = &best[k];
        let r = set.matrices[k];
        let mut t = -(r * Vector3::from(c_x));
        for d in 0..3 {
            t[d] += -boxes[k].min[d] + (geo.center[d] as f64 - b.offset[d] as f64) * s + m_y[d];
        }
        Hypothesis {
            rotation_index: k,
            score: constant + 6 * b.match_score,
            match_score: b.match_score,
            offset: b.offset,
            transform: Rigid::new(r, t),
        }
    };
    let mut order: Vec<usize> = (0..n_rot).collect();
    order.sort_by(|&a, &b| {
        best[b]
            .match_score
            .cmp(&best[a].match_score)
            .then(a.cmp(&b))
    });
    let winner = order[0];
    let radius = cfg.distinct_radius_deg.unwrap_or(2.0 * set.step_deg);
    let mut chosen: Vec<usize> = Vec::with_capacity(cfg.top_k);
    for &k in &order {
        if chosen.len() == cfg.top_k {
            break;
        }
        if chosen
            .iter()
            .all(|&c| rotation_angle_deg(&set.matrices[c], &set.matrices[k]) > radius)
        {
            chosen.push(k);
        }
    }
    let runner_up = order
        .iter()
        .copied()
        .find(|&k| rotation_angle_deg(&set.matrices[winner], &set.matrices[k]) > radius)
        .map(hypothesis);
    let win = hypothesis(winner);
    let ambiguity = match runner_up {
        Some(r) if win.match_score > 0 => Some(r.match_score as f64 / win.match_score as f64),
        _ => None,
    };
    Ok(SearchResult {
        transform: win.transform,
        rotation_index: winner,
        score: win.score,
        match_score: win.match_score,
        offset: win.offset,
        runner_up,
        ambiguity,
        distinct_radius_deg: radius,
        hypotheses: chosen.into_iter().map(hypothesis).collect(),
        voxel: s,
        rotation_set: set.name.clone(),
        rotations: n_rot,
        source_points: source.len(),
        target_points: target.len(),
        target_occupied: corr.kernel_occupied as usize,
        geometry: geo,
        threads,
        memory_estimate_bytes: estimate,
        max_rounding_error: max_err,
        timings: Timings {
            target_ms: ms(t_target),
            extents_ms: ms(t_extents),
            search_ms: ms(t_search),
            total_ms: ms(t_start.elapsed()),
            cpu_voxelize_ms: ms(cpu_vox),
            cpu_forward_ms: ms(cpu_fwd),
            cpu_product_ms: ms(cpu_prod),
            cpu_inverse_ms: ms(cpu_inv),
        },
    })
}

/// What the large buffers of a search cost, and which voxel size makes them fit.
struct MemoryModel {
    target_extent: [f64; 3],
    /// Largest distance of a source point from the centroid: every rotated source grid has
    /// at most `floor(2·radius/s) + 1` cells per axis.
    source_radius: f64,
    threads: usize,
    points: usize,
}

impl MemoryModel {
    /// Kernel spectrum, one workspace per thread, kernel occupancy and the centred points.
    fn bytes(&self, geo: &Geometry) -> u64 {
        let cells = geo
            .kernel_dims
            .iter()
            .fold(1u64, |a, &d| a.saturating_mul(d as u64));
        geo.kernel_bytes()
            .saturating_add((self.threads as u64).saturating_mul(geo.workspace_bytes()))
            .saturating_add(cells)
            .saturating_add((self.points as u64).saturating_mul(24))
    }

    /// Upper bound of `bytes` at voxel `s`, from the source's bounding sphere.
    fn bound_at(&self, s: f64) -> Option<(Geometry, u64)> {
        let nr = voxel::grid_dims(self.target_extent, s).ok()?;
        let ns = voxel::axis_cells(2.0 * self.source_radius, s);
        let geo = Geometry::new(nr, [ns; 3]);
        Some((geo, self.bytes(&geo)))
    }

    /// The error for a search that does not fit, with a voxel size that does (by the bound).
    fn error(&self, geo: &Geometry, need: u64, budget: u64, voxel: f64) -> GgsError {
        let mut suggested = voxel;
        for _ in 0..2000 {
            suggested *= 1.02;
            if self.bound_at(suggested).is_some_and(|(_, b)| b <= budget) {
                break;
            }
        }
        // Round up to 3 significant digits so the printed value still fits.
        let unit = 10f64.powf(suggested.log10().floor() - 2.0);
        let suggested = (suggested / unit).ceil() * unit;
        let digits = (2.0 - suggested.log10().floor()).max(0.0) as usize;
        let suggested = format!("{suggested:.digits$}");
        GgsError::MemoryBudget(format!(
            "the search needs about {} (FFT grid {}×{}×{} for kernel {}×{}×{} and source up to {}×{}×{}, {} thread(s)) but the budget is {}; use a voxel size of at least {} (now {voxel}), fewer threads, or raise --max-memory",
            memory::human_bytes(need),
            geo.fft_len[0], geo.fft_len[1], geo.fft_len[2],
            geo.kernel_dims[0], geo.kernel_dims[1], geo.kernel_dims[2],
            geo.source_max[0], geo.source_max[1], geo.source_max[2],
            self.threads,
            memory::human_bytes(budget),
            suggested,
        ))
    }
}
