//! Every option of `ggs register` does what its help says, checked in the JSON it prints;
//! and the result is bit-identical at 1, 2 and 8 threads in every mode and precision.

mod common;

use common::{data, ggs, ggs_json, s, tmp_dir};
use serde_json::Value;

/// `ggs register SOURCE TARGET --json -q` plus `extra`, parsed.
fn run(source: &str, target: &str, extra: &[&str]) -> Value {
    let mut args = vec!["register", source, target, "--json", "-q"];
    args.extend_from_slice(extra);
    ggs_json(&args)
}

/// The bundled PCL pair at its voxel, plus `extra`.
fn small(extra: &[&str]) -> Value {
    let (b0, b4) = (data("bun0.pcd"), data("bun4.pcd"));
    let mut args = vec!["--voxel", "0.006"];
    args.extend_from_slice(extra);
    run(s(&b0), s(&b4), &args)
}

/// The rotation of a JSON 4×4 matrix (rows).
fn rotation(m: &Value) -> [[f64; 3]; 3] {
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (k, x) in row.iter_mut().enumerate() {
            *x = m[i][k].as_f64().unwrap();
        }
    }
    r
}

/// The angle between two rotations, degrees.
fn angle_deg(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> f64 {
    let tr: f64 = (0..3)
        .flat_map(|i| (0..3).map(move |k| a[k][i] * b[k][i]))
        .sum();
    ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn distinct_radius_spaces_the_hypotheses() {
    let mut ids = Vec::new();
    for radius in [10.0, 60.0] {
        let text = radius.to_string();
        let j = small(&["--no-verify", "--top-k", "6", "--distinct-radius", &text]);
        assert_eq!(j["search"]["distinct_radius_deg"], radius);
        let hyps = j["search"]["hypotheses"].as_array().unwrap();
        assert!(hyps.len() >= 3, "{radius}: {} hypotheses", hyps.len());
        for (i, a) in hyps.iter().enumerate() {
            for b in &hyps[i + 1..] {
                let d = angle_deg(&rotation(&a["transform"]), &rotation(&b["transform"]));
                assert!(d > radius, "radius {radius}: two hypotheses {d:.1}° apart");
            }
        }
        ids.push(
            hyps.iter()
                .map(|h| h["rotation_index"].as_u64().unwrap())
                .collect::<Vec<_>>(),
        );
    }
    assert_ne!(ids[0], ids[1], "the radius changed nothing");
}

#[test]
fn verify_score_tight_weighs_closeness_fitness_counts_the_points_within_d() {
    let args = ["--margin", "0", "--max-hypotheses", "3"];
    let tight = small(&args);
    let fitness = small(&[&args[..], &["--verify-score", "fitness"]].concat());
    assert_eq!(tight["verification"]["score"], "tight");
    assert_eq!(fitness["verification"]["score"], "fitness");
    let scores = |j: &Value| -> Vec<f64> {
        j["verification"]["hypotheses"]
            .as_array()
            .unwrap()
            .iter()
            .map(|h| h["evidence"]["score"].as_f64().unwrap())
            .collect()
    };
    let (t, f) = (scores(&tight), scores(&fitness));
    assert_eq!(t.len(), f.len());
    assert!(t.iter().zip(&f).all(|(t, f)| t <= f), "{t:?} {f:?}");
    assert!(t[0] < f[0], "{t:?} {f:?}");
    // Oriented counts a subset of the tight score's points, with the same weights.
    let oriented = small(&[&args[..], &["--verify-score", "oriented"]].concat());
    assert_eq!(oriented["verification"]["score"], "oriented");
    let o = scores(&oriented);
    assert_eq!(o.len(), t.len());
    assert!(o.iter().zip(&t).all(|(o, t)| o <= t), "{o:?} {t:?}");
    let out = ggs(&["register", "x.ply", "y.ply", "--verify-score", "close"]);
    assert!(!out.status.success());
}

#[test]
fn dedup_drops_the_duplicates_of_a_set() {
    let all = small(&["--no-verify", "--rotations", "hopf15"]);
    let dedup = small(&["--no-verify", "--rotations", "hopf15", "--dedup", "0.5"]);
    assert_eq!(all["search"]["rotations"], 6912);
    // hopf15's duplicates are exact: removing them gives hopf15-dedup's 6360.
    assert_eq!(dedup["search"]["rotations"], 6360);
}

#[test]
fn max_distance_and_distance_quantile_set_the_correspondence_distance() {
    let distance = |j: &Value| {
        j["refine"]["report"]["correspondence_distance"]
            .as_f64()
            .unwrap()
    };
    assert_eq!(distance(&small(&["--max-distance", "0.004"])), 0.004);
    let low = distance(&small(&["--distance-quantile", "0.1"]));
    let high = distance(&small(&["--distance-quantile", "0.9"]));
    let default = distance(&small(&[]));
    assert!(low < default && default < high, "{low} {default} {high}");
}

#[test]
fn max_iterations_caps_the_refinement() {
    let free = small(&[]);
    assert!(free["refine"]["report"]["iterations"].as_u64().unwrap() > 2);
    let capped = small(&["--max-iterations", "2"]);
    let report = &capped["refine"]["report"];
    assert_eq!(report["iterations"], 2);
    assert_eq!(report["stop_reason"], "max iterations");
}

#[test]
fn coarse_keep_min_keeps_at_least_that_many_rotations() {
    let default = small(&["--no-verify"]);
    // 1 % of hopf15-id's 6360 rotations, rounded up.
    assert_eq!(default["search"]["coarse_level"]["kept"], 64);
    let more = small(&["--no-verify", "--coarse-keep-min", "200"]);
    assert_eq!(more["search"]["mode"]["keep_min"], 200);
    assert_eq!(more["search"]["coarse_level"]["kept"], 200);
}

#[test]
fn coarse_hypotheses_adds_the_coarse_levels_own_poses_to_the_verified() {
    let level_of = |v: &Value| -> Vec<String> {
        let hs = v["verification"]["hypotheses"].as_array().unwrap();
        hs.iter().map(|h| s_of(&h["level"])).collect()
    };
    let default = small(&[]);
    assert_eq!(default["search"]["mode"]["hypotheses"], 8);
    let reported = default["search"]["coarse_level"]["hypotheses"]
        .as_array()
        .unwrap();
    assert_eq!(reported.len(), 8);
    let levels = level_of(&default);
    // The voxel size's first, then the coarse level's that none of those already has.
    let first_coarse = levels
        .iter()
        .position(|l| l == "coarse")
        .unwrap_or(levels.len());
    assert!(first_coarse >= 1);
    assert!(levels[first_coarse..].iter().all(|l| l == "coarse"));
    assert!(levels.len() - first_coarse <= 8);
    let verified = default["verification"]["hypotheses"].as_array().unwrap();
    for (rank, h) in verified.iter().enumerate() {
        assert_eq!(h["rank"], rank);
        assert!(h["settled"].is_boolean());
        // One stopped on an earlier pose carries that one's evidence and is never chosen.
        if let Some(j) = h["same_as"].as_u64() {
            assert!((j as usize) < rank);
            assert_eq!(h["evidence"], verified[j as usize]["evidence"]);
            assert_ne!(default["verification"]["chosen"], rank);
        } else {
            assert!(h["same_as"].is_null());
        }
    }
    let none = small(&["--coarse-hypotheses", "0"]);
    assert!(none["search"]["coarse_level"]["hypotheses"]
        .as_array()
        .unwrap()
        .is_empty());
    assert!(level_of(&none).iter().all(|l| l == "voxel"));
    // Exhaustive search has no coarse level.
    let exhaustive = small(&["--search", "exhaustive"]);
    assert!(level_of(&exhaustive).iter().all(|l| l == "voxel"));
}

fn s_of(v: &Value) -> String {
    v.as_str().unwrap().to_string()
}

#[test]
fn no_pose_reads_an_e57_scan_in_its_own_frame() {
    let d = tmp_dir("ggs-options", "pose", true);
    let points = ggs::io::read_exact_points(&data("bun0.pcd"), None)
        .unwrap()
        .points;
    // The scan's pose moves it by half a metre: far beyond the pair's 2 mm accuracy.
    let shift = [0.5, -0.2, 0.1];
    let rows = [
        1.0, 0.0, 0.0, shift[0], 0.0, 1.0, 0.0, shift[1], 0.0, 0.0, 1.0, shift[2], 0.0, 0.0, 0.0,
        1.0,
    ];
    let pose = ggs::Rigid::from_row_major(&rows, 1e-12).unwrap();
    let e57 = d.join("bun0.e57");
    let scan = ggs::io::e57::E57Scan {
        points: &points,
        pose: Some(&pose),
    };
    ggs::io::e57::write_e57(&e57, &[scan]).unwrap();
    let b4 = data("bun4.pcd");
    let translation = |j: &Value| -> Vec<f64> {
        (0..3)
            .map(|i| j["transform"][i][3].as_f64().unwrap())
            .collect()
    };
    let posed = run(s(&e57), s(&b4), &["--voxel", "0.006"]);
    let raw = run(s(&e57), s(&b4), &["--voxel", "0.006", "--no-pose"]);
    let bare = small(&[]);
    // Without the pose the scan is bun0.pcd itself: the same answer, bit for bit.
    assert_eq!(raw["transform"], bare["transform"]);
    // With it, the estimate undoes the pose: T_posed · pose = T_raw (to the accuracy).
    let (tp, tr) = (translation(&posed), translation(&raw));
    let r = rotation(&posed["transform"]);
    for i in 0..3 {
        let undone = tp[i] + (0..3).map(|k| r[i][k] * shift[k]).sum::<f64>();
        assert!(
            (undone - tr[i]).abs() < 0.002,
            "axis {i}: {undone} vs {}",
            tr[i]
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// What must not depend on the thread count: the final transform, every verified
/// hypothesis, every coarse hypothesis.
fn fingerprint(j: &Value) -> Value {
    serde_json::json!({
        "transform": j["transform"],
        "verified": j["verification"]["hypotheses"],
        "coarse": j["search"]["hypotheses"],
        "refine": j["refine"]["report"],
    })
}

#[test]
fn every_mode_and_precision_is_bit_identical_at_1_2_and_8_threads() {
    // The 40k-point scans: the summations run over many 1024-point chunks.
    let (src, tgt) = (data("bun045.ply"), data("bun000.ply"));
    let modes: [&[&str]; 3] = [
        &[],
        &["--precision", "f64"],
        &["--search", "exhaustive", "--rotations", "limited15"],
    ];
    for mode in modes {
        let at = |threads: &str| {
            let mut args = vec!["--voxel", "0.005", "--threads", threads];
            args.extend_from_slice(mode);
            fingerprint(&run(s(&src), s(&tgt), &args))
        };
        let one = at("1");
        assert!(one["coarse"].as_array().is_some_and(|h| !h.is_empty()));
        for threads in ["2", "8"] {
            assert_eq!(one, at(threads), "{mode:?} at {threads} threads");
        }
    }
}
