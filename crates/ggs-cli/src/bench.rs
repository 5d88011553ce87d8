//! `ggs bench PROTOCOL`: run a published benchmark protocol or a manifest of pairs, or a
//! share of one (`--shard I/N`); `ggs bench merge RUN_DIRS... --out DIR` joins the shards.

use crate::pipeline_args::PipelineArgs;
use anyhow::{bail, Context, Result};
use clap::Args;
use ggs::pipeline::Preset;
use ggs::Settings;
use ggs_bench::benchmark::shard::Shard;
use ggs_bench::benchmark::{self, BenchVoxel, Plan, Selection};
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
    /// Voxel size, or `auto`: the automatic voxel of `ggs register` with no flag, so the run
    /// measures what a user who gives no flag gets (success thresholds unchanged). Default:
    /// the protocol's, or each manifest pair's own.
    #[arg(long, value_name = "VOXEL|auto")]
    pub voxel: Option<BenchVoxel>,
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
    if args.protocol != "manifest" && !args.inputs.is_empty() {
        bail!("only 'manifest' takes a file argument; give the clouds' directory with --data");
    }
    let selection = Selection {
        protocol: args.protocol.clone(),
        manifest: args.inputs.first().cloned(),
        data: args.data.clone(),
        pairs: args.pairs.clone(),
        limit: args.limit,
        shard: args.shard.as_deref().map(Shard::parse).transpose()?,
        voxel: args.voxel,
        move_seed: args.move_seed,
        max_rre_deg: args.max_rre,
        max_rte: args.max_rte,
    };
    let (preset, settings) = args.pipeline.settings(|_| {})?;
    // A paper run with the paper's rotation set uses the protocol's set of the paper.
    let paper_rotations =
        preset == Preset::Paper && settings.rotations == Settings::preset(Preset::Paper).rotations;
    let plan = Plan::new(&selection, settings, args.threads, paper_rotations)?;
    let out = args.out.clone().unwrap_or_else(|| plan.default_out());
    let pb = crate::progress::bar(plan.pairs.len(), "pairs", args.quiet);
    let mut successes = 0;
    let outcome = benchmark::run(&plan, &out, |done, _, row| {
        successes += row.success as usize;
        pb.set_position(done as u64);
        pb.set_message(format!("{successes}/{done} solved, last {}", row.id));
    })
    .with_context(|| format!("benchmark run in {}", out.display()))?;
    pb.finish_and_clear();
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&outcome.summary)?);
    } else {
        out!("{}", outcome.summary.markdown(&outcome.rows, plan.metres));
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
