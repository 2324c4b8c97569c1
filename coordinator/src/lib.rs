//! `etp-coordinator`: runs the episodes of a strategy over the agent and the
//! sensor processes.
//!
//! A short tour:
//!
//! * [`Args`] — run id, scenario, `strategy.json`, episodes, seed.
//! * [`run`] — loads the scenario and the strategy (refusing a strategy made
//!   for another scenario: `Policy::check_scenario`), waits for `hello`
//!   from the agent and every sensor, runs the episodes and returns the
//!   [`RunReport`], which names the strategy and its prediction.
//! * [`core::CoordinatorCore`] — the decisions, pure (no ports,
//!   unit-tested), given the strategy's policy only: on each `waypoint` it
//!   classifies the agent's covariance into the policy's region and draws δ
//!   from ω (`Policy::draw`,
//!   uniform numbers from `streams::COORDINATOR`), closing the previous leg
//!   and opening the new one at its sensor; on `outcome` it records the
//!   episode; the sensors' `ledger`s are joined to the agent's received
//!   counts per leg in the report.
//! * [`Coordinator`](session::Coordinator) — the adapter: `control` start
//!   per episode, the `threshold` messages the core decides, the waits and
//!   the liveness checks.

pub mod core;
mod session;

pub use etp_runtime::report::RunReport;

use etp_runtime::shell::{self, Done};
use etp_runtime::wire::{RunId, WireError};
use etp_shared::drift::OnDrift;
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
    Scenario(#[from] etp_runtime::scenario_arg::ScenarioArgError),
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
    /// Built-in scenario name or TOML path (checked against the strategy's hash).
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
    /// What a flag of the agent's channel monitor does: `warn` (reported)
    /// or `stop` (the run ends after the flag's episode).
    #[arg(long, value_parser = on_drift, default_value = "warn")]
    pub on_drift: OnDrift,
}

/// `--on-drift WORD` (docs/MODEL.md §11).
fn on_drift(word: &str) -> Result<OnDrift, String> {
    OnDrift::parse(word).ok_or_else(|| {
        let words: Vec<&str> = OnDrift::ALL.iter().map(|o| o.name()).collect();
        format!("`{word}`: one of {}", words.join(", "))
    })
}

/// Run all episodes and return the report.
pub fn run(args: &Args) -> Result<RunReport, CoordinatorError> {
    let run = RunId::new(&args.run_id)?;
    let scenario = etp_runtime::load_scenario(&args.scenario)?;
    let text = std::fs::read_to_string(&args.strategy)
        .map_err(|e| CoordinatorError::Input(format!("reading strategy {}: {e}", args.strategy)))?;
    let strategy = Strategy::from_sealed_json(&text)
        .map_err(|e| CoordinatorError::Input(format!("{}: {e}", args.strategy)))?;
    strategy
        .policy
        .check_scenario(&scenario)
        .map_err(|e| CoordinatorError::Input(e.to_string()))?;
    let startup = Duration::from_secs_f64(args.startup_timeout.max(0.1));
    let mut c = session::Coordinator::new(&run, &scenario, &strategy.policy, args.seed)?;
    c.on_drift(args.on_drift);
    if let Some(p) = &args.progress {
        c.report_progress_to(p.clone());
    }
    c.wait_ready(startup)?;
    let mut report = c.run_episodes(args.episodes)?;
    // The episodes ran the policy alone; the report names the strategy and
    // what it predicted, to be compared with what the run measured.
    report.strategy_label = strategy.provenance.label;
    report.predicted = strategy.predictions.predicted;
    report.predicted_ci95 = strategy.predictions.predicted_ci95;
    Ok(report)
}

use anyhow::Context;

/// The coordinator process, as the process shell runs it (`main` of the
/// binary, and `etp process etp-coordinator`); the report is its one line
/// on stdout (an undelivered report fails the process).
pub struct CoordinatorProcess;

impl shell::Process for CoordinatorProcess {
    const NAME: &'static str = "etp-coordinator";
    type Args = Args;
    fn parse(argv: Vec<std::ffi::OsString>) -> Self::Args {
        clap::Parser::parse_from(argv)
    }
    type Error = anyhow::Error;
    fn body(args: &Args) -> anyhow::Result<Done> {
        let _span = tracing::info_span!("coordinator").entered();
        let report = run(args).context("coordinator")?;
        let text = serde_json::to_string(&report).context("encoding the report")?;
        Ok(Done::Line {
            text,
            required: true,
        })
    }
}
