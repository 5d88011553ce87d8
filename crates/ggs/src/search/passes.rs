//! The CPU backend: scoring passes over a list of rotations on a thread pool.
//!
//! A pass voxelizes each rotated source into a worker's workspace and correlates it with
//! [`CpuCorrelator`]. Work is handed out by an atomic counter and every result lands in the
//! slot of its rotation, so a pass gives the same results whatever the thread count.
//! Approximate scores are f32 correlations with their proven bound
//! ([`CpuCorrelator::error_bound`]); exact ones are f64 correlations rounded to the integers
//! they equal.

use super::correlator::{
    as_intervals, ApproxBest, Backend, BestOffset, Candidates, Correlator, PassControl, Rescored,
    RotatedSources, Scores, PassTimes,
};
use super::cpu::{CpuCorrelator, ExactKernels, KernelWindow, Real, Workspace};
use rayon::prelude::*;

use super::geometry::Geometry;
use super::sized::SizedPlans;
use super::voxel::Occupancy;
use crate::error::{GgsError, Result};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The CPU backend: f64 FFT correlations (exact), f32 ones with a bound (approximate).
#[derive(Debug, Clone, Copy, Default)]
pub struct CpuBackend;

/// The correlators of one plan: f64 for exact scores, f32 for approximate ones.
// One plan per search level, boxed behind `dyn Correlator`: the size difference costs nothing.
#[allow(clippy::large_enum_variant)]
pub enum CpuPlan {
    /// Rotations are ranked by exact integers: direct or sparse correlation where either is
    /// cheaper ([`ExactKernels`]), else [`CpuCorrelator::rounded_best`], each at the smallest
    /// plan that holds it (the ranking does not depend on the plan).
    Approximate(SizedPlans, ExactKernels),
    /// The kernel is kept for exact scores at a few candidate offsets and for the smaller
    /// approximate plans ([`SizedPlans`]); rotations are scored exactly by sparse
    /// correlation where that is cheaper ([`ExactKernels::sparse_only`]).
    Mixed(CpuCorrelator<f64>, SizedPlans, ExactKernels),
    Exact(CpuCorrelator<f64>),
}

impl Backend for CpuBackend {
    fn plan(
        &self,
        geo: Geometry,
        kernel: &Occupancy,
        scores: Scores,
    ) -> Result<Box<dyn Correlator>> {
        Ok(Box::new(match scores {
            Scores::Approximate => {
                let shared = Arc::new(kernel.clone());
                let full = CpuCorrelator::with_shared_kernel(
                    geo,
                    shared.clone(),
                    KernelWindow::InSpectrum,
                );
                CpuPlan::Approximate(
                    SizedPlans::new(full, shared),
                    ExactKernels::new(&geo, kernel),
                )
            }
            Scores::Mixed => {
                let window =
                    KernelWindow::for_kernel(kernel.cells.len() as i64, kernel.occupied() as i64);
                let shared = Arc::new(kernel.clone());
                let exact = CpuCorrelator::<f64>::with_shared_kernel(geo, shared.clone(), window);
                let approx = CpuCorrelator::<f32>::from_f64(&exact);
                let kernels = ExactKernels::sparse_only(&geo, kernel);
                CpuPlan::Mixed(exact, SizedPlans::new(approx, shared), kernels)
            }
            Scores::Exact => CpuPlan::Exact(CpuCorrelator::new(geo, kernel)),
        }))
    }
}

impl CpuPlan {
    /// `(|K|, n_k, geometry)`, the same in every correlator of the plan.
    fn kernel(&self) -> (i64, i64, &Geometry) {
        match self {
            CpuPlan::Approximate(p, _) | CpuPlan::Mixed(_, p, _) => {
                let c = p.full();
                (c.kernel_cells, c.kernel_occupied, c.geometry())
            }
            CpuPlan::Exact(c) => (c.kernel_cells, c.kernel_occupied, c.geometry()),
        }
    }
}

impl Correlator for CpuPlan {
    fn geometry(&self) -> &Geometry {
        self.kernel().2
    }

    fn kernel_cells(&self) -> i64 {
        self.kernel().0
    }

    fn kernel_occupied(&self) -> i64 {
        self.kernel().1
    }

    fn exact(
        &self,
        ctl: &PassControl<'_>,
        src: &RotatedSources<'_>,
        indices: &[usize],
    ) -> Result<(Vec<BestOffset>, PassTimes)> {
        match self {
            CpuPlan::Mixed(c, ..) | CpuPlan::Exact(c) => {
                run_pass(ctl, src, c, indices, |c, ws, _| c.best_offset(ws))
            }
            CpuPlan::Approximate(..) => Err(GgsError::param(
                "scores",
                "this correlator was planned for approximate scores only",
            )),
        }
    }

    /// With a mixed plan, rotations whose candidates were kept are voxelized and scored at
    /// those offsets ([`CpuCorrelator::exact_among`]); the others are correlated in f32 again
    /// and counted at the offsets that could reach `at_least` ([`CpuCorrelator::exact_above`]);
    /// those with too many such offsets are correlated in f64.
    fn exact_among(
        &self,
        ctl: &PassControl<'_>,
        src: &RotatedSources<'_>,
        indices: &[usize],
        candidates: &[Candidates],
        at_least: f64,
    ) -> Result<(Vec<Rescored>, PassTimes)> {
        let CpuPlan::Mixed(_, sized, _) = self else {
            let (found, times) = self.exact(ctl, src, indices)?;
            return Ok((found.into_iter().map(Rescored::Exact).collect(), times));
        };
        let (approx, kernel) = (sized.full(), sized.kernel());
        let (kept, again): (Vec<usize>, Vec<usize>) =
            (0..indices.len()).partition(|&i| candidates[i].offsets().is_some());
        let pick = |from: &[usize]| from.iter().map(|&i| indices[i]).collect::<Vec<_>>();
        let (counted, mut times) = run_pass(ctl, src, approx, &pick(&kept), |c, ws, slot| {
            let offsets = candidates[kept[slot]].offsets().expect("kept");
            Rescored::Exact(c.exact_among(ws, kernel, offsets))
        })?;
        // Counting at candidates does no transform.
        times.flops = 0.0;
        let n_again = again.len();
        let (above, above_times) = run_pass(ctl, src, approx, &pick(&again), {
            |c, ws, _| c.exact_above(ws, kernel, at_least)
        })?;
        times.add(&above_times);
        let mut out = vec![Rescored::TooMany; indices.len()];
        for (i, r) in kept
            .into_iter()
            .zip(counted)
            .chain(again.into_iter().zip(above))
        {
            out[i] = r;
        }
        let full: Vec<usize> = (0..indices.len())
            .filter(|&i| out[i] == Rescored::TooMany)
            .collect();
        tracing::debug!(
            at_candidates = indices.len() - n_again,
            counted_above = n_again - full.len(),
            in_f64 = full.len(),
            "exact re-scoring"
        );
        let (exact, full_times) = self.exact(ctl, src, &pick(&full))?;
        times.add(&full_times);
        for (i, b) in full.into_iter().zip(exact) {
            out[i] = Rescored::Exact(b);
        }
        Ok((out, times))
    }

    fn approx(
        &self,
        ctl: &PassControl<'_>,
        src: &RotatedSources<'_>,
        indices: &[usize],
    ) -> Result<(Vec<ApproxBest>, PassTimes)> {
        match self {
            CpuPlan::Approximate(sized, kernels) => {
                sized_pass(ctl, src, (sized, kernels), indices, |c, ws| {
                    (ws.direct_best(kernels, c.geometry()))
                        .map_or_else(|| c.rounded_best(ws), ApproxBest::from)
                })
            }
            CpuPlan::Mixed(_, sized, kernels) => {
                sized_pass(ctl, src, (sized, kernels), indices, |c, ws| {
                    (ws.direct_best(kernels, c.geometry()))
                        .map_or_else(|| c.approx_best(ws, true), ApproxBest::from)
                })
            }
            CpuPlan::Exact(_) => Ok(as_intervals(self.exact(ctl, src, indices)?)),
        }
    }
}

/// True when every rotation of `indices` is likely scored by direct or sparse correlation
/// ([`Workspace::direct_best`]): its expected cost is below the transforms' at the rotation's
/// plan with twice as many source runs as the unrotated source occupies cells (a run holds one
/// or more occupied cells; a rotation rarely doubles their count), at most one per point. Only
/// when the spectra are computed depends on it, never a score. The cells are counted only
/// when even a single run leaves every rotation to the exact paths.
fn likely_exact_paths(
    kernels: &ExactKernels,
    plans: &[&CpuCorrelator<f32>],
    plan_of: &[usize],
    src: &RotatedSources<'_>,
    indices: &[usize],
) -> bool {
    let exact_paths_with = |runs: usize| {
        indices.iter().zip(plan_of).all(|(&k, &p)| {
            let Some(b) = src.boxes[k] else {
                return false;
            };
            let fft = plans[p].geometry().flops(b.dims);
            let dense = (kernels.dense.as_ref()).map_or(f64::INFINITY, |d| d.cost(b.dims, runs));
            let sparse = (kernels.sparse.as_ref()).map_or(f64::INFINITY, |s| s.cost(b.dims, runs));
            dense.min(sparse) < fft
        })
    };
    if !exact_paths_with(1) {
        return false;
    }
    let points = &src.cloud.points;
    let cells: std::collections::HashSet<[i64; 3]> = points
        .iter()
        .map(|p| p.map(|c| (c / src.voxel).floor() as i64))
        .collect();
    exact_paths_with((2 * cells.len()).min(points.len()))
}

/// Score the rotations `indices` with `score` (one call per rotation, in a worker's
/// workspace holding that rotation's source grid). Results are in the order of `indices`.
fn run_pass<T: Real, R: Send + Copy>(
    ctl: &PassControl<'_>,
    src: &RotatedSources<'_>,
    corr: &CpuCorrelator<T>,
    indices: &[usize],
    score: impl Fn(&CpuCorrelator<T>, &mut Workspace<T>, usize) -> R + Sync,
) -> Result<(Vec<R>, PassTimes)> {
    let plan_of = vec![0; indices.len()];
    run_sized(ctl, src, &[corr], &plan_of, indices, score)
}

/// [`run_pass`] with each rotation at the smallest plan of `sized` that holds it. The plans'
/// kernel spectra are computed up front, in parallel, unless every rotation is likely scored
/// by `kernels` ([`likely_exact_paths`]): then they are computed only if a rotation still
/// needs the transforms.
fn sized_pass(
    ctl: &PassControl<'_>,
    src: &RotatedSources<'_>,
    (sized, kernels): (&SizedPlans, &ExactKernels),
    indices: &[usize],
    score: impl Fn(&CpuCorrelator<f32>, &mut Workspace<f32>) -> ApproxBest + Sync,
) -> Result<(Vec<ApproxBest>, PassTimes)> {
    let a = sized.assign(ctl.pool, src.boxes, indices);
    let plans = a.plans(sized);
    if !likely_exact_paths(kernels, &plans, &a.plan_of, src, indices) {
        let used: std::collections::BTreeSet<usize> = a.plan_of.iter().copied().collect();
        ctl.pool.install(|| {
            used.into_par_iter()
                .for_each(|p| plans[p].compute_spectrum())
        });
    }
    run_sized(ctl, src, &plans, &a.plan_of, indices, |c, ws, _| {
        score(c, ws)
    })
}

/// [`run_pass`] with rotation `indices[i]` correlated by `plans[plan_of[i]]`. Rotations are
/// handed out plan by plan, so a worker re-sizes its workspace once per plan
/// ([`CpuCorrelator::fit`]).
fn run_sized<T: Real, R: Send + Copy>(
    ctl: &PassControl<'_>,
    src: &RotatedSources<'_>,
    plans: &[&CpuCorrelator<T>],
    plan_of: &[usize],
    indices: &[usize],
    score: impl Fn(&CpuCorrelator<T>, &mut Workspace<T>, usize) -> R + Sync,
) -> Result<(Vec<R>, PassTimes)> {
    // Nothing to score: no worker, no workspace (a re-scoring splits its rotations into two
    // passes, one of them often empty).
    if indices.is_empty() {
        return Ok((Vec::new(), PassTimes::default()));
    }
    let mut order: Vec<usize> = (0..indices.len()).collect();
    order.sort_by_key(|&i| plan_of[i]);
    let pass = Pass {
        ctl,
        src,
        plans,
        plan_of,
        indices,
        order,
        next: AtomicUsize::new(0),
        done: AtomicUsize::new(0),
        slots: Mutex::new(vec![None; indices.len()]),
        stats: Mutex::new(PassTimes::default()),
        skipped_flops: AtomicU64::new(0),
        cancelled: AtomicBool::new(false),
    };
    let workers = ctl.threads.min(indices.len()).max(1);
    ctl.pool.scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|_| pass.work(&score));
        }
    });
    if pass.cancelled.load(Ordering::Relaxed) {
        return Err(GgsError::Cancelled);
    }
    // The FLOPs summed in the order of `indices`, not of the workers, less those of the
    // rotations correlated directly (whole numbers, so their sum does not depend on the order
    // either): the same bits at any thread count.
    let mut times = pass.stats.into_inner().expect("workers finished");
    let all: f64 = indices
        .iter()
        .zip(plan_of)
        .filter_map(|(&k, &p)| Some(plans[p].geometry().flops(src.boxes[k]?.dims)))
        .sum();
    times.flops = all - pass.skipped_flops.into_inner() as f64;
    let results = pass
        .slots
        .into_inner()
        .expect("workers finished")
        .into_iter()
        .map(|r| r.expect("every rotation scored"))
        .collect();
    Ok((results, times))
}

/// One pass's work list and what its workers share: rotations go out in `order` by an atomic
/// counter and every result lands in the slot of its rotation, whichever worker scored it.
struct Pass<'p, 'c, 's, T: Real, R> {
    ctl: &'p PassControl<'c>,
    src: &'p RotatedSources<'s>,
    plans: &'p [&'p CpuCorrelator<T>],
    plan_of: &'p [usize],
    indices: &'p [usize],
    order: Vec<usize>,
    next: AtomicUsize,
    done: AtomicUsize,
    slots: Mutex<Vec<Option<R>>>,
    stats: Mutex<PassTimes>,
    /// Nominal FLOPs of the rotations correlated directly instead ([`Workspace::direct_best`]).
    skipped_flops: AtomicU64,
    cancelled: AtomicBool,
}

impl<T: Real, R: Send + Copy> Pass<'_, '_, '_, T, R> {
    /// One worker: take rotations until none is left (or the pass is cancelled), voxelize
    /// each into its own workspace and score it; then file the results and stage times.
    fn work(&self, score: &(impl Fn(&CpuCorrelator<T>, &mut Workspace<T>, usize) -> R + Sync)) {
        let (src, s) = (self.src, self.src.voxel);
        let mut plan = self.plan_of[self.order[0]];
        let mut ws = Workspace::default();
        self.plans[plan].fit_grid(&mut ws);
        let mut t_vox = Duration::ZERO;
        let mut local: Vec<(usize, R)> = Vec::new();
        loop {
            if self.ctl.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                self.cancelled.store(true, Ordering::Relaxed);
                break;
            }
            let at = self.next.fetch_add(1, Ordering::Relaxed);
            let Some(&slot) = self.order.get(at) else {
                break;
            };
            if self.plan_of[slot] != plan {
                plan = self.plan_of[slot];
                self.plans[plan].fit_grid(&mut ws);
            }
            let k = self.indices[slot];
            let tv = Instant::now();
            let b = src.boxes[k].expect("extents computed for every scored rotation");
            ws.begin(b.dims);
            src.cloud.voxelize(&src.rows[k], &b.min, s, ws.grid_mut());
            t_vox += tv.elapsed();
            local.push((slot, score(self.plans[plan], &mut ws, slot)));
            let n = self.done.fetch_add(1, Ordering::Relaxed) + 1;
            if let Some(p) = self.ctl.progress {
                p(n);
            }
        }
        let lock = "no worker panics while holding the lock";
        let mut slots = self.slots.lock().expect(lock);
        for (slot, r) in local {
            slots[slot] = Some(r);
        }
        self.stats.lock().expect(lock).add(&PassTimes {
            voxelize: t_vox,
            forward: ws.t_forward,
            product: ws.t_product,
            inverse: ws.t_inverse,
            direct: ws.t_direct,
            max_rounding_error: ws.max_rounding_error,
            flops: 0.0,
        });
        self.skipped_flops
            .fetch_add(ws.direct_flops, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_times_add_up() {
        let ms = Duration::from_millis;
        let mut a = PassTimes {
            voxelize: ms(1),
            forward: ms(2),
            product: ms(3),
            inverse: ms(4),
            direct: ms(5),
            max_rounding_error: 1e-9,
            flops: 10.0,
        };
        a.add(&PassTimes {
            voxelize: ms(10),
            forward: ms(20),
            product: ms(30),
            inverse: ms(40),
            direct: ms(50),
            max_rounding_error: 1e-12,
            flops: 5.0,
        });
        assert_eq!(
            (a.voxelize, a.forward, a.product, a.inverse, a.direct),
            (ms(11), ms(22), ms(33), ms(44), ms(55))
        );
        assert_eq!((a.max_rounding_error, a.flops), (1e-9, 15.0));
    }
}
