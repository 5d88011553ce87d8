//! Approximate correlators at several FFT sizes for one kernel.
//!
//! A level is planned for the largest rotated source it scores, but most rotations are
//! smaller: on the bunny pair at its automatic voxel the plan is 64×64×54 while the mean
//! rotation of `hopf15-id` needs 62 % of that volume (7 distinct sizes; `limited15` likewise).
//! A correlation's outputs do not depend on the FFT lengths as long as no wrap-around reaches
//! a valid offset ([`Geometry::new`] sizes each axis for the source it is given), so each
//! rotation may be correlated at the smallest plan that holds it. Only the approximate
//! scores move (within their bounds, computed per plan); exact scores and picks do not.
//!
//! Extra plans cost a kernel spectrum each. They are made for the sizes most rotations of a
//! pass need, largest saving first, while their spectra together stay within
//! [`EXTRA_SPECTRA`] times the full plan's (and [`EXTRA_SPECTRA_CAP`]). A rotation goes to
//! the smallest plan that holds it (the full one always does). On the coarse level the
//! ranking is by exact integers ([`CpuCorrelator::rounded_best`]), so there even the
//! approximate values do not move.

use super::cpu::CpuCorrelator;
use super::extents::RotatedBox;
use super::geometry::Geometry;
use super::voxel::Occupancy;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

/// Extra plans' kernel spectra, together, take at most this many times the full plan's.
pub const EXTRA_SPECTRA: u64 = 4;

/// ... and at most this many bytes (64 MiB): on large grids a plan costs more than its share.
pub const EXTRA_SPECTRA_CAP: u64 = 64 << 20;

/// Volume `Lx·Ly·Lz` of a plan's FFT grid.
fn volume(len: [usize; 3]) -> usize {
    len[0] * len[1] * len[2]
}

/// A full f32 plan, its kernel, and the extra plans made beside it so far (see the module
/// documentation).
pub struct SizedPlans {
    full: CpuCorrelator<f32>,
    kernel: Arc<Occupancy>,
    extra: Mutex<Vec<Arc<CpuCorrelator<f32>>>>,
}

/// The plans of one pass: plan 0 is the full one, plan `j ≥ 1` is `extra[j − 1]`, and
/// `plan_of[i]` is the plan of the `i`-th rotation of the pass.
pub struct Assignment {
    pub extra: Vec<Arc<CpuCorrelator<f32>>>,
    pub plan_of: Vec<usize>,
}

impl Assignment {
    /// The plans, the full one (of `sized`, whose assignment this is) first.
    pub fn plans<'a>(&'a self, sized: &'a SizedPlans) -> Vec<&'a CpuCorrelator<f32>> {
        std::iter::once(&sized.full)
            .chain(self.extra.iter().map(|p| &**p))
            .collect()
    }
}

impl SizedPlans {
    /// The full plan `full` of `kernel`, with no extra plan yet.
    pub fn new(full: CpuCorrelator<f32>, kernel: Arc<Occupancy>) -> Self {
        SizedPlans {
            full,
            kernel,
            extra: Mutex::new(Vec::new()),
        }
    }

    /// The full plan.
    pub fn full(&self) -> &CpuCorrelator<f32> {
        &self.full
    }

    /// The kernel every plan correlates with.
    pub fn kernel(&self) -> &Occupancy {
        &self.kernel
    }

    /// Plans for scoring the rotations `indices` (with extents `boxes`), making the extra
    /// plans worth making (see the module documentation).
    pub fn assign(
        &self,
        pool: &rayon::ThreadPool,
        boxes: &[Option<RotatedBox>],
        indices: &[usize],
    ) -> Assignment {
        let geo = *self.full.geometry();
        let need: Vec<[usize; 3]> = indices
            .iter()
            .map(|&k| match boxes[k] {
                Some(b) => Geometry::new(geo.kernel_dims, b.dims).fft_len,
                None => geo.fft_len,
            })
            .collect();
        let mut extra = self.extra.lock().expect("no panic while planning");
        self.add_wanted(pool, &mut extra, &geo, &need);
        let mut a = Assignment {
            extra: extra.clone(),
            plan_of: Vec::new(),
        };
        drop(extra);
        let plans = a.plans(self);
        let plan_of = need.iter().map(|n| smallest_holding(&plans, *n)).collect();
        a.plan_of = plan_of;
        a
    }

    /// Make the plans for the sizes in `need` that save most, within the spectra budget.
    fn add_wanted(
        &self,
        pool: &rayon::ThreadPool,
        extra: &mut Vec<Arc<CpuCorrelator<f32>>>,
        geo: &Geometry,
        need: &[[usize; 3]],
    ) {
        let mut demand: BTreeMap<[usize; 3], usize> = BTreeMap::new();
        for n in need {
            if *n != geo.fft_len {
                *demand.entry(*n).or_default() += 1;
            }
        }
        let full_volume = volume(geo.fft_len);
        let mut wanted: Vec<([usize; 3], usize)> = demand
            .into_iter()
            .filter(|(len, _)| !extra.iter().any(|p| p.geometry().fft_len == *len))
            .map(|(len, count)| (len, count * (full_volume - volume(len))))
            .collect();
        // Largest saving first; ties in size order (BTreeMap order, kept by a stable sort).
        wanted.sort_by_key(|w| std::cmp::Reverse(w.1));
        let cap = Self::bytes_bound(geo);
        let mut used: u64 = extra.iter().map(|p| p.geometry().kernel_bytes(4)).sum();
        let mut make = Vec::new();
        for (len, _) in wanted {
            let g = Geometry::with_fft_len(geo.kernel_dims, geo.source_max, len);
            let bytes = g.kernel_bytes(4);
            if used.saturating_add(bytes) <= cap {
                used += bytes;
                make.push(g);
            }
        }
        let made: Vec<CpuCorrelator<f32>> = pool.install(|| {
            make.into_par_iter()
                .map(|g| {
                    CpuCorrelator::with_shared_kernel(g, self.kernel.clone(), self.full.window())
                })
                .collect()
        });
        extra.extend(made.into_iter().map(Arc::new));
    }

    /// Bytes the extra plans may take beside a full plan of geometry `geo`.
    pub fn bytes_bound(geo: &Geometry) -> u64 {
        EXTRA_SPECTRA
            .saturating_mul(geo.kernel_bytes(4))
            .min(EXTRA_SPECTRA_CAP)
    }
}

/// The plan of least volume whose lengths are all at least `need`'s (the first on ties;
/// plan 0, the full one, holds every rotation).
fn smallest_holding(plans: &[&CpuCorrelator<f32>], need: [usize; 3]) -> usize {
    let mut best = 0;
    for (i, p) in plans.iter().enumerate().skip(1) {
        let len = p.geometry().fft_len;
        let holds = (0..3).all(|d| len[d] >= need[d]);
        if holds && volume(len) < volume(plans[best].geometry().fft_len) {
            best = i;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::cpu::brute_force_scores;

    fn occupancy(dims: [usize; 3], seed: u64) -> Occupancy {
        let mut next = crate::test_rng::uniform(seed);
        let n = dims.iter().product();
        Occupancy {
            dims,
            cells: (0..n).map(|_| next() < 0.3).collect(),
        }
    }

    fn pool() -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
    }

    fn boxed(dims: [usize; 3]) -> Option<RotatedBox> {
        Some(RotatedBox {
            min: [0.0; 3],
            dims,
        })
    }

    #[test]
    fn each_rotation_gets_the_smallest_plan_that_holds_it() {
        let kernel = occupancy([8, 7, 6], 1);
        let dims = [
            [20, 19, 18],
            [9, 9, 9],
            [9, 9, 9],
            [9, 9, 9],
            [20, 9, 9],
            [5, 5, 5],
        ];
        let boxes: Vec<_> = dims.iter().map(|&d| boxed(d)).collect();
        let full_geo = Geometry::new(kernel.dims, [20, 19, 18]);
        let sized = SizedPlans::new(
            CpuCorrelator::<f32>::new(full_geo, &kernel),
            Arc::new(kernel),
        );
        let idx: Vec<usize> = (0..dims.len()).collect();
        let a = sized.assign(&pool(), &boxes, &idx);
        let plans = a.plans(&sized);
        let kernel = sized.kernel();
        assert_eq!(plans[0].geometry().fft_len, full_geo.fft_len);
        assert_eq!(a.plan_of[0], 0, "the largest source needs the full plan");
        for (i, d) in dims.iter().enumerate() {
            let need = Geometry::new(kernel.dims, *d).fft_len;
            let len = plans[a.plan_of[i]].geometry().fft_len;
            assert!(
                (0..3).all(|ax| len[ax] >= need[ax]),
                "rotation {i} fits its plan"
            );
        }
        // The three equal small sources share the plan made for them, of their exact size.
        let small = plans[a.plan_of[1]].geometry().fft_len;
        assert_eq!(small, Geometry::new(kernel.dims, [9, 9, 9]).fft_len);
        assert_eq!((a.plan_of[2], a.plan_of[3]), (a.plan_of[1], a.plan_of[1]));
        assert!(
            a.extra.len() >= 2,
            "plans for the small and the long sources"
        );
        let extra: u64 = a.extra.iter().map(|p| p.geometry().kernel_bytes(4)).sum();
        assert!(extra <= SizedPlans::bytes_bound(&full_geo));
        // A second pass reuses the plans instead of making them again.
        let b = sized.assign(&pool(), &boxes, &idx);
        assert!(a.extra.iter().zip(&b.extra).all(|(x, y)| Arc::ptr_eq(x, y)));
        assert_eq!(
            (b.extra.len(), b.plan_of.clone()),
            (a.extra.len(), a.plan_of.clone())
        );
    }

    #[test]
    fn a_smaller_plan_gives_the_exact_scores_of_the_definition() {
        let kernel = occupancy([7, 6, 5], 2);
        let source = occupancy([6, 5, 4], 3);
        // Planned for a much larger source, used at the lengths this one needs.
        let big = Geometry::new(kernel.dims, [30, 30, 30]);
        let need = Geometry::new(kernel.dims, source.dims).fft_len;
        assert!(need.iter().zip(big.fft_len).all(|(n, b)| *n < b));
        let geo = Geometry::with_fft_len(kernel.dims, big.source_max, need);
        let c = CpuCorrelator::<f64>::new(geo, &kernel);
        let mut ws = c.workspace();
        ws.load(&source);
        assert_eq!(c.all_scores(&mut ws), brute_force_scores(&source, &kernel));
    }
}
