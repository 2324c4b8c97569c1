//! `etp-coordinator`: thin main over [`etp_coordinator::run`]; prints the run
//! report as one JSON object on stdout.

use anyhow::Context;
use clap::Parser;
use std::process::ExitCode;

/// The coordinator of an etpareto run (spawned by `etp run`).
#[derive(Debug, Parser)]
#[command(name = "etp-coordinator", version, about)]
struct Cli {
    #[command(flatten)]
    args: etp_coordinator::Args,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    etp_shared::wire::init_process_logging();
    let result = etp_coordinator::run(&cli.args)
        .context("coordinator")
        .and_then(|r| serde_json::to_string(&r).context("encoding the report"));
    match result {
        Ok(json) => {
            println!("{json}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("etp-coordinator: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
