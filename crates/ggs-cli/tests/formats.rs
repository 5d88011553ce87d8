//! Every format through the command line: `ggs convert` between all of them, `ggs register`
//! on any pair of formats, `ggs info`, and the errors of each.

mod common;

use common::{assert_fails as fails, data, ggs, s, tmp_dir};
use std::path::{Path, PathBuf};

/// Extensions `ggs convert` writes, and whether they keep f64 exactly.
const WRITABLE: [(&str, bool); 10] = [
    ("ply", true),
    ("pcd", true),
    ("xyz", true),
    ("csv", true),
    ("npy", true),
    ("e57", true),
    ("bin", false),
    ("las", false),
    ("laz", false),
    ("pts", true),
];

fn ok(args: &[&str]) -> String {
    let o = ggs(args);
    assert!(
        o.status.success(),
        "ggs {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

/// `bun0.pcd` and `bun4.pcd` converted to every writable format (and ascii PLY).
fn converted(d: &Path) -> Vec<(String, PathBuf, PathBuf)> {
    let mut out = Vec::new();
    for (ext, _) in WRITABLE {
        let a = d.join(format!("bun0.{ext}"));
        let b = d.join(format!("bun4.{ext}"));
        ok(&["convert", "-q", s(&data("bun0.pcd")), s(&a)]);
        ok(&["convert", "-q", s(&data("bun4.pcd")), s(&b)]);
        out.push((ext.to_string(), a, b));
    }
    let (a, b) = (d.join("bun0.ascii.ply"), d.join("bun4.ascii.ply"));
    ok(&["convert", "-q", "--ascii", s(&data("bun0.pcd")), s(&a)]);
    ok(&["convert", "-q", "--ascii", s(&data("bun4.pcd")), s(&b)]);
    out.push(("ascii ply".to_string(), a, b));
    out
}

fn points(p: &Path) -> Vec<ggs::Point> {
    ggs::io::read_exact_points(p, None).unwrap().points
}

#[test]
fn convert_round_trips_every_writable_format() {
    let d = tmp_dir("ggs-formats", "convert", true);
    let original = points(&data("bun0.pcd"));
    for (ext, a, _) in converted(&d) {
        let back = points(&a);
        assert_eq!(back.len(), original.len(), "{ext}");
        let exact = WRITABLE.iter().find(|w| w.0 == ext).is_none_or(|w| w.1);
        for (p, q) in back.iter().zip(&original) {
            for k in 0..3 {
                if exact {
                    assert_eq!(p[k], q[k], "{ext}");
                } else {
                    // float32 (KITTI) or a LAS scale of at most 1e-9 of a 0.2 m extent.
                    assert!(
                        (p[k] - q[k]).abs() <= 1e-7 * (1.0 + q[k].abs()),
                        "{ext}: {p:?} {q:?}"
                    );
                }
            }
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn register_accepts_any_pair_of_formats() {
    let d = tmp_dir("ggs-formats", "register", true);
    let files = converted(&d);
    let run = |src: &Path, tgt: &Path| -> Vec<f64> {
        let out = ok(&[
            "register",
            s(src),
            s(tgt),
            "--voxel",
            "0.006",
            "--refine",
            "none",
            "--json",
            "-q",
        ]);
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        v["transform"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|r| r.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
            .collect()
    };
    let reference = run(&data("bun0.pcd"), &data("bun4.pcd"));
    // Each format as the source against the next one as the target.
    for (i, (ext, src, _)) in files.iter().enumerate() {
        let (text, _, tgt) = &files[(i + 1) % files.len()];
        let t = run(src, tgt);
        let worst = t
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{ext} -> {text}: {t:?} vs {reference:?}");
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn info_reports_format_points_and_speed() {
    let d = tmp_dir("ggs-formats", "info", true);
    let e57 = d.join("b.e57");
    ok(&["convert", "-q", s(&data("bun0.pcd")), s(&e57)]);
    let out = ok(&["info", "--json", s(&e57), s(&data("bun000.ply"))]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v[0]["format"], "e57");
    assert_eq!(v[0]["points"], 397);
    assert_eq!(v[0]["scans"][0]["records"], 397);
    assert_eq!(v[1]["format"], "ply");
    assert_eq!(v[1]["points"], 40256);
    // The speed is what its definition says (no wall-clock bound): file bytes / 1e6 / read_s.
    let bytes = std::fs::metadata(data("bun000.ply")).unwrap().len();
    assert_eq!(v[1]["bytes"].as_u64(), Some(bytes));
    let (mb_s, secs) = (
        v[1]["read_mb_per_s"].as_f64().unwrap(),
        v[1]["read_s"].as_f64().unwrap(),
    );
    let expected = bytes as f64 / 1e6 / secs.max(1e-9);
    assert!(
        (mb_s - expected).abs() <= 1e-9 * expected,
        "{mb_s} vs {expected}"
    );
    let text = ok(&["info", s(&data("bun000.ply"))]);
    assert!(
        text.contains("points    40256") && text.contains("MB/s"),
        "{text}"
    );
    // A mesh: its vertices, or points sampled on its faces.
    let obj = data("human_woman.obj");
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["info", "--json", "--sample-mesh", "5000", s(&obj)])).unwrap();
    assert_eq!(v[0]["points"], 5000);
    let v: serde_json::Value = serde_json::from_str(&ok(&["info", "--json", s(&obj)])).unwrap();
    assert_eq!(v[0]["points"], 6890);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn format_errors_name_the_file_and_exit_2() {
    let d = tmp_dir("ggs-formats", "errors", true);
    let good = data("bun0.pcd");
    fails(
        &["convert", s(&good), s(&d.join("x.npz"))],
        "read, not written",
    );
    fails(
        &["convert", s(&good), s(&d.join("x.obj"))],
        "read, not written",
    );
    assert!(!d.join("x.npz").exists() && !d.join("x.obj").exists());
    fails(
        &["convert", "--ascii", s(&good), s(&d.join("x.pcd"))],
        "--ascii applies to PLY",
    );
    fails(
        &["convert", "--to", "gif", s(&good), s(&d.join("x"))],
        "--to: unknown format 'gif'",
    );
    fails(
        &["info", "--format", "gif", s(&good)],
        "--format: unknown format 'gif'",
    );
    fails(&["info", s(&d.join("missing.las"))], "missing.las");
    let o = ggs(&["info", s(&d.join("missing.las"))]);
    let said = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(said.lines().count(), 1, "{said}");
    assert!(
        said.matches("(os error").count() <= 1,
        "the cause said twice: {said}"
    );
    let e57 = d.join("one.e57");
    ok(&["convert", "-q", s(&good), s(&e57)]);
    fails(
        &["info", "--scan", "3", s(&e57)],
        "scan 3 asked for, the file holds 1 scan(s)",
    );
    fails(
        &["info", "--sample-mesh", "0", s(&data("human_woman.obj"))],
        "--sample-mesh",
    );
    // A LAS file cut short, a PLY with a bad row, a PCD forced as PLY.
    let las = d.join("cut.las");
    ok(&["convert", "-q", s(&good), s(&las)]);
    let b = std::fs::read(&las).unwrap();
    std::fs::write(&las, &b[..b.len() - 100]).unwrap();
    fails(&["register", s(&las), s(&good)], "cut.las");
    let ply = d.join("bad.ply");
    std::fs::write(&ply, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 x\n").unwrap();
    fails(
        &["register", s(&good), s(&ply)],
        "bad.ply: line 8: 'x' is not a number",
    );
    fails(
        &["info", "--format", "ply", s(&good)],
        "bun0.pcd: line 1: expected 'ply'",
    );
    std::fs::remove_dir_all(&d).unwrap();
}
