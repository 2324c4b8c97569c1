//! `etp scenario random --dim-agent N --seed S [-o FILE]`: a scenario of the
//! random family (`etp_shared::scenario::random`), as TOML text; `etp
//! scenario radio SCENARIO --loss P … [-o FILE]`: a scenario's text with a
//! lossy radio written into it (what `etp run` reads, docs/MODEL.md §8).

use anyhow::{Context, Result};
use etp_shared::scenario::random::{AgentKind, random_scenario};
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: ScenarioCommand,
}

#[derive(Debug, clap::Subcommand)]
pub enum ScenarioCommand {
    /// Draw a random but valid scenario (single or double integrator, 3–7
    /// sensors with rotated anisotropic noise, gates and walls the route must
    /// thread); the same seed gives the same text.
    Random(RandomArgs),
    /// A scenario's TOML text with the radio options written into it as a
    /// `[radio]` table (docs/MODEL.md §8): a file `etp run`, `synthesize`
    /// and every other command read with its channel.
    Radio(RadioTextArgs),
}

#[derive(Debug, clap::Args)]
pub struct RadioTextArgs {
    /// A built-in scenario name or a TOML file without a `[radio]` of its own.
    pub scenario: String,
    #[command(flatten)]
    pub radio: crate::scenario_flags::RadioArgs,
    /// Write the TOML here (refused if it exists, unless --force; its folder
    /// must exist) instead of stdout.
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

#[derive(Debug, clap::Args)]
pub struct RandomArgs {
    /// State dimension: 2, 3 (single integrator in the plane, in space), 4, 6
    /// (double integrator in the plane, in space).
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(["2", "3", "4", "6"]))]
    pub dim_agent: String,
    /// Seed of the draw.
    #[arg(long)]
    pub seed: u64,
    /// Write the TOML here (refused if it exists, unless --force; its folder
    /// must exist) instead of stdout.
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: Args) -> Result<()> {
    let r = match a.command {
        ScenarioCommand::Random(r) => r,
        ScenarioCommand::Radio(r) => return radio(r),
    };
    if let Some(path) = &r.out {
        etp_files::write::existing_folder_of(path, "-o")?;
    }
    let n: usize = r.dim_agent.parse().context("--dim-agent")?;
    let kind = AgentKind::from_dim(n).context("--dim-agent")?;
    let (text, s) = random_scenario(kind, r.seed)
        .context("the generated scenario failed validation (a bug in the generator)")?;
    match &r.out {
        None => print!("{text}"),
        Some(path) => {
            etp_files::write::write_new(path, text.as_bytes(), r.force)?;
            eprintln!(
                "wrote {} ({}: n = {}, {} legs, {} sensors, {} obstacles)",
                path.display(),
                s.name,
                s.dim,
                s.num_legs(),
                s.sensors.len(),
                s.obstacles.len()
            );
        }
    }
    Ok(())
}

fn radio(r: RadioTextArgs) -> Result<()> {
    if r.radio.to_override().is_empty() {
        anyhow::bail!(
            "give the channel: --loss P [--retries R] [--burst B] [--estimator aware|naive]"
        );
    }
    if let Some(path) = &r.out {
        etp_files::write::existing_folder_of(path, "-o")?;
    }
    let text = etp_runtime::scenario_arg::scenario_text(&r.scenario)?;
    let out = crate::input::text_with_radio(&text, &r.radio)?;
    match &r.out {
        None => print!("{out}"),
        Some(path) => {
            etp_files::write::write_new(path, out.as_bytes(), r.force)?;
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(())
}
