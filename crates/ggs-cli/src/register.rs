//! `ggs register` and `ggs rotations`.

use crate::files::{self, InputArgs};
use crate::pipeline_args::{put, RefineOptions};
use crate::refine_args::{print_report, read_matrix};
use anyhow::{Context, Result};
use clap::Args;
use ggs::html::registration::RegistrationReport;
use ggs::io::{self, ReadOptions};
use ggs::pipeline::{
    Preset, RefinementDocument, Registration, RegistrationConfig, RegistrationDocument,
    Verification,
};
use ggs::refine;
use ggs::rotations::RotationSet;
use ggs::search;
use ggs::settings::{Changes, Settings};
use ggs::{Cloud, Rigid};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct RegisterArgs {
    /// Source point cloud (moved onto the target).
    pub source: PathBuf,
    /// Target point cloud.
    pub target: PathBuf,
    /// Voxel size in the clouds' units; unset: the target's longest side / auto_voxel_cells,
    /// or auto_voxel_spacings × the point spacing when larger
    #[arg(long, allow_negative_numbers = true)]
    pub voxel: Option<f64>,
    #[command(flatten)]
    pub pipeline: crate::pipeline_args::PipelineArgs,
    /// Rotation set from a .npy file of shape [N, 3, 3].
    #[arg(long, value_name = "F", conflicts_with = "rotations")]
    pub rotations_file: Option<PathBuf>,
    /// Drop rotations within this many degrees of an earlier one in the set.
    #[arg(long, value_name = "DEG")]
    pub dedup: Option<f64>,
    /// Worker threads (default: all cores). The result does not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Report the K best distinct coarse hypotheses of the whole search (unset: as many as
    /// are verified). Runs the whole search, as --no-first-look: a first look reports only
    /// the distinct poses among its own few rotations.
    #[arg(long)]
    pub top_k: Option<usize>,
    /// Rotations within this angle (degrees) of a better one are not distinct (unset: 2 × the
    /// set's step).
    #[arg(long, value_name = "DEG")]
    pub distinct_radius: Option<f64>,
    /// Memory budget of the search, e.g. 2G or 512M (unset: half of physical memory).
    #[arg(long, value_name = "SIZE")]
    pub max_memory: Option<String>,
    /// Print the time of every stage (wall and CPU per stage).
    #[arg(long)]
    pub timings: bool,
    #[command(flatten)]
    pub io: IoArgs,
    /// Write target (blue) and moved source (orange) together to this PLY file.
    #[arg(long, value_name = "OUT.ply")]
    pub overlay: Option<PathBuf>,
    /// Write a self-contained HTML report (pictures before and after, hypotheses, quality,
    /// timings, the command line) to this file.
    #[arg(long, value_name = "OUT.html")]
    pub report: Option<PathBuf>,
    /// No progress bar and no warnings.
    #[arg(short, long)]
    pub quiet: bool,
}

#[derive(Args)]
pub struct RefineArgs {
    /// Source point cloud.
    pub source: PathBuf,
    /// Target point cloud.
    pub target: PathBuf,
    /// Initial transform (4×4 text, p_target = T · p_source).
    #[arg(long, value_name = "T.txt")]
    pub init: PathBuf,
    /// Estimator: gicp, p2plane or p2p.
    #[arg(long, default_value = "gicp")]
    pub method: String,
    #[command(flatten)]
    pub refine_options: RefineOptions,
    /// Worker threads (default: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    #[command(flatten)]
    pub io: IoArgs,
    /// No warnings.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Write the matrix file and the moved source, where asked (both atomically).
fn write_outputs(io_args: &IoArgs, source: &Cloud, t: &Rigid) -> Result<()> {
    if let Some(path) = &io_args.output {
        io::write_atomic(path, t.to_text().as_bytes())?;
    }
    if let Some(path) = &io_args.aligned {
        let moved: Vec<_> = source.iter().map(|p| t.apply(&p)).collect();
        io::write_cloud(path, &moved, None)?;
    }
    Ok(())
}

/// Input format and outputs, shared by `register` and `refine`.
#[derive(Args)]
pub struct IoArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Print everything as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Write the final 4×4 matrix to this file (four lines of four numbers).
    #[arg(short = 'o', long = "output", value_name = "T.txt")]
    pub output: Option<PathBuf>,
    /// Write the source, moved by the final T, to this file (format by extension: .ply,
    /// .pcd, .xyz/.txt/.pts/.csv, .npy, .bin, .las, .laz, .e57).
    #[arg(long, value_name = "OUT")]
    pub aligned: Option<PathBuf>,
}

#[derive(Args)]
pub struct RotationsArgs {
    /// Built-in set name.
    pub name: String,
    /// Write the matrices here as float64 [N, 3, 3].
    #[arg(long, value_name = "OUT.npy")]
    pub out: Option<PathBuf>,
}

fn load(path: &Path, opts: &ReadOptions, quiet: bool) -> Result<Cloud> {
    Ok(files::load(path, opts, quiet)?.cloud)
}

/// Both clouds, read side by side unless one thread is asked for (an error names its file;
/// the source's comes first).
fn load_pair(args: &RegisterArgs, opts: &ReadOptions) -> Result<(Cloud, Cloud)> {
    if ggs::threads::resolve(args.threads) == 1 {
        return Ok((
            load(&args.source, opts, args.quiet)?,
            load(&args.target, opts, args.quiet)?,
        ));
    }
    let (source, target) = std::thread::scope(|s| {
        let target = s.spawn(|| load(&args.target, opts, args.quiet));
        let source = load(&args.source, opts, args.quiet);
        (source, target.join())
    });
    let target = target.unwrap_or_else(|panic| std::panic::resume_unwind(panic));
    Ok((source?, target?))
}

/// The settings from the command line, and the preset they start from.
fn settings(args: &RegisterArgs) -> Result<(Preset, Settings)> {
    args.pipeline.settings(|c| {
        put(c, "voxel", &args.voxel);
        if let Some(file) = &args.rotations_file {
            c.set_from("--rotations-file", "rotations", file.display().to_string());
        }
        put(c, "dedup", &args.dedup);
        put(c, "top_k", &args.top_k);
        put(c, "distinct_radius", &args.distinct_radius);
        put(c, "max_memory", &args.max_memory);
    })
}

/// The settings and the stages' parameters from the command line.
fn config(args: &RegisterArgs) -> Result<(Preset, Settings, RegistrationConfig)> {
    let (preset, settings) = settings(args)?;
    let cfg = settings.plan(args.threads)?;
    Ok((preset, settings, cfg))
}

pub fn run(args: RegisterArgs) -> Result<()> {
    let t0 = Instant::now();
    let format = args.io.input.options()?;
    // The configuration (its rotation set takes a few ms to build) is made while the clouds
    // are read; an error in it is reported first.
    let (cfg, clouds) = std::thread::scope(|s| {
        let cfg = s.spawn(|| config(&args));
        let clouds = load_pair(&args, &format);
        let cfg = cfg
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (cfg, clouds)
    });
    let (preset, settings, mut cfg) = cfg?;
    let (source, target) = clouds?;
    let read_ms = t0.elapsed().as_secs_f64() * 1e3;
    let pb = crate::progress::bar(cfg.rotations.len(), "rotations", args.quiet);
    let pbc = pb.clone();
    cfg.search.progress = Some(Arc::new(move |n| pbc.set_position(n as u64)));
    let result = ggs::settings::register_planned(&source, &target, &settings, &cfg);
    pb.finish_and_clear();
    let reg = result?;
    let final_t = reg.transform;
    write_outputs(&args.io, &source, &final_t)?;
    if let Some(path) = &args.overlay {
        ggs::io::write_overlay(path, &source, &target, &final_t)?;
    }
    let total_ms = t0.elapsed().as_secs_f64() * 1e3;
    if let Some(path) = &args.report {
        let mut report = RegistrationReport::new(&source, &target, reg.clone());
        report.source_name = args.source.display().to_string();
        report.target_name = args.target.display().to_string();
        report.command = Some(command_line());
        report.read_ms = Some(read_ms);
        report.total_ms = Some(total_ms);
        report.write(path)?;
    }
    if !args.quiet {
        for w in &reg.warnings {
            eprintln!("warning: {w}");
        }
    }
    if args.io.json {
        print_json(&args, preset, &reg, read_ms, total_ms)?;
    } else {
        out!("{}", final_t.to_text());
        print_summary(&reg, preset.name(), read_ms, total_ms)?;
        if let Some(r) = &reg.refine {
            print_report(r)?;
            if reg.refine_cell > 0.0 {
                outln!(
                    "            (on both clouds thinned to cells of {:.2} voxel; --refine-cell 0: full resolution)",
                    reg.refine_cell / reg.voxel
                );
            }
        }
        if args.timings {
            print_timings(&reg, read_ms, total_ms)?;
        }
    }
    Ok(())
}

/// This process's command line, each argument quoted for a POSIX shell where it needs it.
pub fn command_line() -> String {
    let quote = |a: String| {
        let plain = !a.is_empty()
            && a.chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
        if plain {
            a
        } else {
            format!("'{}'", a.replace('\'', "'\\''"))
        }
    };
    let mut args = std::env::args();
    let program = args.next().map(|_| "ggs".to_string()).unwrap_or_default();
    std::iter::once(program)
        .chain(args.map(quote))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The `--json` document ([`RegistrationDocument`]): the registration with the files, the
/// preset and the times of the whole call.
fn print_json(
    args: &RegisterArgs,
    preset: Preset,
    reg: &Registration,
    read_ms: f64,
    total_ms: f64,
) -> Result<()> {
    let doc = RegistrationDocument {
        source: Some(args.source.display().to_string()),
        target: Some(args.target.display().to_string()),
        preset: Some(preset.name()),
        read_ms: Some(read_ms),
        ..RegistrationDocument::new(reg, total_ms)
    };
    outln!("{}", doc.to_json());
    Ok(())
}

fn print_summary(reg: &Registration, preset: &str, read_ms: f64, total_ms: f64) -> Result<()> {
    print_search(reg, preset)?;
    if let Some(f) = &reg.first_look {
        outln!(
            "first look  {} rotations, {} hypothesis(es) verified: best {:.3}, runner-up {}: {}",
            f.rotations,
            f.verified,
            f.score,
            f.runner_up_score
                .map_or("none".to_string(), |r| format!("{r:.3}")),
            if f.accepted {
                "taken (the whole search was not needed)".to_string()
            } else if f.score < f.accept_score {
                format!("below {}, the whole search ran", f.accept_score)
            } else {
                "a distinct pose scored too close to it, the whole search ran".to_string()
            }
        );
    }
    match &reg.verification {
        Some(v) => print_verification(v)?,
        None => {
            for (i, h) in reg.search.hypotheses.iter().enumerate().skip(1) {
                outln!(
                    "hypothesis  {}: rotation #{} match {}",
                    i + 1,
                    h.rotation_index,
                    h.match_score
                );
            }
        }
    }
    outln!(
        "confidence  {:.3}{}",
        reg.confidence,
        if reg.ambiguous {
            " AMBIGUOUS: two distinct poses explain the data about equally well"
        } else {
            ""
        }
    );
    print_grids(&reg.search)?;
    let t = &reg.timings;
    outln!(
        "time        {:.0} ms total: read {:.0}, search {:.0}, verify {:.0}, refine {:.0} ms on {} thread(s){}",
        total_ms,
        read_ms,
        t.search_ms,
        t.verify_ms,
        t.refine_ms,
        reg.search.stats.threads,
        peak_memory_note()
    );
    Ok(())
}

/// The voxel, the search, the coarse winner and its ambiguity.
fn print_search(reg: &Registration, preset: &str) -> Result<()> {
    let r = &reg.search;
    outln!();
    outln!(
        "voxel       {}{}",
        r.stats.voxel,
        match &reg.voxel_rule {
            Some(rule) => format!(" ({rule}; set --voxel to choose)"),
            None => String::new(),
        }
    );
    outln!(
        "search      preset {preset}: {} rotations ({}), {}",
        r.stats.rotations,
        r.stats.rotation_set,
        match r.stats.mode {
            search::SearchMode::Exhaustive => "exhaustive",
            search::SearchMode::CoarseToFine(_) => "coarse-to-fine",
        }
    );
    outln!(
        "rotation    #{} (coarse winner), score {} (match {} = 5·n11 − n01)",
        r.winner().rotation_index,
        r.winner().score,
        r.winner().match_score
    );
    match (&r.runner_up, r.ambiguity) {
        (Some(ru), Some(a)) => outln!(
            "ambiguity   {a:.3} (best rotation > {:.0}° away: #{} with match {})",
            r.stats.distinct_radius_deg,
            ru.rotation_index,
            ru.match_score
        ),
        _ => outln!("ambiguity   n/a"),
    }
    Ok(())
}

/// The grids of the search, its representatives and its coarse level.
fn print_grids(r: &search::SearchResult) -> Result<()> {
    let g = &r.stats.geometry;
    outln!(
        "grids       target {}×{}×{} ({} occupied), source ≤ {}×{}×{}, FFT {}×{}×{}",
        g.kernel_dims[0],
        g.kernel_dims[1],
        g.kernel_dims[2],
        r.stats.target_occupied,
        g.source_max[0],
        g.source_max[1],
        g.source_max[2],
        g.fft_len[0],
        g.fft_len[1],
        g.fft_len[2]
    );
    if r.stats.searched_points < r.stats.source_points {
        outln!(
            "            source searched as {} representatives of its {} points (one per cell of voxel / {})",
            r.stats.searched_points,
            r.stats.source_points,
            search::REPRESENTATIVE_DIVISIONS
        );
    }
    if let Some(c) = r.stats.coarse_level.as_ref().filter(|c| c.rounds == 0) {
        let f = &c.geometry.fft_len;
        outln!(
            "coarse      voxel {}, {} source points, FFT {}×{}×{}; the best {} of {} rotations scored at the voxel size (first look, no neighbours; winner ranked {})",
            c.voxel, c.source_points, f[0], f[1], f[2], c.kept, r.stats.rotations, c.winner_rank
        );
    } else if let Some(c) = &r.stats.coarse_level {
        let f = &c.geometry.fft_len;
        outln!(
            "coarse      voxel {}, {} source points, FFT {}×{}×{}; kept {} of {} rotations ({} round(s); winner ranked {}), with neighbours within {:.1}°: {} scored at the voxel size",
            c.voxel, c.source_points, f[0], f[1], f[2], c.kept, r.stats.rotations, c.rounds, c.winner_rank, c.neighbour_deg, r.stats.scored
        );
    }
    Ok(())
}

/// One line per verified hypothesis, the chosen one marked.
fn print_verification(v: &Verification) -> Result<()> {
    outln!(
        "verified    {} hypothesis(es) at D = {:.4} (score = mean of both fitnesses within D):",
        v.hypotheses.len(),
        v.distance
    );
    let scans = match v.scanners {
        [true, true] => Some("source and target"),
        [true, false] => Some("source"),
        [false, true] => Some("target"),
        [false, false] => None,
    };
    if let Some(which) = scans {
        outln!(
            "  free space: {which} taken as scans from their origins; a point more than {:.3} in front of what the other scan saw counts against a pose",
            v.free_space_margin
        );
    }
    for (k, h) in v.hypotheses.iter().enumerate() {
        let mark = if k == v.chosen {
            " ← chosen"
        } else if Some(k) == v.runner_up {
            " (runner-up)"
        } else {
            ""
        };
        outln!(
            "  #{} rotation {}{} match {} → {} after polish, score {:.3} (source {:.3}, target {:.3}), {} ICP iterations{}{}{}{}{}{}",
            h.rank + 1,
            h.rotation_index,
            match h.level {
                ggs::pipeline::HypothesisLevel::Coarse => " (coarse level)",
                ggs::pipeline::HypothesisLevel::Voxel => "",
            },
            h.match_score,
            h.polished_match_score,
            h.evidence.score,
            h.evidence.fitness_source,
            h.evidence.fitness_target,
            h.iterations,
            if h.screened { " on the screening cells" } else { "" },
            h.evidence
                .free_space_violations
                .map(|s| format!(", {:.1} % in seen free space", 100.0 * s))
                .unwrap_or_default(),
            match (h.rejected_early, h.rejected_on_subsample) {
                (true, true) => ", rejected on a subsample",
                (true, false) => ", rejected early",
                _ => "",
            },
            if h.settled { ", settled on finer cells" } else { "" },
            h.same_as
                .map(|j| format!(", stopped on the pose of #{}", j + 1))
                .unwrap_or_default(),
            mark
        );
    }
    Ok(())
}

/// The per-stage split of `ggs register --timings`.
fn print_timings(reg: &Registration, read_ms: f64, total_ms: f64) -> Result<()> {
    let r = &reg.search;
    let t = &r.timings;
    let cpu = t.cpu_voxelize_ms
        + t.cpu_forward_ms
        + t.cpu_product_ms
        + t.cpu_inverse_ms
        + t.cpu_direct_ms;
    let pct = |v: f64| if cpu > 0.0 { 100.0 * v / cpu } else { 0.0 };
    outln!();
    outln!("stage                              wall ms     CPU ms  share of scoring CPU");
    outln!("read both clouds                {read_ms:>10.1}");
    outln!("target kernel and plans         {:>10.1}", t.target_ms);
    outln!("rotated extents                 {:>10.1}", t.extents_ms);
    if r.stats.coarse_level.is_some() {
        outln!(
            "coarse level (all rotations)    {:>10.1}",
            t.coarse_level_ms
        );
    }
    outln!(
        "search ({} rotations, {} thr)  {:>10.1}",
        r.stats.scored,
        r.stats.threads,
        t.search_ms
    );
    for (name, v) in [
        ("  voxelize rotated source", t.cpu_voxelize_ms),
        ("  forward FFT (z, y)", t.cpu_forward_ms),
        ("  FFT x, spectrum product, iFFT x", t.cpu_product_ms),
        ("  inverse FFT (y, z) + argmax", t.cpu_inverse_ms),
        ("  direct and sparse correlation", t.cpu_direct_ms),
    ] {
        outln!("{name:<32} {:>10} {v:>10.1}  {:>5.1} %", "", pct(v));
    }
    if r.stats.precision == search::Precision::Mixed {
        outln!(
            "  of which exact re-scoring ({} rotation(s)) {:>5.1} wall",
            r.stats.rescored,
            t.rescore_ms
        );
    }
    let fft_cpu_s = (t.cpu_forward_ms + t.cpu_product_ms + t.cpu_inverse_ms) * 1e-3;
    if fft_cpu_s > 0.0 {
        outln!(
            "  FFT work {:.2} GFLOP (nominal 5·N·log2 N): {:.1} GFLOP/s per core in the FFT stages, {:.1} GFLOP/s over the search wall time",
            r.stats.fft_gflop,
            r.stats.fft_gflop / fft_cpu_s,
            r.stats.fft_gflop / ((t.search_ms + t.coarse_level_ms) * 1e-3)
        );
    }
    outln!(
        "verify (polish, ICP, scores)    {:>10.1}",
        reg.timings.verify_ms
    );
    if let Some(f) = &reg.refine {
        outln!(
            "refine (setup {:.1})              {:>10.1}",
            f.setup_ms,
            f.total_ms
        );
    }
    outln!("total                           {total_ms:>10.1}");
    if let Some(peak) = ggs::memory::peak_resident() {
        outln!(
            "peak resident memory            {:>10}",
            ggs::memory::human_bytes(peak)
        );
    }
    Ok(())
}

/// `; peak memory 204 MiB` where the kernel tells this process's peak resident memory.
fn peak_memory_note() -> String {
    ggs::memory::peak_resident()
        .map(|b| format!("; peak memory {}", ggs::memory::human_bytes(b)))
        .unwrap_or_default()
}

pub fn run_refine(args: RefineArgs) -> Result<()> {
    let t0 = Instant::now();
    let format = args.io.input.options()?;
    // The reference GICP's settings (the paper preset's), changed by the flags.
    let mut flags = Changes::new("command line");
    flags.set_from("--method", "refine", args.method.clone());
    args.refine_options.put_changes(&mut flags);
    let cfg = Settings::layered(Preset::Paper, &[flags])?
        .refine_config(args.threads)
        .context("ggs refine needs a method: gicp, p2plane or p2p")?;
    let init = read_matrix(&args.init)?;
    let source = load(&args.source, &format, args.quiet)?;
    let target = load(&args.target, &format, args.quiet)?;
    let r = refine::refine(&source, &target, &init, &cfg)?;
    write_outputs(&args.io, &source, &r.transform)?;
    if args.io.json {
        let doc = RefinementDocument {
            source: Some(args.source.display().to_string()),
            target: Some(args.target.display().to_string()),
            ..RefinementDocument::new(init, &r, t0.elapsed().as_secs_f64() * 1e3)
        };
        outln!("{}", doc.to_json());
    } else {
        out!("{}", r.transform.to_text());
        outln!();
        print_report(&r)?;
    }
    Ok(())
}

pub fn run_rotations(args: RotationsArgs) -> Result<()> {
    let set = RotationSet::named(&args.name)?;
    match &args.out {
        Some(path) => {
            let data: Vec<f64> = set
                .matrices
                .iter()
                .flat_map(|m| (0..3).flat_map(move |r| (0..3).map(move |c| m[(r, c)])))
                .collect();
            io::npy::write_npy_3d(path, set.len(), &data)?;
            outln!(
                "{}: {} rotations written to {}",
                set.name,
                set.len(),
                path.display()
            );
        }
        None => outln!(
            "{}: {} rotations, step {}°",
            set.name,
            set.len(),
            set.step_deg
        ),
    }
    Ok(())
}
