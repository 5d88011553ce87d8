//! `ggs partial` end to end on the bundled SMPL body.

mod common;

use common::{ggs, s, tmp_dir};
use std::path::PathBuf;
use std::process::Output;

fn tmp(tag: &str) -> PathBuf {
    tmp_dir("ggs-partial-cli", tag, false)
}

fn body() -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/human_woman.obj")
        .canonicalize()
        .unwrap()
        .display()
        .to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn generates_a_benchmark_that_bench_runs() {
    let out = tmp("ok");
    let o = ggs(&[
        "partial",
        &body(),
        "--out",
        s(&out),
        "--points",
        "20000",
        "--preset",
        "fp-o-m",
        "--seed",
        "4",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["preset"], "fp-o-m");
    let pairs = summary["pairs"].as_u64().unwrap();
    assert!(pairs > 0);
    for f in [
        "pairs.tsv",
        "pair_list.csv",
        "views.csv",
        "summary.md",
        "summary.json",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let list = std::fs::read_to_string(out.join("pair_list.csv")).unwrap();
    for line in list.lines().skip(1) {
        let overlap: f64 = line.split(',').nth(4).unwrap().parse().unwrap();
        assert!((30.0..60.0).contains(&overlap), "{line}");
    }
    // The manifest is what `ggs bench manifest` reads.
    let run = out.join("run");
    let o = ggs(&[
        "bench",
        "manifest",
        s(&out.join("pairs.tsv")),
        "--limit",
        "1",
        "--rotations",
        "limited15",
        "--refine",
        "none",
        "--out",
        s(&run),
        "--json",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["pairs"], 1);
    assert_eq!(r["failed_to_run"], 0);
    // The same output folder is refused a second time, accepted with --force.
    let again = ["partial", &body(), "--out", s(&out), "--points", "5000"];
    let o = ggs(&again);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not empty"), "{}", stderr(&o));
    let mut forced = again.to_vec();
    forced.extend(["--force", "-q"]);
    assert!(ggs(&forced).status.success());
    std::fs::remove_dir_all(out).unwrap();
}

#[test]
fn bad_arguments_are_clear_errors() {
    let out = tmp("bad");
    let o = ggs(&["partial", &body(), "--out", s(&out), "--preset", "fp-z-e"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("unknown preset 'fp-z-e'"),
        "{}",
        stderr(&o)
    );
    let o = ggs(&["partial", "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no input"), "{}", stderr(&o));
    let o = ggs(&["partial", &body(), "--out", s(&out), "--group", "body"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no group 'body'"), "{}", stderr(&o));
    let o = ggs(&[
        "partial",
        &body(),
        "--out",
        s(&out),
        "--min-overlap",
        "70",
        "--max-overlap",
        "20",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not a range"), "{}", stderr(&o));
    // An inputs list names the line of its mistake.
    std::fs::create_dir_all(&out).unwrap();
    let list = out.join("list.txt");
    std::fs::write(&list, format!("{}\n{} scale=big\n", body(), body())).unwrap();
    let sub = out.join("o");
    let o = ggs(&["partial", "--inputs-list", s(&list), "--out", s(&sub)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("line 2") && stderr(&o).contains("scale"),
        "{}",
        stderr(&o)
    );
    // Two inputs with one name.
    std::fs::write(&list, format!("{}\n{}\n", body(), body())).unwrap();
    let o = ggs(&["partial", "--inputs-list", s(&list), "--out", s(&sub)]);
    assert!(
        stderr(&o).contains("two inputs are named"),
        "{}",
        stderr(&o)
    );
    assert!(!sub.exists(), "nothing is written after an input error");
    // --fpv1 needs --scans, and the scans must be there.
    let o = ggs(&["partial", "--fpv1", "x.csv", "--out", s(&sub)]);
    assert_eq!(o.status.code(), Some(2));
    let csv = out.join("fpv1.csv");
    std::fs::write(&csv, "Scan,Viewpoint_i,Viewpoint_j,overlap,T00,T01,T02,T03,T10,T11,T12,T13,T20,T21,T22,T23,T30,T31,T32,T33\ntr_scan_000,viewpoint0-[0 1 0],viewpoint1-[1 1 0],70,1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1\n").unwrap();
    let o = ggs(&[
        "partial",
        "--fpv1",
        s(&csv),
        "--scans",
        s(&out),
        "--out",
        s(&sub),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("none of the 1 scans"), "{}", stderr(&o));
    std::fs::remove_dir_all(out).unwrap();
}

#[test]
fn vertices_instead_of_samples() {
    let out = tmp("vertices");
    let o = ggs(&["partial", &body(), "--vertices", "--out", s(&out), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["scans"][0]["points"], 6890);
    assert_eq!(summary["scans"][0]["sampled_from_mesh"], false);
    std::fs::remove_dir_all(out).unwrap();
}
