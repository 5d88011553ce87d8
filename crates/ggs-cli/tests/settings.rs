//! The settings from the command line: a settings file, `--set` and the flags change the
//! preset in that order; every result echoes them; the help and docs/settings.md state the
//! presets' values as the code has them.

mod common;

use common::{assert_fails, data, ggs, ggs_json, s, tmp_dir};
use serde_json::Value;

/// `ggs settings --json` plus `extra`, parsed.
fn settings(extra: &[&str]) -> Value {
    let mut args = vec!["settings", "--json"];
    args.extend_from_slice(extra);
    ggs_json(&args)
}

/// A value as the help and docs/settings.md show it.
fn shown(v: &Value) -> String {
    match v {
        Value::Null => "unset".into(),
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

#[test]
fn a_file_then_set_then_flags_change_the_preset() {
    let dir = tmp_dir("ggs-settings", "layers", true);
    let file = dir.join("s.toml");
    std::fs::write(
        &file,
        "preset = \"paper\"\nverify = true\nmargin = 0.3\nmax_iterations = 7\n",
    )
    .unwrap();
    let file = s(&file);
    let got = settings(&[
        "--config",
        file,
        "--set",
        "verify_cell=0.25",
        "--margin",
        "0.4",
    ]);
    assert_eq!(got["search"], "exhaustive", "the file's preset");
    assert_eq!(got["max_iterations"], 7, "the file");
    assert_eq!(got["verify_cell"], 0.25, "--set");
    assert_eq!(got["margin"], 0.4, "the flag after the file");
    // --preset overrides the file's preset; the file's keys still apply.
    let default = settings(&["--config", file, "--preset", "default"]);
    assert_eq!(
        (&default["search"], &default["margin"]),
        (&"coarse-to-fine".into(), &0.3.into())
    );
    // What `ggs settings` prints as TOML reads back as the same settings.
    let out = ggs(&["settings", "--config", file, "--set", "top_k=3"]);
    let toml = dir.join("back.toml");
    std::fs::write(&toml, &out.stdout).unwrap();
    assert_eq!(
        settings(&["--config", s(&toml)]),
        settings(&["--config", file, "--set", "top_k=3"])
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_settings_name_their_origin_and_key() {
    let dir = tmp_dir("ggs-settings", "bad", true);
    let file = dir.join("s.toml");
    std::fs::write(&file, "margn = 0.3\n").unwrap();
    let (b0, b4) = (data("bun0.pcd"), data("bun4.pcd"));
    let register = |extra: &[&str], needle: &str| {
        let mut args = vec!["register", s(&b0), s(&b4), "-q"];
        args.extend_from_slice(extra);
        assert_fails(&args, needle);
    };
    register(
        &["--config", s(&file)],
        "s.toml: setting margn: unknown setting (did you mean margin?)",
    );
    register(
        &["--margin", "3"],
        "--margin: setting margin: must be in [0, 1], got 3",
    );
    register(
        &["--set", "verify_iterations=5"],
        "--set: setting verify_iterations: must be at least verify_check_iterations (10), got 5",
    );
    register(
        &["--no-verify", "--max-hypotheses", "4"],
        "--max-hypotheses: setting max_hypotheses: needs verification",
    );
    // The preset's own values need nothing more: what `ggs settings --no-verify` prints
    // reads back.
    let out = ggs(&["settings", "--no-verify"]);
    std::fs::write(&file, &out.stdout).unwrap();
    assert!(ggs(&["settings", "--config", s(&file)]).status.success());
    register(
        &["--max-memory", "lots"],
        "--max-memory: setting max_memory: cannot read 'lots' as a size",
    );
    std::fs::write(&file, "margin = \n").unwrap();
    register(&["--config", s(&file)], "s.toml");
    register(&["--config", "missing.toml"], "missing.toml");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_json_result_echoes_every_setting_in_force() {
    let (b0, b4) = (data("bun0.pcd"), data("bun4.pcd"));
    let args = [
        "register",
        s(&b0),
        s(&b4),
        "--voxel",
        "0.006",
        "--json",
        "-q",
        "--margin",
        "0.4",
    ];
    let out = ggs(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        j["settings"],
        settings(&["--set", "voxel=0.006", "--margin", "0.4"])
    );
}

#[test]
fn the_help_states_the_presets_values_from_the_code() {
    let default = settings(&[]);
    let paper = settings(&["--preset", "paper"]);
    let help = String::from_utf8(ggs(&["register", "--help"]).stdout).unwrap();
    let mut annotated = 0;
    for key in default.as_object().unwrap().keys() {
        let tag = format!("[setting {key}: ");
        let Some(at) = help.find(&tag) else { continue };
        annotated += 1;
        let values = &help[at + tag.len()..];
        let values = &values[..values.find(']').unwrap()];
        let (d, p) = (shown(&default[key]), shown(&paper[key]));
        let want = if d == p {
            d
        } else {
            format!("{d}; --preset paper: {p}")
        };
        assert_eq!(values, want, "{key}");
    }
    assert!(annotated >= 25, "{annotated} flags annotated");
    // A settings flag's help states no default of its own: the annotation does.
    for line in help.lines().filter(|l| l.contains("[setting ")) {
        assert!(!line.contains("(default"), "{line}");
    }
}

#[test]
fn docs_settings_lists_every_key_with_the_presets_values() {
    let doc = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/settings.md"),
    )
    .unwrap();
    let default = settings(&[]);
    let paper = settings(&["--preset", "paper"]);
    let quoted = |v: &Value| match v {
        Value::String(s) => format!("\"{s}\""),
        other => shown(other),
    };
    let mut listed = Vec::new();
    for row in doc.lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = row.split(" | ").collect();
        let key = cells[0].trim_start_matches("| `").trim_end_matches('`');
        assert_eq!(cells[1], quoted(&default[key]), "{key}: default");
        assert_eq!(cells[2], quoted(&paper[key]), "{key}: paper");
        listed.push(key.to_string());
    }
    let mut keys: Vec<String> = default.as_object().unwrap().keys().cloned().collect();
    listed.sort();
    keys.sort();
    assert_eq!(listed, keys);
}
