//! `ggs bench PROTOCOL`: run a published benchmark protocol or a manifest of pairs, or a
//! share of one (`--shard I/N`); `ggs bench merge RUN_DIRS... --out DIR` joins the shards.

use crate::pipeline_args::PipelineArgs;
use anyhow::{bail, Context, Result};
use clap::Args;
use ggs::benchmark::shard::{write_shard_file, Shard, ShardFile};
use ggs::benchmark::{self, missing_files, Protocol, RunConfig};
use std::path::PathBuf;

#[derive(Args)]
pub struct BenchArgs {
    /// 3dmatch, kitti, eth, fpv1, manifest (then give the manifest file), or merge (then give
    /// the shards' run directories and --out).
    pub protocol: String,
    /// The manifest (`pairs.tsv` format) for `manifest`; the run directories for `merge`.
    pub inputs: Vec<PathBuf>,
    /// Run only shard I of N: the selected pairs at positions k with k mod N = I, into their
    /// own --out; `ggs bench merge` joins the N run directories.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Directory with the protocol's point clouds (not for `manifest`).
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// Run directory: pairs.csv (resumable), results.json, summary.md, recall.svg.
    /// Default: ggs-bench-PROTOCOL.
    #[arg(long, value_name = "RUN_DIR")]
    pub out: Option<PathBuf>,
    /// Only the first N pairs (after --pairs).
    #[arg(long, value_name = "N")]
    pub limit: Option<usize>,
    /// Only pairs whose id contains one of these comma-separated substrings.
    #[arg(long, value_name = "A,B")]
    pub pairs: Option<String>,
    /// Voxel size (default: the protocol's, or each manifest pair's own).
    #[arg(long)]
    pub voxel: Option<f64>,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Move every source by a random rigid motion (uniform rotation, translation up to the
    /// source's diagonal) drawn from this seed and the pair's id, composing the ground truth:
    /// a test that the results do not depend on the pose of the source.
    #[arg(long, value_name = "SEED")]
    pub move_seed: Option<u64>,
    /// Success threshold on RRE, degrees (default: the protocol's).
    #[arg(long, value_name = "DEG")]
    pub max_rre: Option<f64>,
    /// Success threshold on RTE, cloud units (default: the protocol's; 3 voxels for a manifest).
    #[arg(long, value_name = "D")]
    pub max_rte: Option<f64>,
    /// Worker threads per pair (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Exit with an error (status 2) if the recall is below this, in percent: a gate for CI.
    #[arg(long, value_name = "PCT")]
    pub min_recall: Option<f64>,
    /// Print the summary as JSON instead of Markdown.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(args: BenchArgs) -> Result<()> {
    if args.protocol == "merge" {
        return merge(&args);
    }
    if args.inputs.len() > 1 {
        bail!("only one manifest file may be given");
    }
    let protocol = Protocol::from_name(&args.protocol, args.inputs.first().map(|p| p.as_path()))?;
    if matches!(protocol, Protocol::Manifest(_)) {
        if args.data.is_some() {
            bail!("--data is not used with a manifest: its paths are relative to the manifest");
        }
    } else if !args.inputs.is_empty() {
        bail!("only 'manifest' takes a file argument; give the clouds' directory with --data");
    }
    let data = match (&protocol, &args.data) {
        (Protocol::Manifest(_), _) => PathBuf::new(),
        (_, Some(d)) if d.is_dir() => d.clone(),
        (_, Some(d)) => bail!("--data {}: not a directory", d.display()),
        (p, None) => bail!("{} needs --data DIR with its point clouds", p.name()),
    };
    let defaults = protocol.defaults();
    let mut pairs = protocol.pairs(&data)?;
    if let Some(filter) = &args.pairs {
        let keys: Vec<&str> = filter.split(',').filter(|k| !k.is_empty()).collect();
        pairs.retain(|p| keys.iter().any(|k| p.id.contains(k)));
    }
    if let Some(n) = args.limit {
        pairs.truncate(n);
    }
    if pairs.is_empty() {
        bail!("no pair selected (check --pairs and --limit)");
    }
    let (count, first) = missing_files(&pairs, 5);
    if count > 0 {
        let list: Vec<String> = first.iter().map(|p| format!("  {}", p.display())).collect();
        bail!(
            "{count} file(s) the {} pairs need are missing; the first:\n{}",
            protocol.name(),
            list.join("\n")
        );
    }
    let mut pipeline = args.pipeline.config(args.threads)?;
    if args.pipeline.preset == "paper" && args.pipeline.rotations.is_none() {
        pipeline.rotations = ggs::rotations::RotationSet::named(defaults.paper_rotations)?;
    }
    let cfg = RunConfig {
        voxel: args.voxel,
        pipeline,
        max_rre_deg: args.max_rre.unwrap_or(defaults.max_rre_deg),
        max_rte: args.max_rte.or(defaults.max_rte),
        default_voxel: defaults.voxel,
        motion_seed: args.move_seed,
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("ggs-bench-{}", protocol.name())));
    let metres = !matches!(protocol, Protocol::Manifest(_));
    if let Some(text) = &args.shard {
        let shard = Shard::parse(text)?;
        let selected_pairs = pairs.len();
        pairs = shard.select(&pairs);
        let file = ShardFile {
            shard,
            selected_pairs,
            metres,
            ids: pairs.iter().map(|p| p.id.clone()).collect(),
        };
        write_shard_file(&out, &file)?;
        if pairs.is_empty() {
            bail!("shard {text} has no pair: {selected_pairs} pairs were selected");
        }
    }
    let pb = crate::progress::bar(pairs.len(), "pairs", args.quiet);
    let mut successes = 0;
    let outcome = benchmark::run(
        protocol.name(),
        &pairs,
        &cfg,
        metres,
        &out,
        |done, _, row| {
            successes += row.success as usize;
            pb.set_position(done as u64);
            pb.set_message(format!("{successes}/{done} solved, last {}", row.id));
        },
    )
    .with_context(|| format!("benchmark run in {}", out.display()))?;
    pb.finish_and_clear();
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&outcome.summary)?);
    } else {
        out!("{}", outcome.summary.markdown(&outcome.rows, metres));
        outln!(
            "\n{} pairs ({} from an earlier run); results in {}",
            outcome.rows.len(),
            outcome.resumed,
            out.display()
        );
    }
    if let Some(min) = args.min_recall {
        let recall = outcome.summary.recall * 100.0;
        if recall < min {
            bail!(
                "recall {recall:.2} % is below --min-recall {min} % ({} of {} pairs)",
                outcome.summary.successes,
                outcome.summary.pairs
            );
        }
    }
    Ok(())
}

/// `ggs bench merge RUN_DIRS... --out DIR`.
fn merge(args: &BenchArgs) -> Result<()> {
    let Some(out) = &args.out else {
        bail!("merge needs --out DIR for the merged run");
    };
    if args.inputs.is_empty() {
        bail!("merge needs the shards' run directories");
    }
    if args.inputs.iter().any(|d| d == out) {
        bail!("--out must be a new directory, not one of the shards");
    }
    let outcome = benchmark::shard::merge(&args.inputs, out)
        .with_context(|| format!("merging into {}", out.display()))?;
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&outcome.summary)?);
    } else {
        let metres = args.inputs.first().is_some_and(|d| {
            std::fs::read_to_string(d.join("shard.json"))
                .is_ok_and(|t| t.contains("\"metres\": true"))
        });
        out!("{}", outcome.summary.markdown(&outcome.rows, metres));
        outln!(
            "\n{} pairs merged from {} shards; results in {}",
            outcome.rows.len(),
            args.inputs.len(),
            out.display()
        );
    }
    Ok(())
}
