//! `etp-agent`: the simulated plant, the ET Kalman filter and the controller,
//! as one process of a run.
//!
//! A short tour:
//!
//! * [`Args`] — run id, scenario, seed (what `etp run` passes).
//! * [`run`] — opens the agent's ports (`etp_runtime::wire`), says hello and
//!   runs episodes when `control` says start, until stop.
//! * [`core::EpisodeCore`] — the agent's decisions in an episode, pure (no
//!   ports, unit-tested): the true state (plant noise from `streams::AGENT`),
//!   each step through `etp_shared::episode::AgentCore` (input, move,
//!   collision, prior, slot update, leg end — the one step the in-process
//!   simulation, `replay verify` and the sensor's replica run), the
//!   replica's prior digest check, dead slots, the counts and the outcome.
//! * [`runtime::Agent`] — the adapter: at each decision point it publishes
//!   `waypoint`, waits for the coordinator's `threshold`, hands its belief
//!   over to the leg's sensor (`handover`, once per leg) and serves each
//!   slot the core asks for over IPC.
//! * the channel monitor (`etp_shared::drift::Monitor`) — fed every closed
//!   slot's attempts and delivery at the slot's δ; each flag it raises is
//!   published as a `drift` message to the coordinator (docs/MODEL.md §11).
//! * [`link`] — the ports of a slot: publish `truth`, wake the serving
//!   sensor, take its `slot` (and `measurement`); the slot's prior digest
//!   must equal the agent's prior (the sensor's replica is exact). A sensor that is
//!   dead (iceoryx2 node list) — or, only with `--slot-deadline`, late — is a
//!   *dead link*: the agent does prediction only, never the implicit update,
//!   and marks the episode degraded. A live sensor is waited for, however
//!   slow or paused.
//!
//! # One runtime step (lockstep)
//!
//! At a decision point: agent `waypoint` → coordinator `threshold` (OPEN δ at the
//! leg's sensor, CLOSE the previous leg → its `ledger`) → agent `handover` of its
//! belief to the leg's sensor (radio, once per leg; docs/MODEL.md §3.2).
//!
//! Each step: agent: `u = sat(K(C⁺w − x̂))`, move the plant, collision check →
//! publish `truth` → serving sensor: its replica computes the prior (the agent's
//! own step functions), measure, whiten, trigger; if it triggers, its radio
//! draws each attempt's fate from the link's own stream
//! (`LinkChannel::of_episode(radio, seed, AGENT, episode, sensor)`; every attempt costed, retries within the step; an ideal
//! link draws nothing and delivers), and it publishes `measurement` only for a
//! delivered attempt; then `slot` with the attempts, `delivered` and the prior's
//! digest → agent: the digest must equal its prior's; explicit update if a
//! measurement arrived (and its `ack` to the sensor, which checks it against
//! its deliveries), implicit update with `CompiledScenario::silence_beta`
//! (β(δ), or β_q(δ) on a lossy link) on a closed slot from a live sensor,
//! prediction only on a dead link (never "silence = small innovation").

pub mod core;
pub mod link;
pub mod runtime;

use etp_runtime::shell::{self, Done};
use etp_runtime::wire::{RunId, WireError};
use std::time::Duration;

/// Silence on a slot after which the agent asks the node list whether the
/// serving sensor still lives (so a kill -9 is seen within ~this + the list).
pub const SLOT_CHECK: Duration = Duration::from_millis(10);
/// How often an agent waiting on the coordinator checks that it lives.
pub const IDLE_CHECK: Duration = Duration::from_millis(250);

/// Why the agent stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum AgentError {
    #[error(transparent)]
    Wire(#[from] WireError),
    #[error(transparent)]
    Scenario(#[from] etp_runtime::scenario_arg::ScenarioArgError),
    #[error(transparent)]
    Port(#[from] etp_runtime::wire::PortError),
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
    /// Real-time studies: a slot not closed within MS milliseconds is a dead
    /// link even if the sensor process lives (reported as a fault). Default:
    /// a live sensor is waited for, however slow.
    #[arg(long, value_name = "MS")]
    pub slot_deadline: Option<u64>,
    /// `etp run --live`: the live view's feed socket (a Unix datagram socket
    /// in the run's folder). Frames are sent non-blocking and dropped when
    /// the view has no room: the run is the same with and without it.
    #[arg(long, value_name = "SOCKET", hide = true)]
    pub live_feed: Option<std::path::PathBuf>,
    /// Episodes of the run: the channel monitor's horizon (its threshold
    /// grows with the log of the observations it may see).
    #[arg(long, default_value_t = 100)]
    pub episodes: u64,
    /// The channel monitor's false-alarm probability for the whole run
    /// (docs/MODEL.md §11).
    #[arg(long, default_value_t = etp_shared::drift::DEFAULT_FALSE_ALARM)]
    pub drift_false_alarm: f64,
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
    /// Beliefs handed over to a serving sensor (one per leg with a live sensor).
    pub handovers: u64,
    /// Time spent inside episodes (for the steps/s figure), seconds.
    pub busy_seconds: f64,
}

/// Run the agent until the coordinator says stop.
pub fn run(args: &Args) -> Result<(Exit, AgentStats), AgentError> {
    let run = RunId::new(&args.run_id)?;
    let scenario = etp_runtime::load_scenario(&args.scenario)?;
    let deadline = args.slot_deadline.map(Duration::from_millis);
    // A view that cannot be reached is no reason to stop the run.
    let live = args.live_feed.as_deref().and_then(|p| {
        etp_runtime::live::LiveTap::connect(p, scenario.sensors.len())
            .map_err(|e| tracing::warn!("live view feed {}: {e}; running without it", p.display()))
            .ok()
    });
    let monitor = etp_shared::drift::Monitor::new(
        &scenario,
        etp_shared::drift::MonitorConfig {
            false_alarm: args.drift_false_alarm,
            episodes: args.episodes,
        },
    );
    etp_shared::with_dim!(scenario.dim, N => runtime::Agent::<N>::new(&run, &scenario, deadline, live, monitor)?.serve())
}

/// The agent process, as the process shell runs it
/// (`shell::main_with::<AgentProcess>`: `main` of the binary, and `etp
/// process etp-agent` when the binary is not installed beside `etp`).
pub struct AgentProcess;

impl shell::Process for AgentProcess {
    const NAME: &'static str = "etp-agent";
    type Args = Args;
    fn parse(argv: Vec<std::ffi::OsString>) -> Self::Args {
        clap::Parser::parse_from(argv)
    }
    type Error = anyhow::Error;
    fn body(args: &Args) -> anyhow::Result<Done> {
        let _span = tracing::info_span!("agent").entered();
        let (exit, stats) = run(args)?;
        tracing::info!(?exit, ?stats, "agent done");
        Ok(Done::Quiet)
    }
}
