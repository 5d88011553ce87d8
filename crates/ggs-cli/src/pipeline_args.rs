//! The argument groups of the pipeline, shared by `ggs register` and `ggs bench`: a preset and
//! the flags that change it.

use crate::refine_args::{parse_method, RefineOptions};
use anyhow::{bail, Context, Result};
use clap::Args;
use ggs::coarse;
use ggs::pipeline::{Preset, RegistrationConfig};
use ggs::rotations::RotationSet;

/// The configuration of the pipeline, shared by `register` and `bench`: a preset and the
/// flags that change it.
#[derive(Args, Clone)]
pub struct PipelineArgs {
    /// default: full-SO(3) set, coarse-to-fine, verification of the distinct hypotheses
    /// (checking the free space of clouds that are scans from their origin), GICP; paper:
    /// the GGS paper's configuration (limited15, exhaustive, one hypothesis, GICP).
    #[arg(long, default_value = "default")]
    pub preset: String,
    /// Built-in rotation set: hopf15-id (default), limited15, full15, limited10, hopf15,
    /// hopf15-dedup, ico162-s10.
    #[arg(long)]
    pub rotations: Option<String>,
    #[command(flatten)]
    pub search: SearchArgs,
    /// Verify at most N distinct hypotheses (1: only the coarse winner).
    #[arg(long, value_name = "N")]
    pub max_hypotheses: Option<usize>,
    /// Verify the hypotheses whose match score is at least this fraction of the winner's.
    #[arg(long, value_name = "F")]
    pub margin: Option<f64>,
    /// How the verification scores a pose: tight (default: each point within D counts by
    /// 1 − d²/D², so an exact small overlap beats a loose large one), fitness (the share of
    /// points within D) or oriented (tight, counting only points whose normals, turned away
    /// from their cloud's centroid, face the same way: single views of convex objects).
    #[arg(long, value_name = "SCORE")]
    pub verify_score: Option<String>,
    /// Take the coarse winner without verification.
    #[arg(long)]
    pub no_verify: bool,
    /// Always run the whole search. Without this flag the default preset first verifies the
    /// hypotheses of the coarse level's best 16 rotations and stops there when one pose
    /// scores at least 0.5 and no distinct pose 0.6 of that (docs/pipeline.md, "The first
    /// look").
    #[arg(long)]
    pub no_first_look: bool,
    /// Polish each hypothesis on a finer rotation grid (7 rotations a step, scored by the
    /// correlation) before its ICP; off by default (measured: no change on the benchmarks).
    #[arg(long)]
    pub polish: bool,
    /// Refinement after the coarse search: gicp (default), p2plane, p2p or none.
    #[arg(long)]
    pub refine: Option<String>,
    /// Final refinement on both clouds thinned to cells of this many voxels (default preset
    /// 0.2, stopping at steps below 1e-4 rad and 1e-4 source radii; 0: full resolution and
    /// the reference stopping rules, as --preset paper).
    #[arg(long, value_name = "VOXELS")]
    pub refine_cell: Option<f64>,
    #[command(flatten)]
    pub refine_options: RefineOptions,
}

impl PipelineArgs {
    /// The preset, changed by the flags given (voxel and rotation set not included).
    pub fn config(&self, threads: usize) -> Result<RegistrationConfig> {
        let preset: Preset = self.preset.parse().context("--preset")?;
        let mut cfg = RegistrationConfig::preset(preset);
        cfg.threads = threads;
        if let Some(name) = &self.rotations {
            cfg.rotations = RotationSet::named(name)?;
        }
        let (mode, precision) = self.search.parse(cfg.search.mode)?;
        cfg.search.mode = mode;
        cfg.search.precision = precision;
        if self.no_verify {
            cfg.verify = None;
        }
        if self.no_first_look {
            cfg.first_look = None;
        }
        if let Some(v) = &mut cfg.verify {
            if let Some(n) = self.max_hypotheses {
                v.max_hypotheses = n;
            }
            if let Some(m) = self.margin {
                v.margin = m;
            }
            // The ranges are the core's ([`VerifyConfig::validate`]).
            v.validate().context("--max-hypotheses / --margin")?;
            if let Some(sc) = &self.verify_score {
                v.score = sc.parse().context("--verify-score")?;
            }
        } else if self.max_hypotheses.is_some()
            || self.margin.is_some()
            || self.verify_score.is_some()
        {
            bail!("--max-hypotheses, --margin and --verify-score need verification (not with --no-verify or --preset paper)");
        }
        if self.polish {
            cfg.polish = Some(ggs::pipeline::PolishConfig::default());
        }
        if let Some(c) = self.refine_cell {
            cfg.final_stage = cfg
                .final_stage
                .with_cell_voxels(c)
                .context("--refine-cell")?;
        }
        if self.refine_options.max_iterations.is_some() {
            // The user's cap, not the stage's.
            cfg.final_stage.max_iterations = usize::MAX;
        }
        let method = match &self.refine {
            Some(name) => parse_method(name)?,
            None => cfg.refine.map(|r| r.method),
        };
        cfg.refine = match method {
            Some(m) => Some(self.refine_options.config(m, threads)?),
            None => None,
        };
        Ok(cfg)
    }
}

/// How the rotations are searched (shared by `register` and `bench`).
#[derive(Args, Clone)]
pub struct SearchArgs {
    /// exhaustive: every rotation at the voxel size (GGS); coarse-to-fine (the default preset's):
    /// every rotation at --coarse-factor × voxel, then the best --coarse-keep of them and their
    /// grid neighbours at the voxel size (much faster; same answers on every benchmark pair).
    #[arg(long, value_name = "MODE")]
    pub search: Option<String>,
    /// Correlation arithmetic: mixed (f32 with proven error bounds, exact re-scoring of every
    /// rotation whose bound reaches the best: same picks as f64) or f64.
    #[arg(long, default_value = "mixed")]
    pub precision: String,
    /// Coarse voxel = this × voxel (coarse-to-fine; default preset 4, else 2).
    #[arg(long, value_name = "F")]
    pub coarse_factor: Option<f64>,
    /// Fraction of the rotations kept from the coarse level (coarse-to-fine; default preset
    /// 0.01, else 0.02).
    #[arg(long, value_name = "FRAC")]
    pub coarse_keep: Option<f64>,
    /// Keep at least this many rotations from the coarse level (coarse-to-fine; default 16).
    #[arg(long, value_name = "N")]
    pub coarse_keep_min: Option<usize>,
    /// Verify also the N best distinct hypotheses of the coarse level, each with its own
    /// translation at the coarse voxel (coarse-to-fine; default preset 8, else 0; they find
    /// the right pose of low-overlap pairs that the voxel size ranks too low).
    #[arg(long, value_name = "N")]
    pub coarse_hypotheses: Option<usize>,
}

impl SearchArgs {
    /// The search mode (the preset's `mode` unless --search is given) and precision.
    pub fn parse(
        &self,
        preset: coarse::SearchMode,
    ) -> Result<(coarse::SearchMode, coarse::Precision)> {
        // The preset's parameters (the library's defaults for a preset without them), changed
        // by the options given.
        let d = match preset {
            coarse::SearchMode::CoarseToFine(c) => c,
            coarse::SearchMode::Exhaustive => coarse::CoarseToFine::default(),
        };
        let c2f = coarse::CoarseToFine {
            factor: self.coarse_factor.unwrap_or(d.factor),
            keep_fraction: self.coarse_keep.unwrap_or(d.keep_fraction),
            keep_min: self.coarse_keep_min.unwrap_or(d.keep_min),
            neighbour_deg: d.neighbour_deg,
            hypotheses: self.coarse_hypotheses.unwrap_or(d.hypotheses),
        };
        let mode = match (&self.search, preset) {
            (Some(name), _) => coarse::SearchMode::from_name(name, c2f).context("--search")?,
            (None, coarse::SearchMode::CoarseToFine(_)) => coarse::SearchMode::CoarseToFine(c2f),
            (None, m) => m,
        };
        let precision = self.precision.parse().context("--precision")?;
        Ok((mode, precision))
    }
}
