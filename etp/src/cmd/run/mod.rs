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
mod rundir;
mod supervise;

use anyhow::{Context, Result, bail};
use etp_shared::wire::{RunId, cleanup};
use std::path::PathBuf;
use std::time::Duration;

/// Exit code: the run completed but a count disagrees (a sensor's ledger ≠
/// what the agent received), a ledger is missing, or the requested
/// recording did not finish. Never 0.
pub const EXIT_ACCOUNTING: u8 = 4;
/// Exit code: an episode ran with a dead link (degraded), without
/// `--allow-degraded`.
pub const EXIT_DEGRADED: u8 = 5;
/// Exit code: SIGINT or SIGTERM stopped the run; the report covers the
/// complete episodes.
pub const EXIT_INTERRUPTED: u8 = 130;

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
    /// Exit 0 even if some episodes ran with a dead link (a sensor died):
    /// for fault-injection studies. Counts must still agree.
    #[arg(long)]
    pub allow_degraded: bool,
    /// Real-time studies: a slot not closed within MS milliseconds counts as
    /// a dead link (a fault) even if the sensor process lives. Default: a
    /// live process is waited for, however slow or paused.
    #[arg(long, value_name = "MS")]
    pub slot_deadline: Option<u64>,
}

/// Why a completed run is not clean (empty: exit 0).
pub fn verdict(
    report: &etp_shared::wire::report::RunReport,
    recording_ok: bool,
    allow_degraded: bool,
) -> Vec<(u8, String)> {
    let mut v = Vec::new();
    for s in &report.sensors {
        if s.transmitted != s.received || s.missing_ledgers > 0 {
            v.push((
                EXIT_ACCOUNTING,
                format!(
                    "sensor {}: ledger {} transmitted ≠ agent {} received ({} ledgers missing)",
                    s.name, s.transmitted, s.received, s.missing_ledgers
                ),
            ));
        }
    }
    if !recording_ok {
        v.push((EXIT_ACCOUNTING, "the recording did not finish".into()));
    }
    if report.degraded > 0 && !allow_degraded {
        v.push((
            EXIT_DEGRADED,
            format!(
                "{} episode(s) degraded by a dead link (accept with --allow-degraded)",
                report.degraded
            ),
        ));
    }
    v
}

/// Spawn, supervise and clean up one run; the report data.
fn execute_run(a: &Args) -> Result<(prepare::Plan, supervise::Supervised)> {
    if a.episodes == 0 {
        bail!("--episodes must be at least 1");
    }
    if !(a.deadline.is_finite() && a.deadline > 0.0) {
        bail!("--deadline must be a positive number of seconds");
    }
    if a.slot_deadline == Some(0) {
        bail!("--slot-deadline must be at least 1 ms");
    }
    if let Some(p) = &a.record {
        crate::output::refuse_existing(p, a.force)?;
    }
    let run_id = match &a.run_id {
        Some(id) => RunId::new(id)?,
        None => RunId::generate(),
    };
    let stale_dirs = rundir::remove_stale();
    let stale = cleanup::remove_stale_runs();
    if !stale.is_empty() || !stale_dirs.is_empty() {
        tracing::info!(?stale, ?stale_dirs, "removed what dead runs left");
    }
    let dir = rundir::RunDir::claim(&run_id)?;
    let plan = match prepare::prepare(a, &run_id, &dir.path) {
        Ok(p) => p,
        Err(e) => {
            dir.remove();
            return Err(e);
        }
    };
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
        a.slot_deadline,
    ));
    // Whatever happened: no iceoryx2 leftovers of this run.
    let cleaned = cleanup::remove_run(&run_id);
    dir.remove();
    let outcome = outcome?;
    if !cleaned {
        tracing::warn!("run {run_id}: some iceoryx2 node still alive at the end; files left");
    }
    Ok((plan, outcome))
}

/// What is wrong with a finished run, most important first (empty: clean).
fn problems(a: &Args, outcome: &supervise::Supervised) -> Vec<(u8, String)> {
    let recording_ok = outcome.recording.as_ref().is_none_or(|r| r.finished);
    let mut problems = verdict(&outcome.report, recording_ok, a.allow_degraded);
    if outcome.interrupted {
        problems.insert(
            0,
            (
                EXIT_INTERRUPTED,
                format!(
                    "interrupted: the report covers the {} complete episode(s)",
                    outcome.report.episodes
                ),
            ),
        );
    }
    problems
}

/// `Ok` for a clean run, else the exit code of the first problem with all
/// of them as the message.
pub fn exit_for(problems: &[(u8, String)]) -> Result<()> {
    match problems.first() {
        None => Ok(()),
        Some(&(code, _)) => Err(crate::ExitWith {
            code,
            message: problems
                .iter()
                .map(|(_, why)| format!("etp run: {why}"))
                .collect::<Vec<_>>()
                .join("\n"),
        }
        .into()),
    }
}

/// A run's `--json` report object (used by `etp demo`) and its problems
/// (pass them to [`exit_for`] once the report is shown).
pub fn execute(a: &Args) -> Result<(serde_json::Value, Vec<(u8, String)>)> {
    let (plan, outcome) = execute_run(a)?;
    let problems = problems(a, &outcome);
    let mut v = report::json(a, &plan, &outcome);
    if let Some(m) = v.as_object_mut() {
        m.insert(
            "problems".into(),
            problems.iter().map(|(_, w)| w.clone()).collect(),
        );
    }
    Ok((v, problems))
}

/// Run, print the report; the exit code is 0 only for a clean run, else
/// [`EXIT_INTERRUPTED`], [`EXIT_ACCOUNTING`] or [`EXIT_DEGRADED`] (the
/// report and stderr say why).
pub fn run(a: Args) -> Result<()> {
    let (plan, outcome) = execute_run(&a)?;
    report::print(&a, &plan, &outcome)?;
    exit_for(&problems(&a, &outcome))
}
