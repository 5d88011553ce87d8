//! Grid search on every real pair of `shared/data/pairs.tsv` at its suggested voxel.
//!
//! Prints the table of docs/grid-search.md (regenerate it with
//! `cargo test --release -p ggs-bench --test real_pairs -- --nocapture`) and checks the accuracy
//! each rotation set must reach: within 10° and 3 voxels of the ground truth where the set
//! covers the rotation and the overlap is high; 15° / 0.5 m on 3dmatch_demo and 15° / 3
//! voxels on eth_car (the original code lands at 8.7° / 0.32 m and 10.9° / 1.8 m there).
//! Every pair is also searched coarse-to-fine, which must pick exactly the same.

#[path = "../../ggs/tests/common/mod.rs"]
mod common;

use ggs::io::read_cloud;
use ggs::metrics::{rre, rte};
use ggs::refine::{refine, RefineConfig};
use ggs::rotations::RotationSet;
use ggs::search::{grid_search, CoarseToFine, SearchConfig, SearchMode};
use ggs::transform::rotation_angle_deg;
use ggs_bench::manifest::read_manifest;
use nalgebra::Matrix3;
use std::fmt::Write;
use std::time::Instant;

/// Pairs whose rotation every tested set covers (≤ 90°) and whose overlap is high.
const SOLVED_BY_ALL: &[&str] = &[
    "pcl_bun0_bun4",
    "bunny_bun045_bun000",
    "bunny_bun090_bun045",
    "bunny_bun315_bun000",
    "bunny_bun270_bun180",
    "bunny_bun180_bun090",
    "lidar_koide",
];

/// Accuracy bound of a pair: (max RRE in degrees, max RTE in units of the pair).
fn bound(name: &str, voxel: f64) -> Option<(f64, f64)> {
    match name {
        "3dmatch_demo" => Some((15.0, 0.5)),
        "eth_car" => Some((15.0, 3.0 * voxel)),
        n if SOLVED_BY_ALL.contains(&n) => Some((10.0, 3.0 * voxel)),
        _ => None,
    }
}

/// Bound after GICP from the limited15 coarse result: Stanford and PCL scans whose coarse
/// pick is within 15° and 5 voxels end within 1° and 2 mm (bunny_chin_bun000, where the
/// original's refinement stayed at 15°, included); the others within the thresholds (docs/benchmarks.md)
/// of their benchmark (3DMatch 15° / 0.30 m, KITTI 5° / 0.6 m, ETH 5° / 0.30 m).
fn refined_bound(name: &str, coarse_rre: f64, coarse_rte: f64, voxel: f64) -> Option<(f64, f64)> {
    match name {
        "3dmatch_demo" => Some((15.0, 0.30)),
        "lidar_koide" => Some((5.0, 0.6)),
        "eth_car" => Some((5.0, 0.30)),
        _ if coarse_rre <= 15.5 && coarse_rte <= 5.0 * voxel => Some((1.0, 0.002)),
        _ => None,
    }
}

#[test]
fn grid_search_on_real_pairs() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let pairs = read_manifest(&shared.join("data/pairs.tsv")).unwrap();
    assert_eq!(pairs.len(), 13);
    // (set, pairs to run (None = all), extra pairs it must solve)
    type Plan<'a> = (&'a str, Option<&'a [&'a str]>, &'a [&'a str]);
    let plan: [Plan; 3] = [
        ("limited15", None, &[]),
        ("ico162-s10", None, &[]),
        // A uniform full-SO(3) set reaches the 178° pair that the limited set cannot.
        (
            "hopf15-dedup",
            Some(&["bunny_top3_bun315"]),
            &["bunny_top3_bun315"],
        ),
    ];
    let mut table = String::new();
    writeln!(
        table,
        "| set | pair | GT angle ° | nearest set rotation ° | RRE ° | RTE | RTE / voxel | ambiguity | s | required |"
    )
    .unwrap();
    writeln!(table, "|---|---|---|---|---|---|---|---|---|---|").unwrap();
    let mut failures = Vec::new();
    let mut refined = String::new();
    writeln!(
        refined,
        "| pair | coarse RRE ° | coarse RTE | RRE ° | RTE | required | fitness src/tgt | inlier RMSE | iterations | GICP ms |"
    )
    .unwrap();
    writeln!(refined, "|---|---|---|---|---|---|---|---|---|---|").unwrap();
    for (set_name, only, extra) in plan {
        let set = RotationSet::named(set_name).unwrap();
        for pair in &pairs {
            if only.is_some_and(|o| !o.contains(&pair.name.as_str())) {
                continue;
            }
            let source = read_cloud(&pair.source, None).unwrap().cloud;
            let target = read_cloud(&pair.target, None).unwrap().cloud;
            let t0 = Instant::now();
            let r = grid_search(
                &source,
                &target,
                &set,
                &SearchConfig::with_voxel(pair.voxel),
            )
            .unwrap();
            let secs = t0.elapsed().as_secs_f64();
            // The coarse-to-fine search picks what the exhaustive one picks.
            let fast = grid_search(
                &source,
                &target,
                &set,
                &SearchConfig {
                    mode: SearchMode::CoarseToFine(CoarseToFine::default()),
                    ..SearchConfig::with_voxel(pair.voxel)
                },
            )
            .unwrap();
            if (
                fast.winner().rotation_index,
                fast.winner().offset,
                fast.winner().score,
            ) != (
                r.winner().rotation_index,
                r.winner().offset,
                r.winner().score,
            ) {
                failures.push(format!(
                    "{set_name} {}: coarse-to-fine picked rotation {} score {}, exhaustive {} score {}",
                    pair.name, fast.winner().rotation_index, fast.winner().score, r.winner().rotation_index, r.winner().score
                ));
            }
            let gt = &pair.ground_truth;
            let (e_r, e_t) = (rre(&r.transform(), gt), rte(&r.transform(), gt));
            let gt_angle = rotation_angle_deg(&Matrix3::identity(), &gt.rotation);
            let nearest = set
                .matrices
                .iter()
                .map(|m| rotation_angle_deg(m, &gt.rotation))
                .fold(f64::INFINITY, f64::min);
            let required = if extra.contains(&pair.name.as_str()) {
                Some((10.0, 3.0 * pair.voxel))
            } else if only.is_none() {
                bound(&pair.name, pair.voxel)
            } else {
                None
            };
            let verdict = match required {
                Some((mr, mt)) if e_r <= mr && e_t <= mt => "yes: pass".to_string(),
                Some((mr, mt)) => {
                    failures.push(format!(
                        "{set_name} {}: RRE {e_r:.2}° (max {mr}), RTE {e_t:.4} (max {mt})",
                        pair.name
                    ));
                    "yes: FAIL".to_string()
                }
                None => "no".to_string(),
            };
            // GICP only where its result is held to a bound: from a coarse pick outside the
            // basin it has nothing to show (and ran to its iteration cap for no assertion).
            let need = refined_bound(&pair.name, e_r, e_t, pair.voxel);
            if set_name == "limited15" && need.is_none() {
                writeln!(
                    refined,
                    "| {} | {e_r:.2} | {e_t:.4} | — | — | not refined: coarse pick outside the basin | | | | |",
                    pair.name
                )
                .unwrap();
            } else if set_name == "limited15" {
                let g = refine(&source, &target, &r.transform(), &RefineConfig::default()).unwrap();
                let (f_r, f_t) = (rre(&g.transform, gt), rte(&g.transform, gt));
                let ok = need.is_none_or(|(mr, mt)| f_r < mr && f_t < mt);
                if !ok {
                    failures.push(format!(
                        "limited15+GICP {}: RRE {f_r:.3}° RTE {f_t:.4} (bound {need:?})",
                        pair.name
                    ));
                }
                let q = &g.report;
                writeln!(
                    refined,
                    "| {} | {e_r:.2} | {e_t:.4} | {f_r:.3} | {f_t:.4} | {} | {:.3} / {:.3} | {:.5} | {} | {:.0} |",
                    pair.name,
                    match (need, ok) {
                        (None, _) => unreachable!("refined only with a bound"),
                        (Some((mr, mt)), true) => format!("< {mr}° / {mt} m: pass"),
                        (Some((mr, mt)), false) => format!("< {mr}° / {mt} m: FAIL"),
                    },
                    q.fitness_source,
                    q.fitness_target,
                    q.inlier_rmse,
                    q.iterations,
                    g.total_ms
                )
                .unwrap();
            }
            writeln!(
                table,
                "| {set_name} | {} | {gt_angle:.1} | {nearest:.1} | {e_r:.2} | {e_t:.4} | {:.2} | {} | {secs:.2} | {verdict} |",
                pair.name,
                e_t / pair.voxel,
                r.ambiguity.map_or("n/a".into(), |a| format!("{a:.3}")),
            )
            .unwrap();
        }
    }
    eprintln!("\n{table}");
    eprintln!("\nlimited15 + GICP\n\n{refined}");
    assert!(
        failures.is_empty(),
        "pairs outside their bound:\n{}",
        failures.join("\n")
    );
}
