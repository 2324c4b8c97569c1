//! `etp-sensor-node`: one process per sensor of the scenario.
//!
//! A short tour:
//!
//! * [`Args`] — what the supervisor (`etp run`) passes: run id, scenario,
//!   sensor name, seed.
//! * [`run`] — opens the sensor's ports (see `etp_runtime::wire`), says hello
//!   to the coordinator and serves until `threshold` says stop or the
//!   coordinator dies.
//! * [`SensorCore`](core::SensorCore) — what each message means, as pure
//!   functions (unit-tested without processes): `threshold` opens or closes a
//!   leg (a close yields the leg's [`LegLedger`]); a slot takes `truth` x_k
//!   and the prior x̂⁻_k, P⁻_k of its replica of the agent's estimator
//!   (handed over once per leg on `handover`, then advanced with the agent's
//!   own step functions), measures y_k = H x_k + v_k (noise from
//!   `streams::SENSOR`, keyed by episode and step), whitens the innovation and
//!   triggers on ‖ε‖∞ > δ.
//! * `node` — the thin iceoryx2 adapter: receive, call the core, publish
//!   `measurement` (only if it triggers), `slot` and `ledger`.
//!
//! The sensor waits in one place, its wake-up event (`wire::Waiter`): an idle
//! sensor sleeps in the kernel and wakes only every [`IDLE_CHECK`] to check
//! its parent, and every [`LIST_EVERY`] periods (or on iceoryx2's
//! dead-notifier event) that the coordinator still lives. A SIGSTOP/SIGCONT
//! only delays it; SIGINT/SIGTERM end it.

pub mod core;
mod node;

pub use core::{LegLedger, SensorStats};

use etp_runtime::shell::{self, Done};
use etp_runtime::wire::{RunId, WireError};
use std::time::Duration;

/// How often an idle sensor checks its coordinator and its termination flag.
pub const IDLE_CHECK: Duration = Duration::from_millis(250);
/// An idle sensor lists the run's nodes (to see a dead coordinator) every
/// this many idle periods; sooner when iceoryx2 reports a dead notifier.
/// Under `etp run` the supervisor also sends SIGTERM when the coordinator
/// ends abnormally, which is seen at the next idle period.
pub const LIST_EVERY: u32 = 12;

/// Why a sensor node stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum SensorError {
    #[error(transparent)]
    Wire(#[from] WireError),
    #[error(transparent)]
    Scenario(#[from] etp_runtime::scenario_arg::ScenarioArgError),
    #[error("unknown sensor `{0}` in scenario `{1}`")]
    UnknownSensor(String, String),
    #[error(transparent)]
    Port(#[from] etp_runtime::wire::PortError),
    #[error("protocol error: {0}")]
    Protocol(String),
    #[error("channel schedule {0}: {1}")]
    Schedule(String, String),
}

/// One sensor of an etpareto run (spawned by `etp run`).
#[derive(Debug, Clone, clap::Parser)]
#[command(name = "etp-sensor-node", version, about)]
pub struct Args {
    /// Run id (services live under `etp/<run-id>/`).
    #[arg(long)]
    pub run_id: String,
    /// Built-in scenario name or TOML path.
    #[arg(long)]
    pub scenario: String,
    /// Name of the sensor this process is.
    #[arg(long)]
    pub sensor: String,
    /// Run seed (measurement noise comes from `streams::SENSOR`).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The run's channel changes (`etp run --channel-schedule`, written
    /// into the run's folder): applied to this sensor's attempts.
    #[arg(long, value_name = "FILE")]
    pub channel_schedule: Option<std::path::PathBuf>,
}

/// How a sensor node ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// The coordinator said stop.
    Stopped,
    /// The coordinator (or the supervisor) died: no one will stop us.
    CoordinatorGone,
    /// SIGINT/SIGTERM.
    Signal,
}

/// Serve as sensor `args.sensor` until stopped.
pub fn run(args: &Args) -> Result<(Exit, SensorStats), SensorError> {
    let run = RunId::new(&args.run_id)?;
    let scenario = etp_runtime::load_scenario(&args.scenario)?;
    let index = scenario
        .sensors
        .iter()
        .position(|s| s.name == args.sensor)
        .ok_or_else(|| SensorError::UnknownSensor(args.sensor.clone(), scenario.name.clone()))?;
    let schedule = match &args.channel_schedule {
        None => ChannelSchedule::default(),
        Some(path) => {
            let shown = path.display().to_string();
            let text = std::fs::read_to_string(path)
                .map_err(|e| SensorError::Schedule(shown.clone(), e.to_string()))?;
            let names: Vec<String> = scenario.sensors.iter().map(|s| s.name.clone()).collect();
            ChannelSchedule::parse(&text, &shown, &scenario.radio, &names)
                .map_err(|e| SensorError::Schedule(shown, e.to_string()))?
        }
    };
    let m = scenario.sensors[index].dim();
    etp_shared::with_dim!(scenario.dim, N => {
        etp_shared::with_dim!(m, M => node::serve::<N, M>(&run, &scenario, index, args.seed, schedule))
    })
}

use anyhow::Context;
use etp_shared::radio::schedule::ChannelSchedule;

/// The sensor process, as the process shell runs it (`main` of the binary,
/// and `etp process etp-sensor-node`).
pub struct SensorProcess;

impl shell::Process for SensorProcess {
    const NAME: &'static str = "etp-sensor-node";
    type Args = Args;
    fn parse(argv: Vec<std::ffi::OsString>) -> Self::Args {
        clap::Parser::parse_from(argv)
    }
    type Error = anyhow::Error;
    fn body(args: &Args) -> anyhow::Result<Done> {
        let _span = tracing::info_span!("sensor", name = %args.sensor).entered();
        let (exit, stats) = run(args).with_context(|| format!("sensor `{}`", args.sensor))?;
        tracing::info!(?exit, ?stats, "sensor node done");
        Ok(Done::Quiet)
    }
}
