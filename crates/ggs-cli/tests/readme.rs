//! Every `ggs …` command of the shell examples of the README, docs/cli.md and
//! docs/settings.md runs as written from the root of a bare clone: in a scratch folder that holds a link to the repository's `tests/` (so
//! `tests/data/...` resolve and `runs/...` outputs stay out of the checkout), in order, each
//! exiting with status 0. The `cargo` and `pip` lines are the build, test and install
//! commands that `.ci/run` runs itself.

mod common;

use std::path::PathBuf;
use std::process::Command;

fn shell_lines(markdown: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut inside = false;
    for line in markdown.lines() {
        if line.starts_with("```") {
            inside = !inside && line.trim() == "```sh";
            continue;
        }
        if inside {
            let code = line.split(" #").next().unwrap_or("").trim();
            if !code.is_empty() && !code.starts_with('#') {
                out.push(code.to_string());
            }
        }
    }
    out
}

#[test]
fn readme_examples_run_as_written() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut lines = Vec::new();
    for doc in [
        "README.md",
        "docs/cli.md",
        "docs/settings.md",
        "docs/align.md",
    ] {
        lines.extend(shell_lines(
            &std::fs::read_to_string(root.join(doc)).unwrap(),
        ));
    }
    let ggs_lines: Vec<&String> = lines.iter().filter(|l| l.starts_with("ggs ")).collect();
    assert!(ggs_lines.len() >= 8, "{lines:?}");
    for l in &lines {
        assert!(
            ["ggs ", "cargo ", "pip "].iter().any(|p| l.starts_with(p)),
            "a README example this test does not run: {l}"
        );
    }
    let scratch = common::tmp_dir("ggs-readme", "run", true);
    std::os::unix::fs::symlink(
        root.join("tests").canonicalize().unwrap(),
        scratch.join("tests"),
    )
    .unwrap();
    for line in ggs_lines {
        let args: Vec<&str> = line.split_whitespace().skip(1).collect();
        let out = Command::new(env!("CARGO_BIN_EXE_ggs"))
            .args(&args)
            .current_dir(&scratch)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "README example failed: {line}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    std::fs::remove_dir_all(&scratch).unwrap();
}
