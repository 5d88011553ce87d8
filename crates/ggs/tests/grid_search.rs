//! Invariants of the grid search: exact recovery of a grid rotation with a voxel-multiple
//! translation, and bit-identical results whatever the thread count.

mod common;

use common::Lcg;
use ggs::io::read_cloud;
use ggs::metrics::{rre, rte};
use ggs::rotations::RotationSet;
use ggs::search::{grid_search, CoarseToFine, Precision, SearchConfig, SearchMode, SearchResult};
use ggs::{Cloud, Rigid};
use nalgebra::Vector3;
use proptest::prelude::*;
use std::sync::OnceLock;

/// Relative rounding of a cloud's stored coordinates: 2⁻²⁴ of its diagonal (see `Cloud`).
const STORAGE: f64 = 1.0 / (1u64 << 24) as f64;

fn limited15() -> &'static RotationSet {
    static SET: OnceLock<RotationSet> = OnceLock::new();
    SET.get_or_init(|| RotationSet::named("limited15").unwrap())
}

fn ico() -> &'static RotationSet {
    static SET: OnceLock<RotationSet> = OnceLock::new();
    SET.get_or_init(|| RotationSet::named("ico162-s10").unwrap())
}

/// The built-in set `name`, built once per test binary.
macro_rules! named_set {
    ($name:literal) => {{
        static SET: OnceLock<RotationSet> = OnceLock::new();
        SET.get_or_init(|| RotationSet::named($name).unwrap())
    }};
}

/// A random cloud: `n` points in a 1.0 × 0.6 × 0.4 box plus a denser blob, so it has no
/// symmetry a rotation could exploit.
fn random_cloud(seed: u64, n: usize) -> Cloud {
    let mut r = Lcg(seed);
    let mut pts = Vec::with_capacity(n);
    for i in 0..n {
        let p = if i % 4 == 0 {
            [
                0.8 + 0.1 * r.next_f64(),
                0.1 * r.next_f64(),
                0.3 + 0.1 * r.next_f64(),
            ]
        } else {
            [r.next_f64(), 0.6 * r.next_f64(), 0.4 * r.next_f64()]
        };
        pts.push([p[0] + 3.0, p[1] - 1.0, p[2] + 0.5]);
    }
    Cloud::new(pts)
}

fn check_recovery(set: &RotationSet, seed: u64, k: usize, shift: [i32; 3]) {
    check_recovery_in(set, seed, k, shift, Precision::Mixed);
}

fn check_recovery_in(
    set: &RotationSet,
    seed: u64,
    k: usize,
    shift: [i32; 3],
    precision: Precision,
) {
    let voxel = 0.08;
    let source = random_cloud(seed, 300);
    let truth = Rigid::new(
        set.matrices[k],
        Vector3::new(
            shift[0] as f64 * voxel,
            shift[1] as f64 * voxel,
            shift[2] as f64 * voxel,
        ),
    );
    let target = source.transformed(&truth);
    let cfg = SearchConfig {
        precision,
        ..SearchConfig::with_voxel(voxel)
    };
    let r = grid_search(&source, &target, set, &cfg).unwrap();
    let extent = source.aabb().unwrap().diagonal();
    // A later duplicate of an earlier rotation (limited15 keeps 3 float-noise ones, hopf15
    // some 1.7e-6° apart, where the angle from the trace is at the resolution of acos) is
    // recovered as the earlier index with the same voxelization.
    let same_matrix = rre(&r.transform(), &truth) < 1e-4;
    assert!(
        r.winner().rotation_index == k || (same_matrix && r.winner().rotation_index < k),
        "seed {seed}: rotation {k} recovered as {}",
        r.winner().rotation_index
    );
    // The clouds hold f32 offsets (see `Cloud`): a coordinate is off by at most
    // 2⁻²⁴ × the diagonal, and the translation (from the means) to about that.
    let e = rte(&r.transform(), &truth);
    assert!(e < 4.0 * STORAGE * extent, "seed {seed} k {k}: RTE {e:e}");
    // Perfect overlap: every source cell on a kernel cell, m = 5·n11.
    assert_eq!(r.winner().match_score, 5 * r.stats.target_occupied as i64);
    assert!(r.stats.max_rounding_error < 1e-6);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]
    #[test]
    fn exact_recovery_limited15(seed in 1u64..u64::MAX, k in 0usize..1886,
                                sx in -30i32..30, sy in -30i32..30, sz in -30i32..30) {
        check_recovery(limited15(), seed, k, [sx, sy, sz]);
    }

    #[test]
    fn exact_recovery_ico162(seed in 1u64..u64::MAX, k in 0usize..2836,
                             sx in -30i32..30, sy in -30i32..30, sz in -30i32..30) {
        check_recovery(ico(), seed, k, [sx, sy, sz]);
    }
}

// The other built-in sets, and the all-f64 precision: fewer cases each.
proptest! {
    #![proptest_config(ProptestConfig::with_cases(4))]
    #[test]
    fn exact_recovery_full15(seed in 1u64..u64::MAX, k in 0usize..6364,
                             sx in -30i32..30, sy in -30i32..30, sz in -30i32..30) {
        check_recovery(named_set!("full15"), seed, k, [sx, sy, sz]);
    }

    #[test]
    fn exact_recovery_hopf15(seed in 1u64..u64::MAX, k in 0usize..6912,
                             sx in -30i32..30, sy in -30i32..30, sz in -30i32..30) {
        check_recovery(named_set!("hopf15"), seed, k, [sx, sy, sz]);
    }

    #[test]
    fn exact_recovery_limited10(seed in 1u64..u64::MAX, k in 0usize..6173,
                                sx in -30i32..30, sy in -30i32..30, sz in -30i32..30) {
        check_recovery(named_set!("limited10"), seed, k, [sx, sy, sz]);
    }

    #[test]
    fn exact_recovery_in_f64(seed in 1u64..u64::MAX, k in 0usize..1886,
                             sx in -30i32..30, sy in -30i32..30, sz in -30i32..30) {
        check_recovery_in(limited15(), seed, k, [sx, sy, sz], Precision::F64);
    }
}

fn assert_identical(a: &SearchResult, b: &SearchResult) {
    assert_eq!(a.transform().to_rows(), b.transform().to_rows());
    assert_eq!(a.winner().rotation_index, b.winner().rotation_index);
    assert_eq!(a.winner().score, b.winner().score);
    assert_eq!(a.winner().offset, b.winner().offset);
    assert_eq!(a.hypotheses, b.hypotheses);
    assert_eq!(a.runner_up, b.runner_up);
    assert_eq!(a.ambiguity.map(f64::to_bits), b.ambiguity.map(f64::to_bits));
    assert_eq!(a.stats.geometry, b.stats.geometry);
}

/// Every statistic but the thread count and the memory estimate (one workspace per thread),
/// in the bits the JSON prints.
fn assert_same_stats(a: &SearchResult, b: &SearchResult) {
    let stats = |r: &SearchResult| {
        let mut v = serde_json::to_value(&r.stats).unwrap();
        let o = v.as_object_mut().unwrap();
        o.remove("threads");
        o.remove("memory_estimate_bytes");
        v.to_string()
    };
    assert_eq!(stats(a), stats(b));
}

#[test]
fn bit_identical_for_1_2_and_8_threads() {
    let dir = common::repo_root().join("tests/data");
    let source = read_cloud(&dir.join("bun0.pcd"), None).unwrap().cloud;
    let target = read_cloud(&dir.join("bun4.pcd"), None).unwrap().cloud;
    for set in [limited15(), ico()] {
        let run = |threads| {
            let cfg = SearchConfig {
                threads,
                top_k: 5,
                ..SearchConfig::with_voxel(0.006)
            };
            grid_search(&source, &target, set, &cfg).unwrap()
        };
        let one = run(1);
        assert_eq!(one.hypotheses.len(), 5);
        assert_eq!(one.stats.threads, 1);
        for threads in [2, 8] {
            let r = run(threads);
            assert_eq!(r.stats.threads, threads);
            assert_identical(&one, &r);
            assert_same_stats(&one, &r);
        }
    }
}

/// With a least match fraction the hypotheses are those of the full list, cut after the
/// runner-up at the first below that fraction of the winner's match score, and fewer
/// rotations are re-scored exactly; the winner and the runner-up do not change.
#[test]
fn a_least_match_fraction_cuts_the_list_and_nothing_else() {
    let dir = common::repo_root().join("tests/data");
    let source = read_cloud(&dir.join("bun0.pcd"), None).unwrap().cloud;
    let target = read_cloud(&dir.join("bun4.pcd"), None).unwrap().cloud;
    let run = |fraction| {
        let cfg = SearchConfig {
            top_k: 12,
            min_match_fraction: fraction,
            ..SearchConfig::with_voxel(0.006)
        };
        grid_search(&source, &target, limited15(), &cfg).unwrap()
    };
    let all = run(None);
    assert_eq!(all.hypotheses.len(), 12);
    let win = all.hypotheses[0].match_score as f64;
    let cut = run(Some(0.5));
    let kept = 2 + all.hypotheses[2..]
        .iter()
        .take_while(|h| h.match_score as f64 >= 0.5 * win)
        .count();
    assert!(
        kept < 12,
        "the bundled pair's list reaches below half the winner"
    );
    assert_eq!(cut.hypotheses.len(), kept);
    for (a, b) in cut.hypotheses.iter().zip(&all.hypotheses) {
        assert_eq!(
            (a.rotation_index, a.offset, a.match_score),
            (b.rotation_index, b.offset, b.match_score)
        );
    }
    assert_eq!(
        cut.runner_up.map(|h| h.rotation_index),
        all.runner_up.map(|h| h.rotation_index)
    );
    assert!(cut.stats.rescored <= all.stats.rescored);
}

#[test]
fn top_k_hypotheses_are_distinct_and_ordered() {
    let source = random_cloud(3, 300);
    let target = source.transformed(&Rigid::new(limited15().matrices[700], Vector3::zeros()));
    let cfg = SearchConfig {
        top_k: 6,
        ..SearchConfig::with_voxel(0.08)
    };
    let r = grid_search(&source, &target, limited15(), &cfg).unwrap();
    assert_eq!(r.hypotheses.len(), 6);
    assert_eq!(r.hypotheses[0].rotation_index, r.winner().rotation_index);
    for w in r.hypotheses.windows(2) {
        assert!(w[0].match_score >= w[1].match_score);
    }
    for (i, a) in r.hypotheses.iter().enumerate() {
        for b in &r.hypotheses[i + 1..] {
            assert!(rre(&a.transform, &b.transform) > r.stats.distinct_radius_deg);
        }
    }
    let ru = r.runner_up.unwrap();
    assert_eq!(ru, r.hypotheses[1]);
    let amb = r.ambiguity.unwrap();
    assert!(amb < 1.0 && amb == ru.match_score as f64 / r.winner().match_score as f64);
}

#[test]
fn memory_guard_stops_before_allocating() {
    let source = random_cloud(5, 200);
    let cfg = SearchConfig {
        max_memory: Some(1 << 20),
        ..SearchConfig::with_voxel(0.002)
    };
    let e = grid_search(&source, &source, limited15(), &cfg)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("budget") && e.contains("voxel size of at least"),
        "{e}"
    );
    // The suggested voxel fits.
    let suggested: f64 = e
        .split("voxel size of at least ")
        .nth(1)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let cfg = SearchConfig {
        max_memory: Some(1 << 20),
        ..SearchConfig::with_voxel(suggested)
    };
    grid_search(&source, &source, limited15(), &cfg).unwrap();
}

#[test]
fn memory_guard_stops_the_coarse_to_fine_search_too() {
    let source = random_cloud(5, 200);
    let cfg = SearchConfig {
        max_memory: Some(1 << 20),
        mode: SearchMode::CoarseToFine(CoarseToFine::default()),
        ..SearchConfig::with_voxel(0.002)
    };
    let e = grid_search(&source, &source, limited15(), &cfg)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("budget") && e.contains("voxel size of at least"),
        "{e}"
    );
}

#[test]
fn bad_parameters_are_errors() {
    let c = random_cloud(1, 10);
    for v in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(grid_search(&c, &c, limited15(), &SearchConfig::with_voxel(v)).is_err());
    }
    let cfg = SearchConfig {
        top_k: 0,
        ..SearchConfig::with_voxel(0.1)
    };
    assert!(grid_search(&c, &c, limited15(), &cfg).is_err());
    let e = grid_search(
        &Cloud::default(),
        &c,
        limited15(),
        &SearchConfig::with_voxel(0.1),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("source") && e.contains("empty"), "{e}");
}

#[test]
fn cancellation_stops_the_search() {
    let c = random_cloud(2, 100);
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let cfg = SearchConfig {
        cancel: Some(flag),
        ..SearchConfig::with_voxel(0.1)
    };
    assert!(matches!(
        grid_search(&c, &c, limited15(), &cfg),
        Err(ggs::GgsError::Cancelled)
    ));
}

#[test]
fn georeferenced_coordinates_give_the_same_answer() {
    let dir = common::repo_root().join("tests/data");
    let source = read_cloud(&dir.join("bun0.pcd"), None).unwrap().cloud;
    let target = read_cloud(&dir.join("bun4.pcd"), None).unwrap().cloud;
    let far = Rigid::new(
        nalgebra::Matrix3::identity(),
        Vector3::new(5.0e5, 4.2e6, 120.0),
    );
    let cfg = SearchConfig::with_voxel(0.006);
    let a = grid_search(&source, &target, limited15(), &cfg).unwrap();
    let b = grid_search(
        &source.transformed(&far),
        &target.transformed(&far),
        limited15(),
        &cfg,
    )
    .unwrap();
    assert_eq!(a.winner().rotation_index, b.winner().rotation_index);
    assert_eq!(a.winner().score, b.winner().score);
    let back = far.inverse().compose(&b.transform()).compose(&far);
    assert!(
        rte(&a.transform(), &back) < 1e-6,
        "{}",
        rte(&a.transform(), &back)
    );
}

fn with_mode(voxel: f64, mode: SearchMode, precision: Precision, top_k: usize) -> SearchConfig {
    SearchConfig {
        top_k,
        mode,
        precision,
        threads: 2,
        ..SearchConfig::with_voxel(voxel)
    }
}

/// A partial, noisy, rotated copy: the target drops a fifth of the points and gets 60 the
/// source does not have (uniform in its box), so scores are not a perfect overlap.
fn partial_pair(seed: u64) -> (Cloud, Cloud) {
    let source = random_cloud(seed, 400);
    let mut r = Lcg(seed ^ 0x9e37);
    let rot = nalgebra::Rotation3::from_euler_angles(
        r.next_f64() * 6.0,
        r.next_f64() * 3.0,
        r.next_f64() * 6.0,
    );
    let t = Rigid::new(*rot.matrix(), Vector3::new(0.3, -0.2, 0.1));
    let mut pts: Vec<[f64; 3]> = source
        .transformed(&t)
        .to_points()
        .into_iter()
        .enumerate()
        .filter(|(i, _)| i % 5 != 0)
        .map(|(_, p)| p)
        .collect();
    let b = Cloud::new(pts.clone()).aabb().unwrap();
    let e = b.extent();
    for _ in 0..60 {
        pts.push(std::array::from_fn(|d| b.min[d] + e[d] * r.next_f64()));
    }
    (source, Cloud::new(pts))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]
    /// f32 scoring with error bounds and f64 re-scoring picks exactly what f64 picks: the
    /// winner, the top-k distinct hypotheses and the runner-up.
    #[test]
    fn mixed_precision_picks_equal_f64(seed in 1u64..u64::MAX) {
        let (source, target) = partial_pair(seed);
        let run = |p| {
            grid_search(&source, &target, limited15(),
                &with_mode(0.07, SearchMode::Exhaustive, p, 4)).unwrap()
        };
        let mixed = run(Precision::Mixed);
        let exact = run(Precision::F64);
        assert_identical(&mixed, &exact);
        prop_assert!(mixed.stats.rescored >= 1);
        prop_assert_eq!(exact.stats.rescored, 0);
    }
}

#[test]
fn mixed_precision_equals_f64_on_the_bundled_bunny() {
    let dir = common::repo_root().join("tests/data");
    let source = read_cloud(&dir.join("bun0.pcd"), None).unwrap().cloud;
    let target = read_cloud(&dir.join("bun4.pcd"), None).unwrap().cloud;
    let run = |p| {
        grid_search(
            &source,
            &target,
            limited15(),
            &with_mode(0.006, SearchMode::Exhaustive, p, 5),
        )
        .unwrap()
    };
    assert_identical(&run(Precision::Mixed), &run(Precision::F64));
}

#[test]
fn coarse_to_fine_finds_the_exhaustive_answer() {
    let dir = common::repo_root().join("tests/data");
    let source = read_cloud(&dir.join("bun0.pcd"), None).unwrap().cloud;
    let target = read_cloud(&dir.join("bun4.pcd"), None).unwrap().cloud;
    let c2f = SearchMode::CoarseToFine(CoarseToFine::default());
    for set in [limited15(), ico()] {
        let full = grid_search(
            &source,
            &target,
            set,
            &with_mode(0.006, SearchMode::Exhaustive, Precision::Mixed, 1),
        )
        .unwrap();
        let fast = grid_search(
            &source,
            &target,
            set,
            &with_mode(0.006, c2f, Precision::Mixed, 1),
        )
        .unwrap();
        assert_eq!(fast.winner().rotation_index, full.winner().rotation_index);
        assert_eq!(fast.winner().offset, full.winner().offset);
        assert_eq!(fast.winner().score, full.winner().score);
        assert_eq!(fast.transform().to_rows(), full.transform().to_rows());
        assert!(
            fast.stats.scored < set.len() / 4,
            "{} of {}",
            fast.stats.scored,
            set.len()
        );
        let level = fast.stats.coarse_level.unwrap();
        assert_eq!(level.voxel, 0.012);
        assert!(level.kept >= 16);
    }
}

#[test]
fn stopping_when_the_winner_holds_ends_the_widening_of_a_flat_ranking() {
    // A bunny scan onto a cloud of another shape: no rotation stands out at the coarse
    // level, so the plain rule doubles the kept list round after round (here until every
    // rotation is scored); stopping once a doubling leaves the winner where it was scores
    // fewer rotations in fewer rounds.
    let dir = common::repo_root().join("tests/data");
    let source = read_cloud(&dir.join("bun0.pcd"), None).unwrap().cloud;
    let target = random_cloud(32, 3000);
    let run = |stop: bool| {
        let c2f = CoarseToFine {
            stop_when_winner_holds: stop,
            ..CoarseToFine::default()
        };
        let cfg = with_mode(0.01, SearchMode::CoarseToFine(c2f), Precision::Mixed, 1);
        grid_search(&source, &target, limited15(), &cfg)
            .unwrap()
            .stats
    };
    let (plain, held) = (run(false), run(true));
    let rounds = |s: &ggs::search::SearchStats| s.coarse_level.as_ref().unwrap().rounds;
    assert!(rounds(&plain) >= 3, "plain: {} rounds", rounds(&plain));
    assert!(rounds(&held) < rounds(&plain), "{} rounds", rounds(&held));
    assert!(
        held.scored < plain.scored,
        "{} ≥ {}",
        held.scored,
        plain.scored
    );
}

#[test]
fn coarse_to_fine_recovers_grid_rotations() {
    let c2f = SearchMode::CoarseToFine(CoarseToFine::default());
    for (seed, k) in [(11u64, 5usize), (12, 400), (13, 1234), (14, 1885)] {
        let source = random_cloud(seed, 300);
        let truth = Rigid::new(limited15().matrices[k], Vector3::new(0.16, -0.08, 0.24));
        let target = source.transformed(&truth);
        let r = grid_search(
            &source,
            &target,
            limited15(),
            &with_mode(0.08, c2f, Precision::Mixed, 1),
        )
        .unwrap();
        assert!(rre(&r.transform(), &truth) < 1e-6, "seed {seed} k {k}");
        let extent = source.aabb().unwrap().diagonal();
        let e = rte(&r.transform(), &truth);
        assert!(e < 4.0 * STORAGE * extent, "seed {seed} k {k}: {e:e}");
    }
}

#[test]
fn the_coarse_level_reports_distinct_hypotheses_that_place_the_source() {
    // A cloud moved by a rotation of the set: the coarse level's best hypothesis is that
    // rotation, its translation within one coarse cell diagonal of the truth (the thinned
    // source's cells), and the others are more than the distinct radius apart.
    let set = limited15();
    for (seed, k) in [(21u64, 77usize), (22, 901)] {
        let source = random_cloud(seed, 400);
        let truth = Rigid::new(set.matrices[k], Vector3::new(3.1, -40.7, 12.2));
        let target = source.transformed(&truth);
        let c2f = CoarseToFine {
            hypotheses: 5,
            ..CoarseToFine::default()
        };
        let cfg = with_mode(0.05, SearchMode::CoarseToFine(c2f), Precision::Mixed, 1);
        let r = grid_search(&source, &target, set, &cfg).unwrap();
        let level = r.stats.coarse_level.unwrap();
        assert_eq!(level.hypotheses.len(), 5, "seed {seed}");
        let first = &level.hypotheses[0];
        assert_eq!(first.rotation_index, k, "seed {seed}");
        let cell_diagonal = level.voxel * 3f64.sqrt();
        assert!(
            rte(&first.transform, &truth) <= cell_diagonal,
            "seed {seed}: {} > {cell_diagonal}",
            rte(&first.transform, &truth)
        );
        for (i, a) in level.hypotheses.iter().enumerate() {
            assert!(a.error_bound >= 0.0 && a.match_score.is_finite());
            for b in &level.hypotheses[..i] {
                let apart = ggs::transform::rotation_angle_deg(
                    &set.matrices[a.rotation_index],
                    &set.matrices[b.rotation_index],
                );
                assert!(apart > r.stats.distinct_radius_deg, "seed {seed}: {apart}");
            }
        }
        // Off unless asked for.
        let plain = SearchMode::CoarseToFine(CoarseToFine::default());
        let r = grid_search(
            &source,
            &target,
            set,
            &with_mode(0.05, plain, Precision::Mixed, 1),
        );
        assert!(r.unwrap().stats.coarse_level.unwrap().hypotheses.is_empty());
    }
}

#[test]
fn coarse_to_fine_parameters_are_checked() {
    let c = random_cloud(1, 50);
    for bad in [
        CoarseToFine {
            factor: 0.5,
            ..Default::default()
        },
        CoarseToFine {
            keep_fraction: 1.5,
            ..Default::default()
        },
        CoarseToFine {
            neighbour_deg: Some(f64::NAN),
            ..Default::default()
        },
    ] {
        let cfg = with_mode(0.1, SearchMode::CoarseToFine(bad), Precision::Mixed, 1);
        assert!(grid_search(&c, &c, limited15(), &cfg).is_err());
    }
}

/// A second backend, written outside the library the way a GPU backend would be: exact
/// scores only (the CPU's f64 path behind it), no approximate path of its own, so the
/// search runs on the trait's default `approx` (exact scores as intervals of width 0). It
/// counts the rotations it is asked to score.
mod second_backend {
    use ggs::search::correlator::{
        Backend, BestOffset, Correlator, PassControl, PassTimes, RotatedSources, Scores,
    };
    use ggs::search::{CpuBackend, Geometry, Occupancy};
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    #[derive(Default)]
    pub struct ExactOnly {
        pub scored: Arc<AtomicUsize>,
    }

    struct Plan {
        inner: Box<dyn Correlator>,
        scored: Arc<AtomicUsize>,
    }

    impl Backend for ExactOnly {
        fn plan(
            &self,
            geo: Geometry,
            kernel: &Occupancy,
            _scores: Scores,
        ) -> ggs::Result<Box<dyn Correlator>> {
            Ok(Box::new(Plan {
                inner: CpuBackend.plan(geo, kernel, Scores::Exact)?,
                scored: self.scored.clone(),
            }))
        }
    }

    impl Correlator for Plan {
        fn geometry(&self) -> &Geometry {
            self.inner.geometry()
        }
        fn kernel_cells(&self) -> i64 {
            self.inner.kernel_cells()
        }
        fn kernel_occupied(&self) -> i64 {
            self.inner.kernel_occupied()
        }
        fn exact(
            &self,
            ctl: &PassControl<'_>,
            src: &RotatedSources<'_>,
            indices: &[usize],
        ) -> ggs::Result<(Vec<BestOffset>, PassTimes)> {
            self.scored.fetch_add(indices.len(), Ordering::Relaxed);
            self.inner.exact(ctl, src, indices)
        }
    }
}

#[test]
fn a_second_backend_gives_the_cpu_backends_picks_in_both_modes() {
    let dir = common::repo_root().join("tests/data");
    let source = read_cloud(&dir.join("bun0.pcd"), None).unwrap().cloud;
    let target = read_cloud(&dir.join("bun4.pcd"), None).unwrap().cloud;
    for mode in [
        SearchMode::Exhaustive,
        SearchMode::CoarseToFine(CoarseToFine::default()),
    ] {
        let cfg = SearchConfig {
            top_k: 4,
            mode,
            ..SearchConfig::with_voxel(0.006)
        };
        let cpu = grid_search(&source, &target, limited15(), &cfg).unwrap();
        let backend = second_backend::ExactOnly::default();
        let other =
            ggs::search::grid_search_with(&backend, &source, &target, limited15(), &cfg).unwrap();
        assert_identical(&cpu, &other);
        // It did the work: every rotation scored at the voxel, and the coarse level's too.
        let asked = backend.scored.load(std::sync::atomic::Ordering::Relaxed);
        assert!(
            asked >= other.stats.scored,
            "{asked} < {}",
            other.stats.scored
        );
    }
}
