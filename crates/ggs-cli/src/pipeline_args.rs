//! The pipeline's flags, shared by `ggs register` and `ggs bench`: a preset, a settings file,
//! and flags that change single settings. Each flag is one settings key ([`ggs::Settings`]);
//! the ranges and rules are the library's.

use anyhow::{Context, Result};
use clap::Args;
use ggs::pipeline::Preset;
use ggs::settings::{Changes, Settings, SettingsFile};
use serde_json::Value;
use std::path::PathBuf;

/// The flags whose argument id is not their settings key: (argument id, key). Every other
/// flag whose id is a settings key sets that key ([`put`]); the help of both ends with the
/// presets' values ([`with_preset_values`]).
const RENAMED_FLAGS: [(&str, &str); 3] = [
    ("rotations_file", "rotations"),
    ("no_first_look", "first_look"),
    ("no_verify", "verify"),
];

/// The configuration of the pipeline, shared by `register` and `bench`: a preset, a settings
/// file and the flags that change them.
#[derive(Args, Clone)]
pub struct PipelineArgs {
    /// The settings a run starts from: default (full-SO(3) set, coarse-to-fine, verification
    /// of the distinct hypotheses, GICP on thinned clouds) or paper (the GGS paper's:
    /// limited15, exhaustive, one hypothesis, GICP). Default: the settings file's `preset`,
    /// else default.
    #[arg(long)]
    pub preset: Option<String>,
    /// Settings file (TOML or JSON): `preset` and any settings keys (`ggs settings` lists
    /// them with their values); the flags given change it.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Change one setting, KEY=VALUE (repeatable; after --config, before the other flags),
    /// e.g. --set verify_cell=0.25.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Built-in rotation set: hopf15-id, limited15, full15, limited10, hopf15, hopf15-dedup,
    /// ico162-s10; or a .npy file of shape [N, 3, 3].
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
    /// How the verification scores a pose: tight (each point within D counts by 1 − d²/D²,
    /// so an exact small overlap beats a loose large one), fitness (the share of points within
    /// D) or oriented (tight, counting only points whose normals, turned away from their
    /// cloud's centroid, face the same way: single views of convex objects).
    #[arg(long, value_name = "SCORE")]
    pub verify_score: Option<String>,
    /// Take the coarse winner without verification.
    #[arg(long)]
    pub no_verify: bool,
    /// Always run the whole search. Otherwise the coarse-to-fine search first verifies the
    /// hypotheses of the coarse level's best rotations and stops there when one pose scores
    /// well and no distinct pose nearly as well (docs/pipeline.md, "The first look").
    #[arg(long)]
    pub no_first_look: bool,
    /// Polish each hypothesis on a finer rotation grid (7 rotations a step, scored by the
    /// correlation) before its ICP.
    #[arg(long)]
    pub polish: bool,
    /// Refinement after the grid search: gicp, p2plane, p2p or none.
    #[arg(long)]
    pub refine: Option<String>,
    /// Final refinement on both clouds thinned to one point per cell of this many voxels (0:
    /// full resolution); it stops at steps below refine_min_step (--set).
    #[arg(long, value_name = "VOXELS")]
    pub refine_cell: Option<f64>,
    #[command(flatten)]
    pub refine_options: RefineOptions,
}

/// How the rotations are searched (shared by `register` and `bench`).
#[derive(Args, Clone)]
pub struct SearchArgs {
    /// exhaustive: every rotation at the voxel size (GGS); coarse-to-fine: every rotation at
    /// --coarse-factor × voxel, then the best --coarse-keep of them and their grid neighbours
    /// at the voxel size.
    #[arg(long, value_name = "MODE")]
    pub search: Option<String>,
    /// Correlation arithmetic: mixed (f32 with proven error bounds, exact re-scoring of every
    /// rotation whose bound reaches the best: same picks as f64) or f64.
    #[arg(long)]
    pub precision: Option<String>,
    /// Coarse voxel = this × voxel (coarse-to-fine).
    #[arg(long, value_name = "F")]
    pub coarse_factor: Option<f64>,
    /// Fraction of the rotations kept from the coarse level (coarse-to-fine).
    #[arg(long, value_name = "FRAC")]
    pub coarse_keep: Option<f64>,
    /// Keep at least this many rotations from the coarse level (coarse-to-fine).
    #[arg(long, value_name = "N")]
    pub coarse_keep_min: Option<usize>,
    /// Verify also the N best distinct hypotheses of the coarse level, each with its own
    /// translation at the coarse voxel (coarse-to-fine; they find the right pose of
    /// low-overlap pairs that the voxel size ranks too low).
    #[arg(long, value_name = "N")]
    pub coarse_hypotheses: Option<usize>,
}

/// The final refinement's options (shared by `register`, `bench` and `refine`).
#[derive(Args, Clone)]
pub struct RefineOptions {
    /// Fixed correspondence distance in cloud units (otherwise the --distance-quantile
    /// quantile of the source-to-target nearest-neighbour distances at the start).
    #[arg(long, value_name = "D")]
    pub max_distance: Option<f64>,
    /// Quantile of the nearest-neighbour distances taken as correspondence distance.
    #[arg(long, value_name = "Q")]
    pub distance_quantile: Option<f64>,
    /// Robust kernel: none, huber:K, cauchy:K, geman-mcclure:K (K in cloud units).
    #[arg(long)]
    pub kernel: Option<String>,
    /// Iteration cap of the final refinement.
    #[arg(long)]
    pub max_iterations: Option<usize>,
    /// Neighbours for normals and covariances.
    #[arg(long)]
    pub neighbors: Option<usize>,
}

/// `key` set to `value` when its flag (`--key`, dashed) was given; errors name the flag.
pub fn put<T: Into<Value> + Clone>(changes: &mut Changes, key: &str, value: &Option<T>) {
    if let Some(v) = value {
        changes.set_from(format!("--{}", key.replace('_', "-")), key, v.clone());
    }
}

/// `key` set to `value` when the switch `flag` was given.
fn switch(changes: &mut Changes, flag: &str, given: bool, key: &str, value: bool) {
    if given {
        changes.set_from(flag, key, value);
    }
}

impl RefineOptions {
    /// The refinement flags given, as changes.
    pub fn put_changes(&self, c: &mut Changes) {
        put(c, "max_distance", &self.max_distance);
        put(c, "distance_quantile", &self.distance_quantile);
        put(c, "kernel", &self.kernel);
        put(c, "max_iterations", &self.max_iterations);
        put(c, "neighbors", &self.neighbors);
    }
}

impl PipelineArgs {
    /// The pipeline flags given, as changes.
    fn flag_changes(&self) -> Changes {
        let mut c = Changes::new("command line");
        put(&mut c, "rotations", &self.rotations);
        let s = &self.search;
        put(&mut c, "search", &s.search);
        put(&mut c, "precision", &s.precision);
        put(&mut c, "coarse_factor", &s.coarse_factor);
        put(&mut c, "coarse_keep", &s.coarse_keep);
        put(&mut c, "coarse_keep_min", &s.coarse_keep_min);
        put(&mut c, "coarse_hypotheses", &s.coarse_hypotheses);
        switch(
            &mut c,
            "--no-first-look",
            self.no_first_look,
            "first_look",
            false,
        );
        switch(&mut c, "--no-verify", self.no_verify, "verify", false);
        put(&mut c, "max_hypotheses", &self.max_hypotheses);
        put(&mut c, "margin", &self.margin);
        put(&mut c, "verify_score", &self.verify_score);
        switch(&mut c, "--polish", self.polish, "polish", true);
        put(&mut c, "refine", &self.refine);
        put(&mut c, "refine_cell", &self.refine_cell);
        self.refine_options.put_changes(&mut c);
        c
    }

    /// The settings: the preset (--preset, else the file's, else default), changed by the
    /// settings file, then by --set, then by the flags (`extra`: the command's own).
    pub fn settings(&self, extra: impl FnOnce(&mut Changes)) -> Result<(Preset, Settings)> {
        let file = match &self.config {
            Some(path) => Some(SettingsFile::read(path)?),
            None => None,
        };
        let preset: Preset = match (&self.preset, &file) {
            (Some(name), _) => name.parse().context("--preset")?,
            (None, Some(f)) => f.preset.unwrap_or(Preset::Default),
            (None, None) => Preset::Default,
        };
        let mut assignments = Changes::new("--set");
        for a in &self.set {
            assignments.set_assignment(a)?;
        }
        let mut flags = self.flag_changes();
        extra(&mut flags);
        let mut layers: Vec<Changes> = file.map(|f| f.changes).into_iter().collect();
        layers.extend([assignments, flags]);
        Ok((preset, Settings::layered(preset, &layers)?))
    }
}

/// The CLI with the help of each settings flag of `register`, `align`, `bench` and
/// `settings` ending in the presets' values, read from [`Settings::preset`]: the help cannot
/// state a value the code does not use.
pub fn with_preset_values(cli: clap::Command) -> clap::Command {
    let default = Settings::preset(Preset::Default).to_json();
    let paper = Settings::preset(Preset::Paper).to_json();
    let show = |v: &Value| match v {
        Value::Null => "unset".to_string(),
        Value::String(s) => s.clone(),
        other => other.to_string(),
    };
    let annotate = |mut command: clap::Command| {
        let ids: Vec<String> = command
            .get_arguments()
            .map(|a| a.get_id().to_string())
            .collect();
        for id in &ids {
            let renamed = RENAMED_FLAGS.iter().find(|(from, _)| from == id);
            let key = renamed.map_or(id.as_str(), |(_, key)| key);
            if default.get(key).is_none() {
                continue;
            }
            let (d, p) = (show(&default[key]), show(&paper[key]));
            let values = if d == p {
                format!("[setting {key}: {d}]")
            } else {
                format!("[setting {key}: {d}; --preset paper: {p}]")
            };
            command = command.mut_arg(id, |a| {
                let help = a.get_help().map(|h| h.to_string()).unwrap_or_default();
                a.help(format!("{help} {values}"))
            });
        }
        command
    };
    cli.mut_subcommand("register", annotate)
        .mut_subcommand("align", annotate)
        .mut_subcommand("bench", annotate)
        .mut_subcommand("settings", annotate)
}
