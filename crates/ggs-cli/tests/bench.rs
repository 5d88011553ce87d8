//! `ggs bench` end to end, on a manifest of the bundled PCL bunny pair.

mod common;

use common::{ggs, s, tmp_dir};
use std::path::{Path, PathBuf};
use std::process::Output;

fn tmp(tag: &str) -> PathBuf {
    tmp_dir("ggs-bench-cli", tag, true)
}

/// A manifest with the bundled pair both ways (absolute paths).
fn manifest(dir: &Path) -> PathBuf {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data")
        .canonicalize()
        .unwrap();
    let t = "0.825336 0 -0.564642 0.037267 0 1 0 0 0.564642 0 0.825336 0.038325 0 0 0 1";
    let ti = "0.825336 0 0.564642 -0.052397 0 1 0 0 -0.564642 0 0.825336 -0.010588 0 0 0 1";
    let (b0, b4) = (data.join("bun0.pcd"), data.join("bun4.pcd"));
    let text = format!(
        "# name\tsource\ttarget\tT\tquality\tvoxel\n\
         fwd\t{}\t{}\t{t}\texact\t0.006\n\
         back\t{}\t{}\t{ti}\texact\t0.006\n",
        b0.display(),
        b4.display(),
        b4.display(),
        b0.display()
    );
    let p = dir.join("pairs.tsv");
    std::fs::write(&p, text).unwrap();
    p
}

/// `ggs bench manifest M --out OUT` plus `extra`.
fn bench_manifest(m: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["bench", "manifest", s(m), "--out", s(out)];
    args.extend_from_slice(extra);
    ggs(&args)
}

#[test]
fn manifest_run_writes_its_files_and_resumes() {
    let dir = tmp("manifest");
    let m = manifest(&dir);
    let out = dir.join("run");
    let o = bench_manifest(&m, &out, &["--threads", "2"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("| manifest | 2 | 100.00 |"), "{stdout}");
    assert!(stdout.contains("RRE < 10° and RTE < 0.018"), "{stdout}");
    for f in ["pairs.csv", "results.json", "summary.md", "recall.svg"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(json["summary"]["successes"], 2);
    assert_eq!(json["pairs"][1]["id"], "back");
    // Run again: nothing new to do.
    let o = bench_manifest(&m, &out, &["--json", "-q"]);
    assert!(o.status.success());
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["recall"], 1.0);
    // --pairs selects by id.
    let o = bench_manifest(&m, &out, &["--pairs", "back"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("1 pairs (1 from an earlier run)"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--voxel auto` registers with the voxel `ggs register` picks with no flag, and keeps the
/// pair's own thresholds (3 × its voxel for the RTE).
#[test]
fn voxel_auto_registers_as_with_no_flag_and_keeps_the_pairs_thresholds() {
    let dir = tmp("auto");
    let m = manifest(&dir);
    let out = dir.join("run");
    let o = bench_manifest(&m, &out, &["--voxel", "auto", "--threads", "2", "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data");
    let plain = ggs(&[
        "register",
        s(&data.join("bun0.pcd")),
        s(&data.join("bun4.pcd")),
        "--json",
        "-q",
    ]);
    let plain: serde_json::Value = serde_json::from_slice(&plain.stdout).unwrap();
    let fwd = &json["pairs"][0];
    assert_eq!(fwd["voxel"], plain["voxel"], "{fwd}");
    assert_ne!(fwd["voxel"], 0.006);
    assert_eq!(fwd["max_rte"], 3.0 * 0.006);
    let rows: Vec<serde_json::Value> = plain["transform"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r.as_array().unwrap().clone())
        .collect();
    assert_eq!(fwd["transform"], serde_json::Value::Array(rows));
    let run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("run.json")).unwrap()).unwrap();
    assert_eq!(run["voxel"], "auto");
    assert_fails(
        &["bench", "manifest", s(&m), "--voxel", "big"],
        "'big' is neither 'auto' nor a positive number",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

fn assert_fails(args: &[&str], needle: &str) {
    let o = ggs(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(
        err.contains(needle),
        "{args:?}: expected '{needle}' in: {err}"
    );
}

#[test]
fn bench_errors_come_before_any_work() {
    let dir = tmp("errors");
    let d = s(&dir);
    assert_fails(&["bench", "3dmatch"], "3dmatch needs --data DIR");
    assert_fails(
        &["bench", "kitti", "--data", d],
        "file(s) the kitti pairs need are missing",
    );
    assert_fails(&["bench", "kitti", "--data", d], "08/velodyne/000000.bin");
    assert_fails(
        &["bench", "eth", "--data", d],
        "ETH needs each scene's gt.log; 4 missing",
    );
    assert_fails(&["bench", "nope", "--data", d], "unknown protocol 'nope'");
    assert_fails(
        &["bench", "manifest"],
        "manifest needs the manifest file's path",
    );
    let m = manifest(&dir);
    assert_fails(
        &["bench", "manifest", s(&m), "--data", d],
        "--data is not used",
    );
    assert_fails(
        &["bench", "manifest", s(&m), "--pairs", "zzz"],
        "no pair selected",
    );
    // A results file from something else is never overwritten.
    let out = dir.join("foreign");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("pairs.csv"), "a,b\n").unwrap();
    assert_fails(
        &["bench", "manifest", s(&m), "--out", s(&out)],
        "not a ggs results file",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_report_shows_every_pair_and_pictures_the_failed_one() {
    let dir = tmp("report");
    let m = manifest(&dir);
    // A third pair whose "ground truth" is the identity: the right answer counts as a failure.
    let mut text = std::fs::read_to_string(&m).unwrap();
    let fwd = text.lines().nth(1).unwrap().to_string();
    let mut wrong: Vec<&str> = fwd.split('\t').collect();
    wrong[0] = "wrong/truth";
    wrong[3] = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";
    text += &(wrong.join("\t") + "\n");
    std::fs::write(&m, text).unwrap();
    let out = dir.join("run");
    let o = bench_manifest(&m, &out, &["--threads", "2", "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("2 of 3 pairs registered"), "summary banner");
    assert!(html.contains("Failed pairs (1)") && html.contains("<b>wrong/truth</b>"));
    assert!(!html.contains("(no picture)") && !html.contains("In progress"));
    assert_eq!(
        html.matches("data:image/png;base64,").count(),
        1,
        "one failure picture"
    );
    assert_eq!(html.matches("<tr class=\"fail\">").count(), 1);
    for id in ["fwd", "back"] {
        assert!(
            html.contains(&format!("<td class=\"l\">{id}</td>")),
            "{id} in the table"
        );
    }
    let pictures: Vec<_> = std::fs::read_dir(out.join("gallery")).unwrap().collect();
    assert_eq!(pictures.len(), 1, "one picture in gallery/");
    // The right pose's rank is recorded: no hypothesis matches an identity "truth".
    let csv = std::fs::read_to_string(out.join("pairs.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = header.iter().position(|c| *c == "right_rank").unwrap();
    let fwd_row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    assert_eq!(
        fwd_row[col], "0",
        "the coarse winner is right on the bundled pair"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// pairs.csv without its `*_ms` columns.
fn rows_without_times(path: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|&k| !header[k].ends_with("_ms"))
        .collect();
    std::iter::once(header.iter().map(|s| s.to_string()).collect())
        .chain(lines.map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            keep.iter().map(|&k| f[k].to_string()).collect()
        }))
        .collect()
}

#[test]
fn shards_merge_into_the_single_run_and_refuse_what_does_not_fit() {
    let dir = tmp("shards");
    let m = manifest(&dir);
    let mut text = std::fs::read_to_string(&m).unwrap();
    let fwd = text.lines().nth(1).unwrap().replacen("fwd", "fwd-again", 1);
    text += &(fwd + "\n");
    std::fs::write(&m, text).unwrap();
    let run = |out: &Path, extra: &[&str]| {
        let o = bench_manifest(&m, out, &[&["-q", "--threads", "1"], extra].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(&dir.join("all"), &[]);
    run(&dir.join("s0"), &["--shard", "0/2"]);
    run(&dir.join("s1"), &["--shard", "1/2"]);
    let shards = [dir.join("s1"), dir.join("s0")]; // any order
    let merged = dir.join("merged");
    let merge = |dirs: &[PathBuf], out: &Path| {
        let mut args = vec!["bench", "merge"];
        args.extend(dirs.iter().map(|d| s(d)));
        args.extend(["--out", s(out)]);
        ggs(&args)
    };
    let o = merge(&shards, &merged);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        rows_without_times(&merged.join("pairs.csv")),
        rows_without_times(&dir.join("all").join("pairs.csv"))
    );
    for f in [
        "results.json",
        "summary.md",
        "recall.svg",
        "report.html",
        "run.json",
    ] {
        assert!(merged.join(f).is_file(), "{f}");
    }
    // A missing shard, a shard given twice, an unfinished shard: refused, named.
    let o = merge(&shards[..1], &dir.join("m2"));
    assert!(
        !o.status.success() && String::from_utf8_lossy(&o.stderr).contains("shard 0/2 is missing")
    );
    let o = merge(&[shards[0].clone(), shards[0].clone()], &dir.join("m3"));
    assert!(String::from_utf8_lossy(&o.stderr).contains("given twice"));
    let csv = shards[0].join("pairs.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let cut = text.trim_end().rfind('\n').unwrap();
    std::fs::write(&csv, &text[..=cut]).unwrap();
    let o = merge(&shards, &dir.join("m4"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("shard 1/2 is not finished") && err.contains("resume"),
        "{err}"
    );
    // Resuming the shard finishes it, and the merge then succeeds.
    run(&shards[0], &["--shard", "1/2"]);
    assert!(merge(&shards, &dir.join("m5")).status.success());
    // A run directory of another shard is not reused.
    let o = bench_manifest(&m, &shards[0], &["-q", "--shard", "0/2"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("another shard"));
    assert!(!bench_manifest(&m, &dir.join("x"), &["--shard", "2/2"])
        .status
        .success());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn min_recall_fails_the_run_below_it_and_the_rows_do_not_depend_on_threads() {
    let dir = tmp("min-recall");
    let m = manifest(&dir);
    // 0.001° is beyond GICP's accuracy on these scans: both pairs fail, recall 0.
    let strict = ["-q", "--max-rre", "0.001", "--min-recall", "50"];
    let o = bench_manifest(&m, &dir.join("strict"), &strict);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("recall 0.00 % is below --min-recall 50 % (0 of 2 pairs)"),
        "{err}"
    );
    // The files are written all the same.
    assert!(dir.join("strict/results.json").is_file());
    let o = bench_manifest(&m, &dir.join("met"), &["-q", "--min-recall", "100"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The same rows (apart from times) with 1 and 8 threads per pair.
    let o = bench_manifest(&m, &dir.join("eight"), &["-q", "--threads", "8"]);
    assert!(o.status.success());
    let o = bench_manifest(&m, &dir.join("one"), &["-q", "--threads", "1"]);
    assert!(o.status.success());
    assert_eq!(
        rows_without_times(&dir.join("one/pairs.csv")),
        rows_without_times(&dir.join("eight/pairs.csv"))
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
