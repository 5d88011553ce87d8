//! `ggs align`: many scans into one frame, with no initial guess.

use crate::files::{self, InputArgs};
use anyhow::{bail, Context, Result};
use clap::Args;
use ggs::align::{AlignScan, Aligner, Alignment};
use ggs::settings::{Runtime, Settings};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args)]
pub struct AlignArgs {
    /// Scans to align: files, or quoted patterns such as "scans/*.ply" (`*`, `?`, `[ab]`).
    pub scans: Vec<String>,
    /// A file listing scans, one path or pattern a line (relative to the list's folder;
    /// blank lines and lines starting with # are skipped).
    #[arg(long, value_name = "FILE")]
    pub list: Option<PathBuf>,
    /// Write poses.json, poses.txt, the scans moved into the common frame (scans/), the
    /// merged model (model.ply) and report.html into this folder.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// The scan whose frame is the common frame (its name as given); default: the first.
    #[arg(long, value_name = "NAME")]
    pub anchor: Option<String>,
    /// Voxel size of the registrations, in the scans' units (unset: automatic per
    /// registration).
    #[arg(long, allow_negative_numbers = true)]
    pub voxel: Option<f64>,
    #[command(flatten)]
    pub pipeline: crate::pipeline_args::PipelineArgs,
    /// Worker threads (default: all cores). The result does not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    #[command(flatten)]
    pub input: InputArgs,
    /// Print the alignment as JSON on stdout (the content of poses.json).
    #[arg(long)]
    pub json: bool,
    /// No progress bar and no warnings.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Where a scan given as an argument comes from, in errors.
const CLI: &str = "the command line";

/// The scan paths: the arguments, then the list's lines, each pattern expanded (sorted);
/// each with where it was given (the command line, or the list file and line).
fn scan_paths(args: &AlignArgs) -> Result<Vec<(String, String)>> {
    let mut given: Vec<(String, String)> = args
        .scans
        .iter()
        .map(|s| (s.clone(), CLI.to_string()))
        .collect();
    if let Some(list) = &args.list {
        let text = std::fs::read_to_string(list).with_context(|| list.display().to_string())?;
        let dir = list.parent().unwrap_or(Path::new(""));
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let path = if Path::new(line).is_absolute() {
                PathBuf::from(line)
            } else {
                dir.join(line)
            };
            given.push((
                path.display().to_string(),
                format!("{} line {}", list.display(), n + 1),
            ));
        }
    }
    let mut paths = Vec::new();
    for (s, origin) in given {
        if !s.contains(['*', '?', '[']) {
            paths.push((s, origin));
            continue;
        }
        let matches = glob::glob(&s).with_context(|| format!("{origin}: pattern {s:?}"))?;
        let mut found: Vec<String> = matches
            .filter_map(|m| m.ok())
            .map(|p| p.display().to_string())
            .collect();
        if found.is_empty() {
            bail!("{origin}: no file matches {s:?}");
        }
        found.sort();
        paths.extend(found.into_iter().map(|p| (p, origin.clone())));
    }
    if paths.len() < 2 {
        bail!("ggs align needs at least two scans ({} given)", paths.len());
    }
    Ok(paths)
}

fn settings(args: &AlignArgs) -> Result<Settings> {
    Ok(args
        .pipeline
        .settings(|c| crate::pipeline_args::put(c, "voxel", &args.voxel))?
        .1)
}

pub fn run(args: AlignArgs) -> Result<()> {
    let t0 = Instant::now();
    let settings = settings(&args)?;
    let paths = scan_paths(&args)?;
    let opts = args.input.options()?;
    let files: Vec<&Path> = paths.iter().map(|(p, _)| Path::new(p)).collect();
    let loaded =
        ggs::threads::in_pool(args.threads, || files::load_all(&files, &opts, args.quiet))?;
    let scans: Vec<AlignScan> = loaded
        .into_iter()
        .zip(&paths)
        .map(|(loaded, (p, origin))| {
            let loaded = if origin == CLI {
                loaded?
            } else {
                loaded.with_context(|| origin.clone())?
            };
            Ok(AlignScan {
                name: p.clone(),
                cloud: loaded.cloud,
            })
        })
        .collect::<Result<_>>()?;
    let anchor = match &args.anchor {
        Some(name) => Some(
            scans
                .iter()
                .position(|s| &s.name == name)
                .with_context(|| {
                    format!("--anchor: no scan named {name:?} among the scans given")
                })?,
        ),
        None => None,
    };
    let runtime = Runtime {
        threads: args.threads,
        ..Runtime::default()
    };
    let mut aligner = Aligner::new(scans, &settings, anchor, &runtime)?;
    let pb = crate::progress::bar(aligner.scans().len() - 1, "scans placed", args.quiet);
    let result = aligner.run(&runtime, |batch, placed| {
        pb.set_position(placed.saturating_sub(1) as u64);
        let names: Vec<&str> = batch.iter().map(|s| s.name.as_str()).collect();
        pb.set_message(names.join(", "));
    });
    pb.finish_and_clear();
    let alignment = result?;
    let scans = aligner.scans();
    ggs::threads::in_pool(args.threads, || write_outputs(&args, scans, &alignment))??;
    if !args.quiet {
        for w in &alignment.warnings {
            eprintln!("warning: {w}");
        }
    }
    if args.json {
        out!("{}\n", serde_json::to_string_pretty(&alignment)?);
    } else {
        print_summary(&alignment, t0)?;
    }
    Ok(())
}

/// Every output file, each written atomically, once the alignment has succeeded.
fn write_outputs(args: &AlignArgs, scans: &[AlignScan], a: &Alignment) -> Result<()> {
    let command = Some(crate::register::command_line());
    Ok(ggs::html::alignment::write_folder_and_report(
        &args.out, scans, a, command,
    )?)
}

fn print_summary(a: &Alignment, t0: Instant) -> Result<()> {
    let placed = a.scans.iter().filter(|s| s.pose.is_some()).count();
    outln!(
        "{placed} of {} scans placed in the frame of {} ({} registrations, {} of {} edges accepted, {:.2} s)",
        a.scans.len(),
        a.anchor,
        a.registrations,
        a.edges.iter().filter(|e| e.accepted).count(),
        a.edges.len(),
        t0.elapsed().as_secs_f64()
    );
    for s in &a.scans {
        match &s.pose {
            Some(_) => outln!(
                "  {:<40} confidence {:.3}  overlap {:.2}",
                s.name,
                s.confidence,
                s.overlap
            ),
            None => outln!(
                "  {:<40} NOT PLACED: {}",
                s.name,
                s.reason.as_deref().unwrap_or("")
            ),
        }
    }
    Ok(())
}
