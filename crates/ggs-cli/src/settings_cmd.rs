//! `ggs settings`: print the settings a run would use, as a settings file to start from.

use crate::pipeline_args::PipelineArgs;
use anyhow::Result;
use clap::Args;

#[derive(Args)]
pub struct SettingsArgs {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Print JSON (unset optional settings as null) instead of TOML (where they are left
    /// out).
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: SettingsArgs) -> Result<()> {
    let (preset, settings) = args.pipeline.settings(|_| {})?;
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&settings.to_json())?);
    } else {
        outln!("# ggs settings: the {} preset and the changes given; every key is documented in docs/settings.md", preset.name());
        outln!("preset = \"{}\"", preset.name());
        outln!("{}", settings.to_toml().trim_end());
    }
    Ok(())
}
