//! `ggs align` end to end on the bundled bunny scans: the files it writes, the frame, the
//! list file and patterns, thread independence and its errors.

mod common;

use common::{assert_fails, data, ggs, ggs_json, s, tmp_dir};
use serde_json::Value;
use std::path::Path;

fn pose(doc: &Value, k: usize) -> Vec<f64> {
    doc["scans"][k]["pose"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
        .collect()
}

/// The document without its times, which differ from run to run.
fn without_times(mut doc: Value) -> Value {
    doc.as_object_mut().unwrap().remove("times");
    for a in doc["attempts"].as_array_mut().unwrap() {
        a.as_object_mut().unwrap().remove("ms");
    }
    doc
}

#[test]
fn two_scans_come_out_in_the_first_ones_frame_with_every_file() {
    let out = tmp_dir("ggs-align", "files", true);
    let (b0, b45) = (data("bun000.ply"), data("bun045.ply"));
    let doc = ggs_json(&["align", s(&b0), s(&b45), "--out", s(&out), "--json", "-q"]);
    assert_eq!(doc["format"], "ggs-alignment/1");
    assert_eq!(doc["anchor"], s(&b0));
    let identity = [
        1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.,
    ];
    assert_eq!(pose(&doc, 0), identity);
    // bun045 is turned about 34° about the vertical (data/pairs.tsv: bunny_bun045_bun000).
    let p = pose(&doc, 1);
    let angle = ((p[0] + p[5] + p[10] - 1.0) / 2.0).acos().to_degrees();
    assert!((angle - 34.3).abs() < 1.0, "{angle}");
    assert!(doc["scans"][1]["confidence"].as_f64().unwrap() > 0.3);
    for f in [
        "poses.json",
        "poses.txt",
        "model.ply",
        "report.html",
        "scans/bun000.ply",
        "scans/bun045.ply",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let written: Value =
        serde_json::from_slice(&std::fs::read(out.join("poses.json")).unwrap()).unwrap();
    assert_eq!(without_times(written), without_times(doc));
    let text = std::fs::read_to_string(out.join("poses.txt")).unwrap();
    assert!(text.contains("bun045.ply (confidence"), "{text}");
}

#[test]
fn a_list_file_a_pattern_and_an_anchor_give_the_same_poses_on_any_thread_count() {
    let out = tmp_dir("ggs-align", "list", true);
    let list = out.join("scans.txt");
    let dir = data("");
    std::fs::write(
        &list,
        format!(
            "# the bundled bunny scans\n\n{}\n",
            s(&dir.join("bun0[04]*.ply"))
        ),
    )
    .unwrap();
    let run = |threads: &str| {
        let args = ["align", "--list", s(&list), "--out", s(&out), "--anchor"];
        let anchor = s(&dir.join("bun045.ply")).to_string();
        let mut all: Vec<&str> = args.to_vec();
        all.extend([anchor.as_str(), "--json", "-q", "--threads", threads]);
        ggs_json(&all)
    };
    let one = run("1");
    assert_eq!(one["scans"].as_array().unwrap().len(), 2);
    assert!(one["anchor"].as_str().unwrap().ends_with("bun045.ply"));
    assert_eq!(pose(&one, 1)[0], 1.0, "the anchor's pose is the identity");
    assert_eq!(without_times(one), without_times(run("2")));
}

#[test]
fn bad_input_is_refused_with_what_is_wrong_and_no_file_written() {
    let out = tmp_dir("ggs-align", "errors", false);
    let b0 = data("bun000.ply");
    let o = s(&out);
    assert_fails(&["align", s(&b0), "--out", o], "at least two scans");
    assert_fails(&["align", s(&b0), "missing.ply", "--out", o], "missing.ply");
    let pattern = s(&data("nothing*.ply")).to_string();
    assert_fails(&["align", s(&b0), &pattern, "--out", o], "no file matches");
    let b45 = data("bun045.ply");
    let two = ["align", s(&b0), s(&b45), "--out", o];
    let with = |extra: &[&'static str]| -> Vec<&str> {
        two.iter().copied().chain(extra.iter().copied()).collect()
    };
    assert_fails(
        &with(&["--anchor", "other.ply"]),
        "--anchor: no scan named \"other.ply\"",
    );
    assert_fails(
        &with(&["--set", "align_min_overlap=2"]),
        "align_min_overlap",
    );
    assert!(!Path::new(o).join("poses.json").exists());
    let list = tmp_dir("ggs-align", "badlist", true).join("l.txt");
    std::fs::write(&list, format!("{}\nabsent.ply\n", s(&b0))).unwrap();
    assert_fails(&["align", "--list", s(&list), "--out", o], "l.txt line 2: ");
    assert_fails(&["align", "--list", s(&list), "--out", o], "absent.ply");
    let out_ok = ggs(&["align", "--help"]);
    assert!(String::from_utf8_lossy(&out_ok.stdout).contains("--anchor"));
}

/// A scan of three points (`tiny.xyz`) in a fresh folder, and an output folder beside it.
fn tiny_scan(tag: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = tmp_dir("ggs-align", tag, true);
    let tiny = dir.join("tiny.xyz");
    std::fs::write(&tiny, "0 0 0\n0.01 0 0\n0 0.01 0\n").unwrap();
    (tiny, dir.join("out"))
}

#[test]
fn an_anchor_that_cannot_be_placed_gives_its_frame_to_another_scan_and_says_so() {
    let (tiny, out) = tiny_scan("anchor");
    let (b0, b45) = (data("bun000.ply"), data("bun045.ply"));
    let run = ggs(&["align", s(&tiny), s(&b0), s(&b45), "--out", s(&out)]);
    assert!(run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains("tiny.xyz is not placed: the common frame is that of"),
        "{err}"
    );
    let doc: Value =
        serde_json::from_slice(&std::fs::read(out.join("poses.json")).unwrap()).unwrap();
    assert_ne!(doc["anchor"], s(&tiny));
    assert_eq!(doc["warnings"].as_array().unwrap().len(), 1);
}

#[test]
fn a_scan_of_three_points_is_not_placed() {
    let (tiny, out) = tiny_scan("tiny");
    let (b0, b45) = (data("bun000.ply"), data("bun045.ply"));
    let doc = ggs_json(&[
        "align",
        s(&b0),
        s(&b45),
        s(&tiny),
        "--out",
        s(&out),
        "--json",
        "-q",
    ]);
    assert!(doc["scans"][2]["pose"].is_null(), "{}", doc["scans"][2]);
    assert!(doc["scans"][1]["pose"].is_array());
    let text = std::fs::read_to_string(out.join("poses.txt")).unwrap();
    assert!(text.contains("tiny.xyz: not placed ("), "{text}");
}
