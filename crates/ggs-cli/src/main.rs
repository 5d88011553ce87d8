//! `ggs`: the command line. It parses arguments, calls the library and prints; nothing else.

/// Write to stdout; a closed pipe (`ggs … | head`) ends the output quietly instead of
/// panicking, any other write error is reported.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::emit(&format!($($arg)*))?
    };
}
macro_rules! outln {
    () => { $crate::emit("\n")? };
    ($($arg:tt)*) => {
        $crate::emit(&format!("{}\n", format!($($arg)*)))?
    };
}

mod align;
mod bench;
mod files;
mod partial;
mod pipeline_args;
mod progress;
mod refine_args;
mod register;
mod settings_cmd;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

/// Correspondence-free global registration of 3-D point clouds (Greedy Grid Search).
#[derive(Parser)]
#[command(name = "ggs", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Register SOURCE onto TARGET: print T with p_target = T · p_source.
    Register(Box<register::RegisterArgs>),
    /// Align many scans into one frame with no initial guess: poses, moved scans, a merged
    /// model and a report.
    Align(Box<align::AlignArgs>),
    /// Refine an initial transform (p_target = T · p_source) by ICP.
    Refine(Box<register::RefineArgs>),
    /// Read point-cloud files and print their format, points, bounds and read speed.
    Info(files::InfoArgs),
    /// Convert a point cloud between formats (any readable to any writable, atomically).
    Convert(Box<files::ConvertArgs>),
    /// Write a rotation set to a .npy file of shape [N, 3, 3] (or print its size).
    Rotations(register::RotationsArgs),
    /// Print the settings a run would use (a preset, a settings file, --set and the flags
    /// applied), as TOML to save and pass to --config, or as JSON.
    Settings(Box<settings_cmd::SettingsArgs>),
    /// Run a benchmark protocol (3dmatch, kitti, eth, fpv1) or a manifest of pairs.
    Bench(Box<bench::BenchArgs>),
    /// Generate partial-view pairs (FAUST-partial style) from scans or meshes, or rebuild
    /// the published FPv1 pairs.
    Partial(Box<partial::PartialArgs>),
}

/// Write `s` to stdout. Returns an error only for a real failure; a broken pipe marks stdout
/// closed and later writes are dropped.
pub fn emit(s: &str) -> anyhow::Result<()> {
    use std::io::Write;
    use std::sync::atomic::{AtomicBool, Ordering};
    static CLOSED: AtomicBool = AtomicBool::new(false);
    if CLOSED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    match out.write_all(s.as_bytes()).and_then(|_| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            CLOSED.store(true, Ordering::Relaxed);
            Ok(())
        }
        Err(e) => Err(anyhow::anyhow!("writing to standard output: {e}")),
    }
}

/// The error and its causes, joined by ": ", leaving out a cause whose text the message
/// already holds (the library's I/O errors print their source themselves, so anyhow's `{:#}`
/// would say "No such file or directory" twice).
fn error_text(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text.push_str(": ");
            text.push_str(&cause);
        }
    }
    text
}

fn main() -> ExitCode {
    let matches = pipeline_args::with_preset_values(Cli::command()).get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .without_time()
        .with_target(false)
        .init();
    let outcome = match cli.command {
        Command::Register(a) => register::run(*a),
        Command::Align(a) => align::run(*a),
        Command::Refine(a) => register::run_refine(*a),
        Command::Rotations(a) => register::run_rotations(a),
        Command::Info(a) => files::run_info(a),
        Command::Convert(a) => files::run_convert(*a),
        Command::Bench(a) => bench::run(*a),
        Command::Settings(a) => settings_cmd::run(*a),
        Command::Partial(a) => partial::run(*a),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_text(&e));
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::error_text;

    #[test]
    fn a_cause_is_said_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let e = anyhow::Error::new(ggs::GgsError::Io {
            path: "a.ply".into(),
            source: io,
        });
        assert_eq!(error_text(&e), "a.ply: no such file");
        let wrapped = e.context("reading the source");
        assert_eq!(
            error_text(&wrapped),
            "reading the source: a.ply: no such file"
        );
    }
}
