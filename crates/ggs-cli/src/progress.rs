//! The one progress bar of every command: on stderr, only on a terminal, never with `--quiet`.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

/// A bar of `len` steps counting `what` (`rotations`, `pairs`, `scans`), with the rate, the
/// time left and a message; hidden when `quiet` or when stderr is not a terminal.
pub fn bar(len: usize, what: &str, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::with_draw_target(Some(len as u64), ProgressDrawTarget::stderr());
    pb.set_style(style(what));
    pb
}

fn style(what: &str) -> ProgressStyle {
    ProgressStyle::with_template(&format!(
        "{{spinner}} {{bar:40}} {{pos}}/{{len}} {what} {{per_sec}}, ETA {{eta}} {{msg}}"
    ))
    .expect("valid template")
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_template_is_valid_for_every_unit() {
        for what in ["rotations", "pairs", "scans"] {
            let _ = super::style(what);
        }
    }
}
