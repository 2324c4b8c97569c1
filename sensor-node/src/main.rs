//! `etp-sensor-node`: thin main over [`etp_sensor_node::run`].

use anyhow::Context;
use clap::Parser;
use std::process::ExitCode;

/// One sensor of an etpareto run (spawned by `etp run`).
#[derive(Debug, Parser)]
#[command(name = "etp-sensor-node", version, about)]
struct Cli {
    #[command(flatten)]
    args: etp_sensor_node::Args,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    etp_shared::wire::init_process_logging();
    match etp_sensor_node::run(&cli.args).with_context(|| format!("sensor `{}`", cli.args.sensor)) {
        Ok((exit, stats)) => {
            tracing::info!(?exit, ?stats, "sensor node done");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("etp-sensor-node: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
