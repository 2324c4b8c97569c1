//! `etp-coordinator`: runs the episodes of a strategy over the agent and the
//! sensor processes.
//!
//! A short tour:
//!
//! * [`Args`] — run id, scenario, `strategy.json`, episodes, seed.
//! * [`run`] — loads the scenario and the strategy (refusing a strategy made
//!   for another scenario: `Strategy::check_scenario`), waits for `hello`
//!   from the agent and every sensor, runs the episodes and returns the
//!   [`RunReport`].
//! * [`Coordinator`](session::Coordinator) — per episode: `control` start;
//!   on each `waypoint` it classifies the agent's covariance into the
//!   strategy's region and draws δ from ω (`Strategy::draw`, uniform numbers
//!   from `streams::COORDINATOR`), closes the previous leg at its sensor and
//!   opens the new one (`threshold`); on `outcome` it records the episode. The
//!   sensors' `ledger`s are joined to the agent's received counts per leg.

mod core;
mod session;

pub use etp_runtime::wire::report::RunReport;

use etp_runtime::wire::{self, RunId, WireError};
use etp_shared::strategy::Strategy;
use std::time::Duration;

/// Why the coordinator failed.
#[derive(Debug, thiserror::Error)]
pub enum CoordinatorError {
    #[error(transparent)]
    Wire(#[from] WireError),
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Port(#[from] etp_runtime::wire::PortError),
    #[error("processes not ready after {0:?}: missing {1}")]
    Startup(Duration, String),
    #[error("protocol error: {0}")]
    Protocol(String),
    #[error("the agent died during episode {0}")]
    AgentDied(u64),
}

/// The coordinator of an etpareto run (spawned by `etp run`).
#[derive(Debug, Clone, clap::Parser)]
#[command(name = "etp-coordinator", version, about)]
pub struct Args {
    /// Run id (services live under `etp/<run-id>/`).
    #[arg(long)]
    pub run_id: String,
    /// Built-in scenario name or TOML path (must match the strategy's hash).
    #[arg(long)]
    pub scenario: String,
    /// Path of `strategy.json`.
    #[arg(long)]
    pub strategy: String,
    /// Number of episodes.
    #[arg(long, default_value_t = 100)]
    pub episodes: u64,
    /// Run seed (agent, sensor and coordinator streams derive from it).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Seconds to wait for every process's hello.
    #[arg(long, default_value_t = 30.0)]
    pub startup_timeout: f64,
    /// Keep the number of finished episodes in FILE (rewritten at most every
    /// 100 ms and at the end; `etp run` draws its progress from it).
    #[arg(long, value_name = "FILE")]
    pub progress: Option<std::path::PathBuf>,
}

/// Run all episodes and return the report.
pub fn run(args: &Args) -> Result<RunReport, CoordinatorError> {
    let run = RunId::new(&args.run_id)?;
    let scenario = wire::load_scenario(&args.scenario).map_err(CoordinatorError::Input)?;
    let text = std::fs::read_to_string(&args.strategy)
        .map_err(|e| CoordinatorError::Input(format!("reading strategy {}: {e}", args.strategy)))?;
    let strategy = Strategy::from_json(&text)
        .map_err(|e| CoordinatorError::Input(format!("{}: {e}", args.strategy)))?;
    strategy
        .check_scenario(&scenario)
        .map_err(|e| CoordinatorError::Input(e.to_string()))?;
    let startup = Duration::from_secs_f64(args.startup_timeout.max(0.1));
    let mut c = session::Coordinator::new(&run, &scenario, &strategy, args.seed)?;
    if let Some(p) = &args.progress {
        c.report_progress_to(p.clone());
    }
    c.wait_ready(startup)?;
    c.run_episodes(args.episodes)
}

use anyhow::Context;

/// The process entry point (`main` of the binary, and `etp process <name>`
/// when the binary is not installed beside `etp`): parse `args` (the first
/// is the program name) and run.
pub fn main_with<I, T>(args: I) -> std::process::ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    use clap::Parser;
    use std::process::ExitCode;
    // Prints help or the usage error and exits (0 or 2), as `main` would.
    let args = Args::parse_from(args);
    etp_runtime::wire::init_process_logging("etp-coordinator");
    let _span = tracing::info_span!("coordinator").entered();
    let result = crate::run(&args)
        .context("coordinator")
        .and_then(|r| serde_json::to_string(&r).context("encoding the report"));
    match result {
        Ok(json) => {
            // The supervisor reads the report; if it is gone (its end of the
            // pipe closed), there is no one to tell: exit quietly, no panic.
            use std::io::Write;
            let mut out = std::io::stdout().lock();
            if writeln!(out, "{json}").and_then(|()| out.flush()).is_err() {
                tracing::warn!("report not delivered: stdout closed");
                return ExitCode::FAILURE;
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("etp-coordinator: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
