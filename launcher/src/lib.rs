//! `etp-launcher`: the multi-process run of a strategy as a library — what
//! `etp run` prints (`etp/src/cmd/run.rs`), `etp demo` tabulates and a
//! notebook can start — kept out of the CLI crate.
//!
//! It spawns `etp-coordinator`, `etp-agent`, one `etp-sensor-node` per
//! sensor and the `etp-recorder` (binaries found next to the running
//! executable, else `etp process NAME`), supervises them with tokio (exit
//! codes, ctrl-c, a deadline), judges the finished run, cleans the run's
//! iceoryx2 files and folder, and reports it: outcomes with 95 % intervals
//! beside the strategy's prediction, and per sensor its ledger
//! (transmitted), what the agent received, and its predicted energy.
//!
//! A short tour:
//!
//! * [`Args`] — a run's request (`etp run`'s arguments); [`config`] its
//!   launch file (`--config RUN.toml`, each key named once).
//! * [`execute_run`] — spawn, supervise and clean up one run: the
//!   [`prepare::Plan`] and the [`supervise::Supervised`] outcome;
//!   [`execute`] the same as the `--json` object with its problems.
//! * [`prepare`] — strategy and scenario (a strategy file, or `--scenario
//!   NAME --delta D` for a constant-δ strategy made on the fly), the run's
//!   files, `--clone-sensors K` for the scaling benchmark.
//! * [`supervise`] — spawning and supervising the processes ([`process`]:
//!   where their binaries are, how one is started and signalled).
//! * [`problems`] and [`exit_for`] — is the finished run clean (accounting
//!   identities leg by leg and over the totals, the recording, refused link
//!   traffic, an interrupt) and its exit code ([`EXIT_ACCOUNTING`],
//!   [`EXIT_DEGRADED`], [`EXIT_INTERRUPTED`]).
//! * [`report`] — the table and the `--json` object; [`figure`] the data of
//!   `--plot`'s figure.
//! * [`link`] — `--tls DIR` / `--insecure` of a run across hosts; the
//!   bridge process for remote sensors and its report (`remote`).
//! * `live` — `--live [ADDR:PORT]`: the Foxglove view (`etp-live`), bound
//!   before any process starts, fed by the agent without ever waiting.
//! * `record` — the recording's target (claimed before the run, replaced
//!   only once the run ran) and the recorder process; `rundir` — the run's
//!   private folder, owned by one live run (a lock the kernel drops when
//!   the owner dies).
//!
//! # Semantics of faults
//!
//! * **Dead** (the iceoryx2 node of a process is dead or gone): the episodes it
//!   serves are *degraded*. A dead sensor is a dead link: the agent predicts only
//!   on its slots (never the implicit update) and the episode is marked degraded;
//!   its ledgers are missing. A dead agent fails the run; a dead coordinator ends
//!   every process: at once under `etp run` (SIGTERM to each), otherwise
//!   within a sensor's node-list period (3 s).
//! * **Live but slow or paused** (load, SIGSTOP/SIGCONT, Ctrl-Z + `fg`, a
//!   debugger): waited for. Simulated time does not advance, nothing is
//!   degraded. Only `etp run --slot-deadline MS` (real-time studies) turns a slot
//!   late by MS into a reported fault.
//! * **Interrupted waits** (EINTR after SIGCONT) are resumed, never fatal.
//! * **Nothing that carries data, control or accounting is overwritten**: every
//!   publish-subscribe service has `safe_overflow` off, so a full buffer makes
//!   the publisher wait for its reader (the recorder included) instead of
//!   dropping or overwriting; only the wake-up events may coalesce.
//! * **SIGINT = SIGTERM** to `etp run`: the coordinator stops after the complete
//!   episodes, collects their ledgers (a live sensor's ledger is always waited
//!   for; after a termination request for at most 2 s), stops every process,
//!   the recorder finishes its file, the partial report is printed and every
//!   file of the run is removed (exit 130). The run's processes live in process
//!   groups of their own, so a terminal's Ctrl-C reaches `etp run` only.
//! * **A service left half-made.** A process killed between creating a
//!   shared-memory file and sizing it leaves it empty (and write-only).
//!   iceoryx2 0.10, removing a dead node's resources, retries opening such a
//!   file forever as root. Every removal of dead nodes' resources
//!   (`wire::remove_dead_nodes`, `wire::liveness`, the stale-run sweeps) first
//!   removes the run's empty shared-memory files older than 2 s
//!   (`wire::liveness::remove_abandoned_storage`; a live creator sizes its file within
//!   microseconds). Before this, one such file hung every later `etp run` on the
//!   machine, and a CI run (`faults::a_service_left_half_made_…` reproduces it).
//! * **kill -9 of `etp run`**: its processes see their parent change and exit;
//!   the run folder (`<private>/run/<id>` in the user's private folder, locked by its owner for the run's
//!   lifetime) and iceoryx2 files of the dead run are removed by the next start.
//! * **Exit codes of `etp run`** (README "Exit codes"): 0 only when every
//!   episode ran, every count agrees and the requested recording finished at its
//!   path; 4 when a count disagrees (per leg, or per sensor over the legs with a
//!   ledger), a live sensor's ledger is missing or the recording failed (also:
//!   its target changed under it); 5 when an episode degraded (unless
//!   `--allow-degraded`, which excuses exactly a dead sensor's legs without a
//!   ledger: their received measurements are reported apart as
//!   `received_without_ledger`); 130 when interrupted; 1 for errors.
//! * **`--record` never loses a file**: the recorder writes
//!   `<FILE>.<run-id>.partial`; `record::Target::commit` moves it onto FILE once
//!   the run ran — with `link(2)` when FILE did not exist, with `rename(2)` when
//!   it is still the inode `--force` allowed to replace — and otherwise keeps it
//!   beside and exits 4. A run that fails before it ran removes its partial file.

pub mod config;
pub mod figure;
mod interrupts;
pub mod link;
mod live;
pub mod prepare;
pub mod process;
mod record;
mod remote;
pub mod report;
mod rundir;
pub mod supervise;
mod verdict;

use anyhow::{Context, Result, bail};
use etp_runtime::cleanup;
use etp_runtime::wire::RunId;
use std::path::PathBuf;
use std::time::Duration;
pub use verdict::{exit_for, problems};

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

/// Exit codes (`etp run --help`; README "Exit codes").
const EXIT_CODES: &str = "Exit codes: 0 a clean run; 4 an accounting identity fails (ledger \
≠ received, a live sensor's ledger missing) or the recording failed (unfinished, its file \
removed or replaced during the run, or the target changed by another writer: the recording \
is then kept at FILE.<run-id>.partial) — never waived by --allow-degraded; 5 an episode ran \
with a dead link, or the link to remote sensors refused a message (garbage, forged, out of \
place), without --allow-degraded; 130 interrupted (Ctrl-C/SIGTERM: the report \
covers the complete episodes; before the first episode, no report and nothing left: no \
process, no recording); 1 an error before any report (nothing recorded, no file \
touched). --allow-degraded excuses exactly a dead sensor's legs without a ledger: what the \
agent received on them is reported apart (received_without_ledger).";

#[derive(Debug, Clone, clap::Args)]
#[command(after_help = EXIT_CODES)]
pub struct Args {
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
    #[arg(long, requires = "scenario")]
    pub delta: Option<f64>,
    /// Number of episodes (at least 1) [default: 100].
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
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
    pub radio: etp_runtime::scenario_options::RadioArgs,
    /// The trigger family (docs/MODEL.md §9), written into the run's
    /// scenario text; with a strategy it must be the strategy's own.
    #[command(flatten)]
    pub trigger: etp_runtime::scenario_options::TriggerArgs,
    /// Kill everything and fail after this many seconds [default: 3600].
    #[arg(long)]
    pub deadline: Option<f64>,
    /// Run id (default: generated). Names the services `etp/<run-id>/…`.
    #[arg(long)]
    pub run_id: Option<String>,
    /// Include every episode (legs, ledgers, received counts) in the JSON.
    #[arg(long)]
    pub episode_details: bool,
    /// In-process episodes used to predict each sensor's energy [default: 2000].
    #[arg(long)]
    pub predict_episodes: Option<u64>,
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
    #[arg(long, value_name = "MS")]
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
    /// Seconds to wait for the remote sensors to join [default: 60].
    #[arg(long)]
    pub join_timeout: Option<f64>,
    /// The link's protection (with `--listen`).
    #[command(flatten)]
    pub link: link::LinkArgs,
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
        value_parser = live::parse_addr
    )]
    pub live: Option<std::net::SocketAddr>,
    /// With --live: start the episodes only once a Foxglove client has
    /// subscribed (waits at most --deadline). Changes only when the run
    /// starts, not what it computes.
    #[arg(long, requires = "live")]
    pub live_wait: bool,
}

impl Args {
    /// Episodes to run (after [`config::resolve`]).
    pub fn episodes(&self) -> u64 {
        self.episodes.unwrap_or(config::DEFAULT_EPISODES)
    }
    pub fn seed(&self) -> u64 {
        self.seed.unwrap_or(config::DEFAULT_SEED)
    }
    pub fn deadline(&self) -> f64 {
        self.deadline.unwrap_or(config::DEFAULT_DEADLINE)
    }
    pub fn join_timeout(&self) -> f64 {
        self.join_timeout.unwrap_or(config::DEFAULT_JOIN_TIMEOUT)
    }
    pub fn predict_episodes(&self) -> u64 {
        self.predict_episodes
            .unwrap_or(config::DEFAULT_PREDICT_EPISODES)
    }
}

/// Spawn, supervise and clean up one run (`a` resolved: see
/// [`config::resolve`]); the report data.
pub fn execute_run(a: &Args) -> Result<(prepare::Plan, supervise::Supervised)> {
    if a.episodes() == 0 {
        bail!("--episodes must be at least 1");
    }
    if !(a.deadline().is_finite() && a.deadline() > 0.0) {
        bail!("--deadline must be a positive number of seconds");
    }
    if a.slot_deadline == Some(0) {
        bail!("--slot-deadline must be at least 1 ms");
    }
    let run_id = match &a.run_id {
        Some(id) => RunId::new(id)?,
        None => RunId::generate(),
    };
    live::check(a)?;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let mut interrupts = interrupts::Interrupts::listen(&rt)?;
    // `--record PATH` is claimed before any work (an existing file is
    // refused without --force); `--record-default` once its name is known.
    let mut target = match &a.record {
        Some(p) => {
            // A folder the user named must exist (`--record-default`'s
            // `recordings/` is made when missing).
            etp_recording_tools::files::existing_folder_of(p, "--record")?;
            Some(record::Target::claim(p, a.force, run_id.as_str())?)
        }
        None => None,
    };
    let stale_dirs = rundir::remove_stale();
    let stale = cleanup::remove_stale_runs();
    if !stale.is_empty() || !stale_dirs.is_empty() {
        tracing::info!(?stale, ?stale_dirs, "removed what dead runs left");
    }
    let dir = rundir::RunDir::claim(&run_id)?;
    let prepared = prepare::prepare(a, &run_id, &dir.path).and_then(|mut p| {
        if target.is_none() && a.record_default {
            target = Some(record::Target::claim(
                &record::default_path(&p),
                a.force,
                run_id.as_str(),
            )?);
        }
        let c = config::of_args(a, target.as_ref().map(|t| t.path.as_path()));
        p.config_toml = config::stored(&c)?;
        Ok(p)
    });
    let plan = match prepared {
        Ok(p) => p,
        Err(e) => {
            dir.remove();
            return Err(e);
        }
    };
    // The view listens before any process starts (a port in use fails here).
    let view = match live::start(a, &plan, &dir.path) {
        Ok(v) => v,
        Err(e) => {
            dir.remove();
            return Err(e);
        }
    };
    if let Some(name) = interrupts.pending(&rt) {
        dir.remove();
        return Err(interrupts::before_any_episode(
            name,
            "while the run prepared",
        ));
    }
    if let Some(v) = &view
        && let Err(e) = live::wait(a, v, &rt, &mut interrupts)
    {
        dir.remove();
        return Err(e);
    }
    let remote = match &a.listen {
        Some(listen) => match remote::remote_indices(&plan, &a.remote) {
            Ok(r) => match a
                .link
                .bridge_args(listen, etp_runtime::link_keys::AGENT_HOST)
            {
                Ok(link) => Some(remote::RemoteSpec {
                    listen: listen.clone(),
                    remote: r,
                    join_timeout: a.join_timeout(),
                    link,
                }),
                Err(e) => {
                    dir.remove();
                    return Err(e);
                }
            },
            Err(e) => {
                dir.remove();
                return Err(e);
            }
        },
        None => None,
    };
    let outcome = rt.block_on(supervise::supervise(
        &mut interrupts,
        &plan,
        Duration::from_secs_f64(a.deadline()),
        a.slot_deadline,
        supervise::Attached {
            record: target.as_ref().map(|t| t.partial.as_path()),
            remote: remote.as_ref(),
            live_feed: view.as_ref().map(|v| v.feed.as_path()),
        },
        a.json,
    ));
    if let Some(v) = view {
        let stats = v.view.finish();
        tracing::info!(?stats, "live view stopped");
    }
    // Whatever happened: no iceoryx2 leftovers of this run.
    let cleaned = cleanup::remove_run(&run_id);
    dir.remove();
    // The recording replaces its target only once the run ran (record.rs).
    let outcome = match (outcome, &target) {
        (Ok(mut o), Some(t)) => {
            if let Some(rec) = o.recording.as_mut() {
                t.commit(rec);
            }
            Ok(o)
        }
        (Err(e), Some(t)) => {
            t.abandon();
            Err(e)
        }
        (o, None) => o,
    };
    let outcome = outcome?;
    if !cleaned {
        tracing::warn!("run {run_id}: some iceoryx2 node still alive at the end; files left");
    }
    Ok((plan, outcome))
}

/// A run's `--json` report object (used by `etp demo`) and its problems
/// (pass them to [`exit_for`] once the report is shown).
pub fn execute(a: &Args) -> Result<(serde_json::Value, Vec<(u8, String)>)> {
    let a = &config::resolve(a.clone())?;
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
