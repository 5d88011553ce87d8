//! `ggs info` and `ggs convert`, and the input options every command shares.

use anyhow::{bail, Context, Result};
use clap::Args;
use ggs::io::{self, e57::E57Options, Format, LoadedCloud, LoadedPoints, ReadOptions};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How input files are read (every command that reads clouds).
#[derive(Args, Clone, Default)]
pub struct InputArgs {
    /// Force the input format of every input file (ply, pcd, xyz, txt, csv, pts, npy, npz,
    /// bin, las, laz, e57, obj, stl); default: magic bytes, then the extension.
    #[arg(long)]
    pub format: Option<String>,
    /// E57: read only this scan (numbered from 0); default: every scan, each moved by its pose.
    #[arg(long, value_name = "N")]
    pub scan: Option<usize>,
    /// E57: keep scans in their own frame (do not apply their poses).
    #[arg(long)]
    pub no_pose: bool,
    /// NPZ: the array to read; default: the one shaped [N, 3] (or named points / xyz).
    #[arg(long, value_name = "NAME")]
    pub array: Option<String>,
    /// OBJ, STL and PLY meshes: sample N points uniformly on the faces instead of taking
    /// the vertices (reproducible).
    #[arg(long, value_name = "N")]
    pub sample_mesh: Option<usize>,
}

impl InputArgs {
    /// The library's read options.
    pub fn options(&self) -> Result<ReadOptions> {
        let format = match &self.format {
            Some(f) => Some(Format::from_name(f).with_context(|| {
                format!(
                    "--format: unknown format '{f}' (known: {})",
                    io::FORMAT_NAMES
                )
            })?),
            None => None,
        };
        if self.sample_mesh == Some(0) {
            bail!("--sample-mesh: 0 points asked for (at least 1)");
        }
        Ok(ReadOptions {
            format,
            e57: E57Options {
                scan: self.scan,
                apply_pose: !self.no_pose,
            },
            npz_array: self.array.clone(),
            mesh_samples: self.sample_mesh,
        })
    }
}

/// Read a cloud (`f32` offsets, see `ggs::Cloud`), warning (unless `quiet`) about dropped
/// non-finite points.
pub fn load(path: &Path, opts: &ReadOptions, quiet: bool) -> Result<LoadedCloud> {
    let loaded = io::read_cloud_with(path, opts)?;
    warn_dropped(path, loaded.dropped_non_finite, quiet);
    Ok(loaded)
}

/// Read several clouds side by side ([`io::read_clouds_with`]), warning as [`load`] does, in
/// the order of `paths`.
pub fn load_all(paths: &[&Path], opts: &ReadOptions, quiet: bool) -> Vec<Result<LoadedCloud>> {
    io::read_clouds_with(paths, opts)
        .into_iter()
        .zip(paths)
        .map(|(loaded, path)| {
            let loaded = loaded?;
            warn_dropped(path, loaded.dropped_non_finite, quiet);
            Ok(loaded)
        })
        .collect()
}

/// Read a file's points as `f64`, exactly as written; warns as [`load`] does.
pub fn load_points(path: &Path, opts: &ReadOptions, quiet: bool) -> Result<LoadedPoints> {
    let loaded = io::read_points_with(path, opts)?;
    warn_dropped(path, loaded.dropped_non_finite, quiet);
    Ok(loaded)
}

fn warn_dropped(path: &Path, dropped: usize, quiet: bool) {
    if dropped > 0 && !quiet {
        tracing::warn!(
            "{}: dropped {} point(s) with NaN, infinite or invalid coordinates",
            path.display(),
            dropped
        );
    }
}

#[derive(Args)]
pub struct InfoArgs {
    /// Point-cloud files.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
    /// Print JSON (one object per file, in a list).
    #[arg(long)]
    pub json: bool,
}

/// `ggs info`: format, size, points, bounds, and the read time and throughput of each file.
pub fn run_info(args: InfoArgs) -> Result<()> {
    let opts = args.input.options()?;
    let mut all = Vec::new();
    for f in &args.files {
        let t0 = Instant::now();
        let l = load_points(f, &opts, true)?;
        let secs = t0.elapsed().as_secs_f64();
        let b = ggs::cloud::bounds(&l.points).context("empty cloud")?;
        let mb_s = l.file_bytes as f64 / 1e6 / secs.max(1e-9);
        let scans = if l.format == Format::E57 {
            let file = std::fs::File::open(f).with_context(|| f.display().to_string())?;
            Some(io::e57::e57_scans(f, std::io::BufReader::new(file))?)
        } else {
            None
        };
        if args.json {
            all.push(serde_json::json!({
                "file": f,
                "format": format!("{:?}", l.format).to_lowercase(),
                "bytes": l.file_bytes,
                "points": l.points.len(),
                "dropped_non_finite": l.dropped_non_finite,
                "min": b.min,
                "max": b.max,
                "read_s": secs,
                "read_mb_per_s": mb_s,
                "scans": scans.as_ref().map(|s| s.iter().map(|s| serde_json::json!({
                    "name": s.name,
                    "records": s.records,
                    "pose": s.pose.map(|p| p.to_rows()),
                })).collect::<Vec<_>>()),
            }));
            continue;
        }
        outln!("{}", f.display());
        outln!("  format    {:?}", l.format);
        outln!("  size      {:.3} MB", l.file_bytes as f64 / 1e6);
        outln!(
            "  points    {}{}",
            l.points.len(),
            if l.dropped_non_finite > 0 {
                format!(" ({} non-finite or invalid dropped)", l.dropped_non_finite)
            } else {
                String::new()
            }
        );
        outln!("  min       {:?}", b.min);
        outln!("  max       {:?}", b.max);
        outln!("  read      {:.3} s, {:.0} MB/s", secs, mb_s);
        for (k, s) in scans.iter().flatten().enumerate() {
            outln!(
                "  scan {k}    {} records{}{}",
                s.records,
                s.name
                    .as_ref()
                    .map(|n| format!(", '{n}'"))
                    .unwrap_or_default(),
                if s.pose.is_some() {
                    ", with a pose"
                } else {
                    ""
                }
            );
        }
    }
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&all)?);
    }
    Ok(())
}

#[derive(Args)]
pub struct ConvertArgs {
    /// Input file (any format ggs reads).
    pub input: PathBuf,
    /// Output file; the format follows its extension (ply, pcd, xyz/txt/pts/csv, npy, bin,
    /// las, laz, e57) unless --to is given.
    pub output: PathBuf,
    /// Output format, overriding the extension.
    #[arg(long, value_name = "FORMAT")]
    pub to: Option<String>,
    /// PLY output as text instead of binary.
    #[arg(long)]
    pub ascii: bool,
    #[command(flatten)]
    pub input_args: InputArgs,
    /// No warnings.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `ggs convert`: read any format, write any writable one (atomically).
pub fn run_convert(args: ConvertArgs) -> Result<()> {
    let opts = args.input_args.options()?;
    let l = load_points(&args.input, &opts, args.quiet)?;
    let to =
        match &args.to {
            Some(f) => Some(Format::from_name(f).with_context(|| {
                format!("--to: unknown format '{f}' (writable: {})", io::WRITABLE)
            })?),
            None => None,
        };
    let is_ply = to.or_else(|| Format::from_extension(&args.output)) == Some(Format::Ply);
    if args.ascii && !is_ply {
        bail!("--ascii applies to PLY output only");
    }
    if is_ply {
        io::ply::write_ply(
            &args.output,
            &l.points,
            None,
            io::ply::PlyWriteOptions { ascii: args.ascii },
        )?;
    } else {
        io::write_cloud(&args.output, &l.points, to)?;
    }
    if !args.quiet {
        eprintln!(
            "{} points: {} -> {}",
            l.points.len(),
            args.input.display(),
            args.output.display()
        );
    }
    Ok(())
}
