//! `etp-agent`: the simulated plant, the ET Kalman filter and the controller,
//! as one process of a run.
//!
//! A short tour:
//!
//! * [`Args`] — run id, scenario, seed (what `etp run` passes).
//! * [`run`] — opens the agent's ports (`etp_shared::wire`), says hello and
//!   runs episodes when `control` says start, until stop.
//! * [`runtime::Agent`] — one episode, step by step in exactly the order of
//!   MODEL.md §3 / `etp_shared::episode` (controller, plant move from
//!   `streams::AGENT`, collision check, slot, update, leg termination); at
//!   each decision point it publishes `waypoint` and waits for `threshold`.
//! * [`link`] — one slot over IPC: publish `truth` and `prior`, wake the
//!   serving sensor, wait for its `slot` (and `measurement`). A sensor that is
//!   dead (iceoryx2 node list) or silent past [`SLOT_DEADLINE`] is a *dead
//!   link*: the agent does prediction only, never the implicit update, and
//!   marks the episode degraded.

pub mod link;
pub mod runtime;

use etp_shared::wire::{self, RunId, WireError};
use std::time::Duration;

/// Silence on a slot after which the agent asks the node list whether the
/// serving sensor still lives (so a kill -9 is seen within ~this + the list).
pub const SLOT_CHECK: Duration = Duration::from_millis(10);
/// A slot not closed after this long is a dead link even if the process lives.
pub const SLOT_DEADLINE: Duration = Duration::from_secs(2);
/// How often an agent waiting on the coordinator checks that it lives.
pub const IDLE_CHECK: Duration = Duration::from_millis(250);

/// Why the agent stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum AgentError {
    #[error(transparent)]
    Wire(#[from] WireError),
    #[error("{0}")]
    Scenario(String),
    #[error("sending on `{0}` failed: {1}")]
    Send(&'static str, String),
    #[error("receiving on `{0}` failed: {1}")]
    Receive(&'static str, String),
    #[error("protocol error: {0}")]
    Protocol(String),
}

/// The agent of an etpareto run: plant, ET-KF, controller (spawned by `etp run`).
#[derive(Debug, Clone, clap::Parser)]
#[command(name = "etp-agent", version, about)]
pub struct Args {
    /// Run id (services live under `etp/<run-id>/`).
    #[arg(long)]
    pub run_id: String,
    /// Built-in scenario name or TOML path.
    #[arg(long)]
    pub scenario: String,
}

/// How the agent ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    Stopped,
    CoordinatorGone,
    Signal,
}

/// Totals of an agent process.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AgentStats {
    pub episodes: u64,
    pub steps: u64,
    pub received: u64,
    pub dead_slots: u64,
    /// Time spent inside episodes (for the steps/s figure), seconds.
    pub busy_seconds: f64,
}

/// Run the agent until the coordinator says stop.
pub fn run(args: &Args) -> Result<(Exit, AgentStats), AgentError> {
    let run = RunId::new(&args.run_id)?;
    let scenario = wire::load_scenario(&args.scenario).map_err(AgentError::Scenario)?;
    etp_shared::with_dim!(scenario.dim, N => runtime::Agent::<N>::new(&run, &scenario)?.serve())
}

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
    etp_shared::wire::init_process_logging();
    match crate::run(&args) {
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
