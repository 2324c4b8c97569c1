//! `etp scenario random --dim-agent N --seed S [-o FILE]`: a scenario of the
//! random family (`etp_shared::scenario::random`), as TOML text.

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
    /// Write the TOML here (refused if it exists, unless --force) instead of stdout.
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: Args) -> Result<()> {
    let ScenarioCommand::Random(r) = a.command;
    let n: usize = r.dim_agent.parse().context("--dim-agent")?;
    let kind = AgentKind::from_dim(n).context("--dim-agent")?;
    let (text, s) = random_scenario(kind, r.seed)
        .context("the generated scenario failed validation (a bug in the generator)")?;
    match &r.out {
        None => print!("{text}"),
        Some(path) => {
            crate::output::write_new(path, text.as_bytes(), r.force)?;
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
