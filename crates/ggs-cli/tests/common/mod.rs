//! Helpers shared by the command-line tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A bundled fixture under `tests/data`.
pub fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data")
        .join(name)
}

/// Run the `ggs` binary.
pub fn ggs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ggs"))
        .args(args)
        .output()
        .expect("run ggs")
}

/// `ggs ARGS`, which must succeed, its standard output parsed as JSON.
pub fn ggs_json(args: &[&str]) -> serde_json::Value {
    let out = ggs(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// `ggs ARGS` exits with status 2 and a message on stderr that contains `needle`, without
/// a panic.
pub fn assert_fails(args: &[&str], needle: &str) {
    let out = ggs(args);
    assert_eq!(out.status.code(), Some(2), "args {args:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(needle), "expected '{needle}' in: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// A fresh temporary folder `<prefix>-<tag>-<pid>` (emptied; created if `create`).
pub fn tmp_dir(prefix: &str, tag: &str, create: bool) -> PathBuf {
    let d = std::env::temp_dir().join(format!("{prefix}-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    if create {
        std::fs::create_dir_all(&d).unwrap();
    }
    d
}

/// A path as `&str`.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
