//! `etp run`: the multi-process run of a strategy.
//!
//! Spawns `etp-coordinator`, `etp-agent` and one `etp-sensor-node` per sensor
//! (binaries found next to the running `etp`), supervises them with tokio
//! (exit codes, ctrl-c, a deadline), cleans the run's iceoryx2 files and
//! prints the report: outcomes with 95 % intervals beside the strategy's
//! prediction, and per sensor its ledger (transmitted), what the agent
//! received, and its predicted energy.
//!
//! * [`prepare`] — strategy and scenario (a strategy file, or `--scenario
//!   NAME --delta D` for a constant-δ strategy made on the fly), the run
//!   folder, `--clone-sensors K` for the scaling benchmark.
//! * [`supervise`] — spawning and supervising the processes.
//! * [`report`] — the table and the `--json` object.

mod prepare;
mod record;
mod report;
mod supervise;

use anyhow::{Context, Result, bail};
use etp_shared::wire::{RunId, cleanup};
use std::path::PathBuf;
use std::time::Duration;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// A strategy.json (from `etp strategy`). Omit it and give `--scenario` and
    /// `--delta` to run a constant threshold.
    pub strategy: Option<PathBuf>,
    /// Scenario (built-in name or TOML path) for a constant-δ run.
    #[arg(long)]
    pub scenario: Option<String>,
    /// The constant threshold δ (one of the scenario's Δ) for a constant-δ run.
    #[arg(long, requires = "scenario")]
    pub delta: Option<f64>,
    /// Number of episodes.
    #[arg(long, default_value_t = 100)]
    pub episodes: u64,
    /// Seed: the same seed gives the same episodes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Kill everything and fail after this many seconds.
    #[arg(long, default_value_t = 3600.0)]
    pub deadline: f64,
    /// Run id (default: generated). Names the services `etp/<run-id>/…`.
    #[arg(long)]
    pub run_id: Option<String>,
    /// Include every episode (legs, ledgers, received counts) in the JSON.
    #[arg(long)]
    pub episode_details: bool,
    /// In-process episodes used to predict each sensor's energy.
    #[arg(long, default_value_t = 2000)]
    pub predict_episodes: u64,
    /// Benchmark: replace the sensors by K copies of the first one, legs
    /// served round robin (same maths, K sensor processes).
    #[arg(long)]
    pub clone_sensors: Option<usize>,
    /// Record every message of the run to this MCAP file (see `etp replay`).
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Record to the default file `recordings/<scenario>-<run-id>.mcap`.
    #[arg(long, conflicts_with = "record")]
    pub record_default: bool,
    /// Overwrite the `--record` file if it exists.
    #[arg(long)]
    pub force: bool,
}

/// Spawn, supervise and clean up one run; the report data.
fn execute_run(a: &Args) -> Result<(prepare::Plan, supervise::Supervised)> {
    if a.episodes == 0 {
        bail!("--episodes must be at least 1");
    }
    if !(a.deadline.is_finite() && a.deadline > 0.0) {
        bail!("--deadline must be a positive number of seconds");
    }
    if let Some(p) = &a.record {
        record::claim(p, a.force)?;
    }
    let run_id = match &a.run_id {
        Some(id) => RunId::new(id)?,
        None => RunId::generate(),
    };
    let stale = cleanup::remove_stale_runs();
    if !stale.is_empty() {
        tracing::info!(?stale, "removed stale iceoryx2 runs");
    }
    let plan = prepare::prepare(a, &run_id)?;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let record = match (&a.record, a.record_default) {
        (Some(p), _) => Some(p.clone()),
        (None, true) => Some(record::default_path(&plan)),
        (None, false) => None,
    };
    let outcome = rt.block_on(supervise::supervise(
        &plan,
        Duration::from_secs_f64(a.deadline),
        record.as_deref(),
    ));
    // Whatever happened: no iceoryx2 leftovers of this run.
    let cleaned = cleanup::remove_run(&run_id);
    let _ = std::fs::remove_dir_all(&plan.dir);
    let outcome = outcome?;
    if !cleaned {
        tracing::warn!("run {run_id}: some iceoryx2 node still alive at the end; files left");
    }
    Ok((plan, outcome))
}

/// Run and return the `--json` report object (used by `etp demo`).
pub fn execute(a: &Args) -> Result<serde_json::Value> {
    let (plan, outcome) = execute_run(a)?;
    Ok(report::json(a, &plan, &outcome))
}

pub fn run(a: Args) -> Result<()> {
    let (plan, outcome) = execute_run(&a)?;
    report::print(&a, &plan, &outcome)
}
