//! `ggs partial`: generate a FAUST-partial-style benchmark, or rebuild the published FPv1
//! pairs.

use anyhow::{bail, Context, Result};
use clap::Args;
use ggs_bench::generator::{
    self, fpv1,
    options::{positive, GeneratorOptions},
    output, GeneratorConfig, ScanInput,
};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args)]
pub struct PartialArgs {
    /// Scans or meshes (any format ggs reads; OBJ, STL and PLY meshes are sampled).
    pub inputs: Vec<PathBuf>,
    /// A list of inputs with their own settings: `PATH [name=] [scale=] [group=] [radius=]
    /// [voxel=] [points=] [spacing=]` per line, paths relative to the list.
    #[arg(long, value_name = "LIST")]
    pub inputs_list: Option<PathBuf>,
    /// Output folder (must be empty or new unless --force).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Overwrite files in a non-empty output folder.
    #[arg(long)]
    pub force: bool,
    /// Ground-truth preset: fpv1, fpv1-code, fp-{r,t,o}-{e,m,h}, or scene-{e,m,h} (views
    /// cropped from a scene: a room, a LiDAR scan; overlap as fp-o-{e,m,h}).
    #[arg(long, default_value = "fpv1")]
    pub preset: String,
    /// Random seed: the same seed gives the same benchmark, byte for byte.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Points sampled on each mesh (point clouds are used as they are).
    #[arg(long, value_name = "N", conflicts_with = "spacing")]
    pub points: Option<usize>,
    /// Sample meshes to this mean spacing instead (in metres after --scale).
    #[arg(long, value_name = "S")]
    pub spacing: Option<f64>,
    /// Use a mesh's vertices as its points (no surface sampling), e.g. FAUST scans.
    #[arg(long, conflicts_with_all = ["points", "spacing"])]
    pub vertices: bool,
    /// Multiply coordinates by this (0.1 for decimetres, 0.001 for millimetres).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Keep only this OBJ group (e.g. `body` for the MakeHuman base mesh).
    #[arg(long)]
    pub group: Option<String>,
    /// Icosphere subdivisions: 0 → 12, 1 → 42, 2 → 162 vertices.
    #[arg(long, default_value_t = 1)]
    pub subdivisions: u32,
    /// Icosphere radius (m).
    #[arg(long, default_value_t = 1.5)]
    pub radius: f64,
    /// Icosphere centre: centroid (the scan's centre of mass) or origin (its own coordinate
    /// origin, as the published FPv1).
    #[arg(long, default_value = "centroid")]
    pub centre: String,
    /// Up axis (x, y or z): cameras at or below the floor are dropped.
    #[arg(long, default_value = "y")]
    pub up: String,
    /// Keep the first K above-floor cameras (0: all). The published FPv1 used 12. A scene
    /// preset draws K crops.
    #[arg(long, value_name = "K", default_value_t = 12)]
    pub views: usize,
    /// Scene presets: crop radius as this share of the scene's extent, the diagonal of the
    /// box holding the middle 96 % of its coordinates on each axis (a list's radius= gives
    /// one scene its own radius instead).
    #[arg(long, value_name = "SHARE", default_value_t = 0.4)]
    pub crop: f64,
    /// Camera positions (x y z per line, floor frame) instead of the icosphere.
    #[arg(long, value_name = "FILE")]
    pub cameras: Option<PathBuf>,
    /// Keep pairs with overlap at least this (percent; default: the preset's).
    #[arg(long, value_name = "PCT")]
    pub min_overlap: Option<f64>,
    /// Keep pairs with overlap below this (percent; 100 includes 100).
    #[arg(long, value_name = "PCT")]
    pub max_overlap: Option<f64>,
    /// Hidden point removal radius R = FACTOR × the scan's bounding-box diagonal.
    #[arg(long, value_name = "FACTOR", default_value_t = 1000.0)]
    pub flip_factor: f64,
    /// Voxel size written into the manifest for each pair (m).
    #[arg(long, default_value_t = 0.06)]
    pub voxel: f64,
    /// Rebuild the published FPv1 pairs from this CSV (with --scans).
    #[arg(long, value_name = "CSV", requires = "scans")]
    pub fpv1: Option<PathBuf>,
    /// Folder with the FAUST scans (tr_scan_000.ply, …) for --fpv1.
    #[arg(long, value_name = "DIR")]
    pub scans: Option<PathBuf>,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

/// The generator's configuration from the flags, checked by the library.
fn config(args: &PartialArgs) -> Result<GeneratorConfig> {
    let options = GeneratorOptions {
        preset: &args.preset,
        seed: args.seed,
        points: args.points,
        spacing: args.spacing,
        vertices: args.vertices,
        subdivisions: args.subdivisions,
        radius: args.radius,
        centre: &args.centre,
        up: &args.up,
        views: args.views,
        crop: args.crop,
        cameras: args.cameras.as_deref(),
        min_overlap: args.min_overlap,
        max_overlap: args.max_overlap,
        flip_factor: args.flip_factor,
        voxel: args.voxel,
        threads: args.threads,
    };
    Ok(options.config()?)
}

pub fn run(args: PartialArgs) -> Result<()> {
    let cfg = config(&args)?;
    match &args.fpv1 {
        Some(csv) => rebuild_fpv1(&args, &cfg, csv),
        None => generate(&args, &cfg),
    }
}

/// `--fpv1 CSV --scans DIR`: the published pairs, with the overlap check.
fn rebuild_fpv1(args: &PartialArgs, cfg: &GeneratorConfig, csv: &Path) -> Result<()> {
    let t0 = Instant::now();
    if !args.inputs.is_empty() || args.inputs_list.is_some() {
        bail!("--fpv1 rebuilds the published pairs from --scans; give no other inputs");
    }
    let scans = args.scans.as_ref().context("--fpv1 needs --scans DIR")?;
    if !scans.is_dir() {
        bail!("--scans {}: not a directory", scans.display());
    }
    output::prepare_out(&args.out, args.force)?;
    let pb = crate::progress::bar(100, "scans", args.quiet);
    let r = fpv1::rebuild(csv, scans, cfg, &args.out, |done, total, name| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
        pb.set_message(name.to_string());
    })?;
    pb.finish_and_clear();
    let diffs: Vec<f64> = r
        .checks
        .iter()
        .map(|c| (c.recomputed - c.published).abs())
        .collect();
    let max = diffs.iter().copied().fold(0.0, f64::max);
    let within = |t: f64| diffs.iter().filter(|&&d| d <= t).count();
    if args.json {
        outln!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "summary": r.summary,
                "missing_scans": r.missing_scans,
                "overlap_max_abs_difference": max,
                "overlap_within_1": within(1.0),
                "overlap_within_5": within(5.0),
            }))?
        );
        return Ok(());
    }
    out!("{}", r.summary.markdown());
    outln!(
        "\nOverlap check ({} pairs): |recomputed − published| ≤ 1 point for {}, ≤ 5 for {}, max {:.2} (per pair: overlap_check.csv)",
        diffs.len(),
        within(1.0),
        within(5.0),
        max
    );
    if !r.missing_scans.is_empty() {
        outln!(
            "{} scans of the list are not in {} (their pairs were skipped), e.g. {}",
            r.missing_scans.len(),
            scans.display(),
            r.missing_scans[0]
        );
    }
    outln!(
        "{} pairs in {:.1} s; run them with: ggs bench manifest {}",
        r.pairs.len(),
        t0.elapsed().as_secs_f64(),
        args.out.join("pairs.tsv").display()
    );
    Ok(())
}

/// The inputs of the command line and of `--inputs-list`, named uniquely.
fn inputs(args: &PartialArgs) -> Result<Vec<ScanInput>> {
    let mut inputs: Vec<ScanInput> = Vec::new();
    if let Some(list) = &args.inputs_list {
        let text =
            std::fs::read_to_string(list).with_context(|| format!("reading {}", list.display()))?;
        inputs.extend(generator::parse_inputs_list(list, &text)?);
    }
    for p in &args.inputs {
        let mut s = ScanInput::new(p);
        s.scale = positive("scale", args.scale)?;
        s.group = args.group.clone();
        inputs.push(s);
    }
    if inputs.is_empty() {
        bail!("no input: give scans or meshes, --inputs-list LIST, or --fpv1 CSV --scans DIR");
    }
    generator::check_names(&inputs)?;
    Ok(inputs)
}

/// Scans or meshes in: a generated benchmark out.
fn generate(args: &PartialArgs, cfg: &GeneratorConfig) -> Result<()> {
    let t0 = Instant::now();
    let inputs = inputs(args)?;
    output::prepare_out(&args.out, args.force)?;
    let pb = crate::progress::bar(inputs.len(), "scans", args.quiet);
    let g = generator::generate(&inputs, cfg, &args.out, |done, _, name| {
        pb.set_position(done as u64);
        pb.set_message(name.to_string());
    })?;
    pb.finish_and_clear();
    if g.hull_skipped > 0 {
        tracing::warn!(
            "{} hull points were skipped for rounding trouble; views may miss a few points",
            g.hull_skipped
        );
    }
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&g.summary)?);
    } else {
        out!("{}", g.summary.markdown());
        outln!(
            "\n{} pairs in {:.1} s; run them with: ggs bench manifest {}",
            g.pairs.len(),
            t0.elapsed().as_secs_f64(),
            args.out.join("pairs.tsv").display()
        );
    }
    Ok(())
}
