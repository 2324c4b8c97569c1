//! `etp-agent`: thin main over [`etp_agent::run`].

use clap::Parser;
use std::process::ExitCode;

/// The agent of an etpareto run: plant, ET-KF, controller (spawned by `etp run`).
#[derive(Debug, Parser)]
#[command(name = "etp-agent", version, about)]
struct Cli {
    #[command(flatten)]
    args: etp_agent::Args,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    etp_shared::wire::init_process_logging();
    match etp_agent::run(&cli.args) {
        Ok((exit, stats)) => {
            tracing::info!(?exit, ?stats, "agent done");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("etp-agent: error: {e}");
            ExitCode::FAILURE
        }
    }
}
