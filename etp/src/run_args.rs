//! `etp run`'s flags (the command line's form of a run) and how they become
//! the launcher's typed [`RunRequest`]: each flag given is written as the
//! run file's key of the same name, merged over `--config RUN.toml`
//! ([`config::merge`]), then checked once by [`RunRequest::from_config`] —
//! the same path a run file alone and Python take. clap stays here; the
//! launcher never sees a flag.

use crate::scenario_flags::{RadioArgs, TriggerArgs};
use anyhow::{Context, Result};
use etp_launcher::RunRequest;
use etp_launcher::config::{self, RunConfig};
use etp_launcher::request::LinkProtection;
use std::path::PathBuf;

/// Exit codes (`etp run --help`; README "Exit codes").
const EXIT_CODES: &str = "Exit codes: 0 a clean run; 4 an accounting identity fails (ledger \
≠ received, a live sensor's ledger missing) or the recording failed (unfinished, its file \
removed or replaced during the run, or the target changed by another writer: the recording \
is then kept at FILE.<run-id>.partial) — never waived by --allow-degraded; 5 an episode ran \
with a dead link, or the link to remote sensors refused a message (garbage, forged, out of \
place), without --allow-degraded; 130 interrupted (Ctrl-C/SIGTERM: the report \
covers the complete episodes; before the first episode, no report and nothing left: no \
process, no recording); 1 an error before any report (nothing recorded, no file \
touched); 2 a bad command line (a value out of its range: nothing starts). \
--allow-degraded excuses exactly a dead sensor's legs without a ledger: what the \
agent received on them is reported apart (received_without_ledger).";

#[derive(Debug, Clone, clap::Args)]
#[command(after_help = EXIT_CODES)]
pub struct RunArgs {
    /// A run file (TOML; keys are the long flags: `strategy` or `scenario` +
    /// `delta`, `episodes`, `seed`, `record`, `slot_deadline`, …). Flags on
    /// the command line win over the file. Stored in the recording (`etp.config`).
    #[arg(long, value_name = "RUN.toml")]
    pub config: Option<PathBuf>,
    /// A strategy.json (from `etp strategy`). Omit it and give `--scenario` and
    /// `--delta` to run a constant threshold.
    pub strategy: Option<PathBuf>,
    /// Scenario (built-in name or TOML path) for a constant-δ run.
    #[arg(long)]
    pub scenario: Option<String>,
    /// The constant threshold δ (one of the scenario's Δ) for a constant-δ run.
    #[arg(long, requires = "scenario", value_parser = crate::values::non_negative)]
    pub delta: Option<f64>,
    /// Number of episodes (at least 1) [default: 100].
    #[arg(long, value_parser = crate::values::whole::<u64>(1, None))]
    pub episodes: Option<u64>,
    /// Seed: the same seed gives the same episodes [default: 0].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// The radio (docs/MODEL.md §8): each option given replaces the
    /// strategy's own channel (or the scenario's) on every link; the run's
    /// channel is written into the run's scenario text (every process and the
    /// recording read that text).
    #[command(flatten)]
    pub radio: RadioArgs,
    /// The trigger family (docs/MODEL.md §9), written into the run's
    /// scenario text; with a strategy it must be the strategy's own.
    #[command(flatten)]
    pub trigger: TriggerArgs,
    /// Change sensors' links during the run (docs/MODEL.md §8.8): a TOML
    /// file of `[[change]]` tables (`sensor`, `episode`, and any of `loss`,
    /// `retries`, `burst`), applied on the sensor side; the agent's model and
    /// the prediction keep the strategy's channel. Recorded with the run.
    #[arg(long, value_name = "FILE")]
    pub channel_schedule: Option<PathBuf>,
    /// The channel monitor's false-alarm probability for the whole run, in
    /// (0, 1) (docs/MODEL.md §11: sequential tests of each sensor's losses
    /// and triggers against the strategy's channel) [default: 0.01].
    #[arg(long, value_name = "ALPHA", value_parser = crate::values::open_unit)]
    pub drift_false_alarm: Option<f64>,
    /// What a flag of the channel monitor does: `warn` reports it (the run
    /// goes on), `stop` ends the run after the flag's episode [default:
    /// warn].
    #[arg(long, value_name = "WHAT", value_parser = ["warn", "stop"])]
    pub on_drift: Option<String>,
    /// Kill everything and fail after this many seconds (> 0) [default: 3600].
    #[arg(long, value_name = "SECONDS", value_parser = crate::values::seconds)]
    pub deadline: Option<f64>,
    /// Run id (default: generated). Names the services `etp/<run-id>/…`.
    #[arg(long)]
    pub run_id: Option<String>,
    /// Include every episode (legs, ledgers, received counts) in the JSON.
    #[arg(long)]
    pub episode_details: bool,
    /// In-process episodes used to predict each sensor's energy (at least
    /// 1) [default: 2000].
    #[arg(long, value_name = "N", value_parser = crate::values::whole::<u64>(1, None))]
    pub predict_episodes: Option<u64>,
    /// Benchmark: replace the sensors by K copies of the first one, legs
    /// served round robin (same maths, K sensor processes); K from 1 to 64.
    #[arg(long, value_name = "K",
          value_parser = crate::values::whole::<usize>(1, Some(etp_launcher::prepare::MAX_SENSORS as u64)))]
    pub clone_sensors: Option<usize>,
    /// Record every message of the run to this MCAP file (see `etp replay`).
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Record to the default file `recordings/<scenario>-<run-id>.mcap`.
    #[arg(long, conflicts_with = "record")]
    pub record_default: bool,
    /// Replace the `--record` file if it exists — only once the run ran and
    /// its recording finished, and only if no other writer touched the file
    /// meanwhile (the run records beside it, to `<FILE>.<run-id>.partial`).
    #[arg(long)]
    pub force: bool,
    /// Exit 0 even if some episodes ran with a dead link (a sensor died):
    /// for fault-injection studies. Counts must still agree.
    #[arg(long)]
    pub allow_degraded: bool,
    /// Real-time studies: a slot not closed within MS milliseconds counts as
    /// a dead link (a fault) even if the sensor process lives. Default: a
    /// live process is waited for, however slow or paused.
    #[arg(long, value_name = "MS", value_parser = crate::values::whole::<u64>(1, None))]
    pub slot_deadline: Option<u64>,
    /// Draw measured vs predicted (per-sensor energy per episode, outcomes,
    /// 95 % intervals) to `<recording without .mcap>-report.png` and `.svg`
    /// (with `--record`), else `run-<run-id>-report.png` here; `-o STEM`
    /// chooses.
    #[arg(long)]
    pub plot: bool,
    /// With --plot: the figure's file stem, writes STEM.png and STEM.svg
    /// (its folder must exist).
    #[arg(short = 'o', long = "out", value_name = "STEM", requires = "plot")]
    pub plot_out: Option<PathBuf>,
    /// Across hosts: listen on this Zenoh endpoint (e.g. `tls/10.0.0.1:7447`
    /// with `--tls DIR`; `tcp/…` with `--insecure`) for sensor hosts (`etp
    /// sensor-host --connect …`). Scouting is off: only this endpoint is used.
    #[arg(long, value_name = "ENDPOINT", requires = "remote")]
    pub listen: Option<String>,
    /// Sensors served from other hosts (names, comma-separated); the run
    /// waits until they joined.
    #[arg(
        long,
        value_delimiter = ',',
        requires = "listen",
        value_name = "SENSORS"
    )]
    pub remote: Vec<String>,
    /// Seconds to wait for the remote sensors to join (> 0) [default: 60].
    #[arg(long, value_name = "SECONDS", value_parser = crate::values::seconds)]
    pub join_timeout: Option<f64>,
    /// The link's protection (with `--listen`).
    #[command(flatten)]
    pub link: LinkArgs,
    /// Serve the run live to Foxglove (the Foxglove SDK's WebSocket server, `foxglove.sdk.v1`)
    /// at ADDR:PORT (an IP address or a host name such as `localhost`)
    /// [default: 127.0.0.1:8765; port 0: any free port]: the
    /// map, the true state, the estimate with its 3σ ellipse, each sensor's
    /// transmissions and threshold, each episode's outcome, rates and
    /// energy vs predicted (layout: docs/foxglove-live-layout.json). The view
    /// never slows or changes the run: it drops frames, not steps. It is
    /// plain WebSocket, neither authenticated nor encrypted: an address
    /// other than loopback is refused unless --insecure is given.
    #[arg(
        long,
        value_name = "ADDR:PORT",
        num_args = 0..=1,
        default_missing_value = etp_live::DEFAULT_ADDR,
        value_parser = etp_launcher::parse_live_addr
    )]
    pub live: Option<std::net::SocketAddr>,
    /// With --live: start the episodes only once a Foxglove client has
    /// subscribed (waits at most --deadline). Changes only when the run
    /// starts, not what it computes.
    #[arg(long, requires = "live")]
    pub live_wait: bool,
}

impl RunArgs {
    /// The flags given, as run-file keys (a switch given is `Some(true)`).
    fn given(&self) -> RunConfig {
        let on = |b: bool| b.then_some(true);
        RunConfig {
            strategy: self.strategy.clone(),
            scenario: self.scenario.clone(),
            delta: self.delta,
            episodes: self.episodes,
            seed: self.seed,
            deadline: self.deadline,
            run_id: self.run_id.clone(),
            predict_episodes: self.predict_episodes,
            clone_sensors: self.clone_sensors,
            record: self.record.clone(),
            record_default: on(self.record_default),
            allow_degraded: on(self.allow_degraded),
            slot_deadline: self.slot_deadline,
            listen: self.listen.clone(),
            remote: (!self.remote.is_empty()).then(|| self.remote.clone()),
            join_timeout: self.join_timeout,
            tls: self.link.tls.clone(),
            insecure: on(self.link.insecure),
            loss: self.radio.loss,
            retries: self.radio.retries,
            burst: self.radio.burst,
            estimator: self.radio.estimator.clone(),
            trigger: self.trigger.trigger,
            channel_schedule: self.channel_schedule.clone(),
            drift_false_alarm: self.drift_false_alarm,
            on_drift: self.on_drift.clone(),
            live: self.live,
            live_wait: on(self.live_wait),
        }
    }

    /// The run these flags ask for, over `--config`'s run file (a flag
    /// wins); errors name the flag or the file and its key.
    pub fn request(&self) -> Result<RunRequest> {
        let merged = match &self.config {
            Some(path) => {
                let file = config::read(path)?;
                RunRequest::from_config(config::merge(self.given(), file))
                    .with_context(|| format!("run file {}", path.display()))?
            }
            None => RunRequest::from_config(self.given())?,
        };
        Ok(RunRequest {
            force: self.force,
            json: self.json,
            episode_details: self.episode_details,
            ..merged
        })
    }
}

/// `--tls DIR` / `--insecure`: how a link across hosts is protected (`etp
/// run --listen`, `etp sensor-host`). The rule (a `tls/` endpoint with a key
/// folder, or plain `tcp/` only when asked for) is checked before any
/// process starts and again by the bridge.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct LinkArgs {
    /// Key folder of `etp certs init DIR`: the link is TLS, both ends
    /// authenticated by the folder's CA (endpoints `tls/ADDR:PORT`). The default.
    #[arg(long, value_name = "DIR", conflicts_with = "insecure")]
    pub tls: Option<PathBuf>,
    /// Plain TCP (`tcp/ADDR:PORT`): no authentication, no encryption.
    /// For isolated test networks only. Also lets `etp run --live` serve
    /// its (plain WebSocket) view on an address other than loopback.
    #[arg(long)]
    pub insecure: bool,
}

impl LinkArgs {
    /// The launcher's typed form.
    pub fn protection(&self) -> LinkProtection {
        LinkProtection {
            tls: self.tls.clone(),
            insecure: self.insecure,
        }
    }
}
