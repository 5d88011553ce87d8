//! `ggs settings`: print the settings a run would use, as a settings file to start from.

use crate::pipeline_args::PipelineArgs;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct SettingsArgs {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Print JSON (unset optional settings as null) instead of TOML (where they are left
    /// out).
    #[arg(long)]
    pub json: bool,
    /// Write the settings to this file (atomically) instead of printing them.
    #[arg(short, long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

pub fn run(args: SettingsArgs) -> Result<()> {
    let (preset, settings) = args.pipeline.settings(|_| {})?;
    let text = if args.json {
        serde_json::to_string_pretty(&settings.to_json())? + "\n"
    } else {
        format!(
            "# ggs settings: the {0} preset and the changes given; every key is in docs/settings.md\npreset = \"{0}\"\n{1}\n",
            preset.name(),
            settings.to_toml().trim_end()
        )
    };
    match &args.out {
        Some(path) => ggs::io::write_atomic(path, text.as_bytes())?,
        None => out!("{text}"),
    }
    Ok(())
}
