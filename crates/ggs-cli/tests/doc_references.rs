//! Every section reference in the repository's text resolves: wherever a Markdown file is
//! named with a heading beside it (`docs/method.md, "Reduced precision"` in docs, help
//! texts and comments), that file exists and has a heading that starts with those words (or
//! that they start with, for a heading cited by its first words).

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The files git tracks that may cite a section: Markdown, Rust, Python and the CI script.
fn cited_in(root: &Path) -> Vec<PathBuf> {
    let out = Command::new("git")
        .args(["ls-files"])
        .current_dir(root)
        .output()
        .expect("git runs");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|f| [".md", ".rs", ".py"].iter().any(|e| f.ends_with(e)) || *f == ".ci/run")
        .map(|f| root.join(f))
        .collect()
}

/// The text with line breaks (and the comment markers after them) as single spaces, so a
/// heading cited across two comment lines reads as one.
fn joined(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let t = line.trim_start();
        let t = ["//!", "///", "//", "#"]
            .iter()
            .find_map(|m| t.strip_prefix(m))
            .unwrap_or(t);
        out.push_str(t.trim());
        out.push(' ');
    }
    out
}

/// `(file, heading)` for every Markdown file name followed by a quoted heading: after `, `,
/// ` (` or `), `.
fn citations(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let path_char = |c: char| c.is_ascii_alphanumeric() || "_./-".contains(c);
    for (at, _) in text.match_indices(".md") {
        let start = text[..at]
            .char_indices()
            .rev()
            .take_while(|&(_, c)| path_char(c))
            .last()
            .map_or(at, |(i, _)| i);
        let rest = &text[at + 3..];
        let rest = rest.strip_prefix(')').unwrap_or(rest);
        let Some(rest) = rest
            .strip_prefix(", \"")
            .or_else(|| rest.strip_prefix(" (\""))
        else {
            continue;
        };
        if let Some(end) = rest.find('"') {
            out.push((text[start..at + 3].to_string(), rest[..end].to_string()));
        }
    }
    out
}

fn headings(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter(|l| l.starts_with('#'))
        .map(|l| {
            l.trim_start_matches('#')
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect()
}

#[test]
fn every_section_reference_resolves() {
    let root = repo_root();
    let mut seen = 0;
    let mut broken = Vec::new();
    for file in cited_in(&root) {
        let Ok(text) = std::fs::read_to_string(&file) else {
            continue;
        };
        for (md, heading) in citations(&joined(&text)) {
            seen += 1;
            let here = file.parent().unwrap_or(&root).join(&md);
            let target = [root.join(&md), here, root.join("docs").join(&md)]
                .into_iter()
                .find(|p| p.is_file());
            let found = target.as_deref().map(headings).unwrap_or_default();
            if !found
                .iter()
                .any(|h| h.starts_with(&heading) || heading.starts_with(h.as_str()))
            {
                let name = file
                    .strip_prefix(&root)
                    .unwrap_or(&file)
                    .display()
                    .to_string();
                broken.push(format!("{name}: {md}, \"{heading}\""));
            }
        }
    }
    assert!(
        seen >= 40,
        "only {seen} section references found: is the scan right?"
    );
    assert!(broken.is_empty(), "unresolved:\n{}", broken.join("\n"));
}

#[test]
fn a_citation_is_read_across_comment_lines() {
    let text = joined("/// see (docs/method.md, \"Reduced\n/// precision\") and x.md");
    assert_eq!(
        citations(&text),
        vec![(
            "docs/method.md".to_string(),
            "Reduced precision".to_string()
        )]
    );
}
