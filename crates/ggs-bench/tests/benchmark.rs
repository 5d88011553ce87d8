//! Benchmark protocols and the resumable runner.

#[path = "../../ggs/tests/common/mod.rs"]
mod common;

use ggs::io::kitti::write_kitti_bin;
use ggs::transform::Rigid;
use ggs::Settings;
use ggs_bench::benchmark::protocol::{eth_selection, parse_gt_log, Protocol};
use ggs_bench::benchmark::{missing_files, run, BenchPair, CloudRef, Plan, RunConfig};
use std::path::{Path, PathBuf};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ggs-bench-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn shipped_protocols_have_the_published_pair_counts() {
    let nowhere = Path::new("/nonexistent-data");
    assert_eq!(Protocol::ThreeDMatch.pairs(nowhere).unwrap().len(), 1523);
    assert_eq!(Protocol::Kitti.pairs(nowhere).unwrap().len(), 555);
    assert_eq!(eth_selection().unwrap().len(), 713);
    let fp = Protocol::Fpv1.pairs(nowhere).unwrap();
    assert_eq!(fp.len(), 1724);
    let ids: std::collections::HashSet<&str> = fp.iter().map(|p| p.id.as_str()).collect();
    assert_eq!(ids.len(), 1724, "pair ids are unique");
    // ETH per scene, as in Perfect Match's benchmark.
    let per_scene = |s: &str| eth_selection().unwrap().iter().filter(|p| p.0 == s).count();
    assert_eq!(
        [
            per_scene("gazebo_summer"),
            per_scene("gazebo_winter"),
            per_scene("wood_autmn"),
            per_scene("wood_summer")
        ],
        [184, 289, 115, 125]
    );
}

#[test]
fn threedmatch_ground_truth_equals_the_reference_gt_logs() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let data = Path::new("/data");
    let pairs = Protocol::ThreeDMatch.pairs(data).unwrap();
    let gt_dir = shared.join("reference/protocols/3dmatch_gt");
    let mut checked = 0;
    for scene in std::fs::read_dir(&gt_dir).unwrap() {
        let scene = scene.unwrap().path();
        let name = scene.file_name().unwrap().to_str().unwrap().to_string();
        let log_path = scene.join("gt.log");
        let log = parse_gt_log(&log_path, &std::fs::read_to_string(&log_path).unwrap()).unwrap();
        for p in pairs
            .iter()
            .filter(|p| p.id.starts_with(&format!("{name}/")))
        {
            let (i, j) = p.id[name.len() + 1..].split_once('_').unwrap();
            let t = log[&(i.parse().unwrap(), j.parse().unwrap())];
            assert!(
                (t.rotation - p.ground_truth.rotation).amax() < 1e-8,
                "{}",
                p.id
            );
            assert!((t.translation - p.ground_truth.translation).amax() < 1e-8);
            // gt.log maps cloud j into cloud i: source j, target i.
            assert_eq!(
                p.source,
                CloudRef::File(data.join(&name).join(format!("cloud_bin_{j}.ply")))
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 1523);
}

#[test]
fn kitti_and_fpv1_rows_match_the_reference_csv() {
    let data = Path::new("/d");
    let k = Protocol::Kitti.pairs(data).unwrap();
    assert_eq!(k[0].id, "08/000014_000000");
    assert_eq!(
        k[0].source,
        CloudRef::File(data.join("08/velodyne/000000.bin"))
    );
    assert!((k[0].ground_truth.translation.x + 9.181639565156512).abs() < 1e-12);
    let f = Protocol::Fpv1.pairs(data).unwrap();
    assert_eq!(f[0].id, "tr_scan_000/0_4");
    assert!((f[0].overlap.unwrap() - 0.6010421709046385).abs() < 1e-12);
    assert!((f[0].ground_truth.rotation[(0, 0)] - 0.7657525588658064).abs() < 1e-12);
    match &f[0].target {
        CloudRef::Visible {
            indices, transform, ..
        } => {
            assert_eq!(indices, &data.join("visible/tr_scan_000/0.txt"));
            assert_eq!(transform.as_ref(), Some(&f[0].ground_truth));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn eth_reads_the_users_gt_logs_and_names_missing_ones() {
    let dir = temp_dir("eth");
    let e = Protocol::Eth.pairs(&dir).unwrap_err().to_string();
    assert!(
        e.contains("4 missing") && e.contains("gazebo_summer"),
        "{e}"
    );
    // gt.log records in either direction.
    let sel = eth_selection().unwrap();
    for scene in ggs_bench::benchmark::protocol::ETH_SCENES {
        std::fs::create_dir_all(dir.join(scene)).unwrap();
        let mut log = String::new();
        for (s, i, j, _) in sel.iter().filter(|p| p.0 == scene) {
            assert_eq!(s, scene);
            let (a, b, x) = if (i + j) % 2 == 0 {
                (i, j, 1.0)
            } else {
                (j, i, -1.0)
            };
            log += &format!("{a} {b} 2\n1 0 0 {x}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
        }
        std::fs::write(dir.join(scene).join("gt.log"), log).unwrap();
    }
    let pairs = Protocol::Eth.pairs(&dir).unwrap();
    assert_eq!(pairs.len(), 713);
    for p in &pairs {
        // Inverted where the record was (j, i): always +1 along x.
        assert_eq!(p.ground_truth.translation.x, 1.0, "{}", p.id);
    }
    let (count, first) = missing_files(&pairs, 3);
    assert!(count > 100 && first.len() == 3, "{count}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A tiny KITTI-layout data set from the bundled bunny views, three pairs.
fn kitti_like(dir: &Path) -> Vec<BenchPair> {
    let root = common::repo_root().join("tests/data");
    let a = ggs::io::read_cloud(&root.join("bun0.pcd"), None)
        .unwrap()
        .cloud;
    let b = ggs::io::read_cloud(&root.join("bun4.pcd"), None)
        .unwrap()
        .cloud;
    let gt_text = std::fs::read_to_string(root.join("bun0_to_bun4_groundtruth.txt")).unwrap();
    let v: Vec<f64> = gt_text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .flat_map(str::split_whitespace)
        .map(|s| s.parse().unwrap())
        .collect();
    let gt = Rigid::from_row_major(&v, 1e-6).unwrap();
    let seq = dir.join("08/velodyne");
    std::fs::create_dir_all(&seq).unwrap();
    write_kitti_bin(&seq.join("000000.bin"), &a.to_points()).unwrap();
    write_kitti_bin(&seq.join("000001.bin"), &b.to_points()).unwrap();
    let file = |f: &str| CloudRef::File(seq.join(f));
    let pair = |id: &str, s: &str, t: &str, gt: Rigid| BenchPair {
        id: id.into(),
        source: file(s),
        target: file(t),
        ground_truth: gt,
        voxel: Some(0.01),
        overlap: None,
    };
    vec![
        pair("a", "000000.bin", "000001.bin", gt),
        pair("b", "000001.bin", "000000.bin", gt.inverse()),
        pair("missing", "000002.bin", "000000.bin", gt),
    ]
}

/// The default pipeline on 2 threads.
fn config() -> RunConfig {
    RunConfig {
        voxel: None,
        settings: Settings::default(),
        threads: 2,
        cancel: None,
        max_rre_deg: 10.0,
        max_rte: Some(0.01),
        default_voxel: None,
        motion_seed: None,
    }
}

fn without_times(csv: &str) -> String {
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    csv.lines()
        .map(|l| {
            l.split(',')
                .zip(&header)
                .filter(|(_, h)| !h.ends_with("_ms"))
                .map(|(f, _)| f)
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// A plan of `pairs` (built directly, not from a protocol) with `cfg`.
fn kitti_plan(pairs: &[BenchPair], cfg: &RunConfig) -> Plan {
    Plan {
        name: "kitti-like",
        pairs: pairs.to_vec(),
        cfg: cfg.clone(),
        metres: true,
        shard: None,
    }
}

#[test]
fn an_interrupted_run_resumes_to_the_same_csv() {
    let dir = temp_dir("resume");
    let pairs = kitti_like(&dir.join("data"));
    let whole = dir.join("whole");
    let once = run(&kitti_plan(&pairs, &config()), &whole, |_, _, _| {}).unwrap();
    assert_eq!(once.summary.pairs, 3);
    assert_eq!(once.summary.failed_to_run, 1);
    assert!(once.rows[2]
        .error
        .as_deref()
        .unwrap()
        .contains("000002.bin"));
    assert!(
        once.rows[0].success && once.rows[1].success,
        "{:?}",
        once.rows
    );
    // "Kill" after the first pair: run a prefix, tear the last line, then run everything.
    let part = dir.join("part");
    run(&kitti_plan(&pairs[..2], &config()), &part, |_, _, _| {}).unwrap();
    let mut text = std::fs::read_to_string(part.join("pairs.csv")).unwrap();
    let keep = text.trim_end().rfind('\n').unwrap() + 1;
    text.truncate(keep + 10);
    std::fs::write(part.join("pairs.csv"), &text).unwrap();
    let resumed = run(&kitti_plan(&pairs, &config()), &part, |_, _, _| {}).unwrap();
    assert_eq!(resumed.resumed, 1);
    let a = std::fs::read_to_string(whole.join("pairs.csv")).unwrap();
    let b = std::fs::read_to_string(part.join("pairs.csv")).unwrap();
    assert_eq!(without_times(&a), without_times(&b));
    for f in ["results.json", "summary.md", "recall.svg"] {
        assert!(part.join(f).is_file(), "{f}");
    }
    let md = std::fs::read_to_string(part.join("summary.md")).unwrap();
    assert!(md.contains("| kitti-like | 3 | 66.67 |"), "{md}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_run_directory_of_another_configuration_is_refused() {
    let dir = temp_dir("config");
    let pairs = kitti_like(&dir.join("data"));
    let out = dir.join("run");
    run(&kitti_plan(&pairs[..1], &config()), &out, |_, _, _| {}).unwrap();
    assert!(out.join("run.json").is_file());
    // The same configuration resumes (on any thread count)...
    let mut same = config();
    same.threads = 1;
    let again = run(&kitti_plan(&pairs[..1], &same), &out, |_, _, _| {}).unwrap();
    assert_eq!(again.resumed, 1);
    // ...another one does not mix its rows with the earlier ones.
    let mut other = config();
    other.max_rre_deg = 5.0;
    let e = run(&kitti_plan(&pairs, &other), &out, |_, _, _| {})
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("run.json") && e.contains("another configuration"),
        "{e}"
    );
    let mut moved = config();
    moved.motion_seed = Some(3);
    assert!(run(&kitti_plan(&pairs, &moved), &out, |_, _, _| {}).is_err());
    // The final refinement's resolution and the memory budget are settings of the run too.
    let mut full_resolution = config();
    full_resolution.settings.refine_cell = 0.0;
    assert!(run(&kitti_plan(&pairs, &full_resolution), &out, |_, _, _| {}).is_err());
    let mut budget = config();
    budget.settings.max_memory = Some(1 << 40);
    assert!(run(&kitti_plan(&pairs, &budget), &out, |_, _, _| {}).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn visible_point_views_load_and_register() {
    // FAUST-partial style: two index sets of one scan, the target moved by T.
    let dir = temp_dir("visible");
    let scan = common::repo_root().join("tests/data/bun0.pcd");
    let n = ggs::io::read_cloud(&scan, None).unwrap().cloud.len();
    let write = |name: &str, idx: Vec<usize>| {
        let p = dir.join(name);
        let text: Vec<String> = idx.iter().map(usize::to_string).collect();
        std::fs::write(&p, text.join("\n")).unwrap();
        p
    };
    let a = write("a.txt", (0..n * 3 / 4).collect());
    let b = write("b.txt", (n / 4..n).collect());
    let t = Rigid::new(
        *nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.5).matrix(),
        nalgebra::Vector3::new(0.05, -0.02, 0.01),
    );
    let pair = BenchPair {
        id: "scan/0_1".into(),
        source: CloudRef::Visible {
            cloud: scan.clone(),
            indices: b,
            transform: None,
        },
        target: CloudRef::Visible {
            cloud: scan.clone(),
            indices: a,
            transform: Some(t),
        },
        ground_truth: t,
        voxel: Some(0.006),
        overlap: Some(0.5),
    };
    let target = pair.target.load().unwrap();
    assert_eq!(target.len(), n * 3 / 4);
    let row = ggs_bench::benchmark::run_pair(&pair, &config());
    assert!(row.success, "{row:?}");
    assert!(row.rre < 0.5 && row.rte < 1e-3, "{row:?}");
    // Bad index files are named with the line.
    let bad = write("bad.txt", vec![]);
    std::fs::write(&bad, "0 1\n2 x\n").unwrap();
    let e = ggs_bench::benchmark::read_indices(&bad, n)
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 2") && e.contains("'x'"), "{e}");
    std::fs::write(&bad, format!("{n}\n")).unwrap();
    let e = ggs_bench::benchmark::read_indices(&bad, n)
        .unwrap_err()
        .to_string();
    assert!(e.contains("out of range"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
