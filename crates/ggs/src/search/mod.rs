//! The grid search of Greedy Grid Search (docs/method.md): every rotation of a set, the
//! best translation of each by FFT correlation, the best (rotation, translation) overall.
//!
//! The stages, in the order one search runs them ([`grid_search`]); the modules behind
//! them are crate-private (public with the `internals` feature, for the benchmarks):
//!
//! 1. `source`: the source's representatives (dense clouds, [`representatives`]) and
//!    `rotated::RotatableCloud`, the centred source prepared for many rotations (its
//!    voxelization runs in the vector blocks of `blocks`);
//! 2. `extents`: the exact box of every rotated copy, hence its grid and the FFT
//!    [`Geometry`];
//! 3. `voxel`: the target's [`Occupancy`] (the kernel) and the voxel arithmetic both sides
//!    share;
//! 4. [`correlator`]: the [`Correlator`] trait a [`Backend`] implements, with the CPU backend
//!    ([`CpuBackend`]: `cpu`, FFT plans, kernel spectrum, per-thread workspaces, f32 and f64),
//!    `direct` (exact direct correlation of small grids) and `sparse` (exact correlation over
//!    the pairs of occupied cells of sparse grids), each used where it is cheaper than the
//!    transforms;
//! 5. `passes`: a scoring pass over a list of rotations on a backend;
//! 6. `levels`: the coarse level of a coarse-to-fine search (rank at a coarser voxel, keep
//!    the best and their neighbours);
//! 7. `selection`: the exact selection (exact re-scoring where the f32 bound requires) and the
//!    distinct hypotheses;
//! 8. [`result`]: the hypotheses, the statistics and the timings.
//!
//! Determinism: each rotation is scored independently into its own slot and the winner is
//! chosen by a sequential scan, so the result is bit-identical whatever the thread count.
//! Ties go to the lowest rotation index, then the lowest offset in x-major C order; scores
//! are exact integers, so float noise never decides a tie.
//!
//! Precision ([`Precision::Mixed`], the default): rotations are scored in f32 with a proven
//! error bound and every rotation whose bound could reach the winner (or a top-k hypothesis,
//! or the runner-up) is re-scored exactly (integer counts at the offsets the bound leaves
//! open, in `at_offsets`, or an f64 correlation where they are many), so
//! the picks are the all-f64 ones (`selection::exact_best`). On sparse targets the kernel's
//! empty window is counted beside the transforms (`cpu::KernelWindow`), which shrinks the
//! bound.
//!
//! Modes: [`SearchMode::Exhaustive`] scores every rotation at the voxel size;
//! [`SearchMode::CoarseToFine`] ranks every rotation at a coarser voxel first and scores at the
//! voxel size only the best and their neighbours, in rounds that look further while the
//! winner ranks in the lower half of what was kept (docs/performance.md).

mod at_offsets;
mod blocks;
pub mod config;
pub mod correlator;
mod fine;
mod memory_model;
mod prepared;
mod register;
pub mod result;
mod staged;
mod transpose;
mod window;
internal_modules!(
    cpu, direct, extents, geometry, grid_view, levels, passes, rotated, selection, sized, source,
    sparse, voxel, zaxis,
);

pub use config::{
    auto_voxel, round_2_digits, CoarseToFine, Precision, ProgressFn, SearchConfig, SearchMode,
    COARSE_LEVEL_HYPOTHESES,
};
pub use correlator::{Backend, Correlator, Scores};
pub use geometry::Geometry;
pub use passes::CpuBackend;
pub use register::{grid_search, grid_search_with};
pub use result::{CoarseLevel, Hypothesis, LevelHypothesis, SearchResult, SearchStats, Timings};
pub use source::{representatives, MIN_POINTS_PER_REPRESENTATIVE, REPRESENTATIVE_DIVISIONS};
pub use staged::{PreparedSearch, Search};
pub use voxel::Occupancy;
