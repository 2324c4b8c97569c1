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
//! * [`RunRequest`] — a run's request, typed and resolved ([`request`]:
//!   what to run, the recording, remote sensors, the live view), built from
//!   [`config::RunConfig`], the run file's keys (`--config RUN.toml`, each
//!   key named once; `etp run`'s flags are written as the same keys).
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
//! * [`error`] — what a run fails with ([`Error`], one variant per kind of
//!   failure); an outcome with its own exit code is [`Error::Exit`].
//! * [`request::LinkProtection`] — `--tls DIR` / `--insecure` of a run
//!   across hosts; `remote` the bridge process for remote sensors and its
//!   report.
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
pub mod error;
pub mod figure;
mod interrupts;
mod live;
pub mod prepare;
pub mod process;
mod record;
mod remote;
pub mod report;
pub mod request;
mod rundir;
pub mod supervise;
mod verdict;

use error::IoContext;
pub use error::{Error, Result};
use etp_runtime::cleanup;
use etp_runtime::wire::RunId;
pub use live::parse_addr as parse_live_addr;
pub use request::{DriftWatch, RecordTo, RunRequest, RunTarget};
use std::time::Duration;
pub use verdict::{exit_for, problems};

/// Exit code: the run completed but a count disagrees (a sensor's ledger ≠
/// what the agent received), a ledger is missing, or the requested
/// recording did not finish. Never 0.
pub const EXIT_ACCOUNTING: u8 = 4;
/// Exit code: an episode ran with a dead link (degraded), without
/// `--allow-degraded`.
pub const EXIT_DEGRADED: u8 = 5;
/// Exit code: with `--on-drift stop`, the channel monitor flagged a drift
/// and the run stopped after the flag's episode; the report covers the
/// episodes run.
pub const EXIT_DRIFT: u8 = 6;
/// Exit code: SIGINT or SIGTERM stopped the run; the report covers the
/// complete episodes.
pub const EXIT_INTERRUPTED: u8 = 130;

/// Spawn, supervise and clean up one run; the report data.
pub fn execute_run(a: &RunRequest) -> Result<(prepare::Plan, supervise::Supervised)> {
    let run_id = match &a.run_id {
        Some(id) => RunId::new(id)?,
        None => RunId::generate(),
    };
    live::check(a)?;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .setting_up("starting the tokio runtime")?;
    let mut interrupts = interrupts::Interrupts::listen(&rt)?;
    // `--record PATH` is claimed before any work (an existing file is
    // refused without --force); `--record-default` once its name is known.
    let mut target = match &a.record {
        RecordTo::File(p) => {
            // A folder the user named must exist (`--record-default`'s
            // `recordings/` is made when missing).
            etp_files::write::existing_folder_of(p, "--record")?;
            Some(record::Target::claim(p, a.force, run_id.as_str())?)
        }
        RecordTo::DefaultFile | RecordTo::Nothing => None,
    };
    let stale_dirs = rundir::remove_stale();
    let stale = cleanup::remove_stale_runs();
    if !stale.is_empty() || !stale_dirs.is_empty() {
        tracing::info!(?stale, ?stale_dirs, "removed what dead runs left");
    }
    let dir = rundir::RunDir::claim(&run_id)?;
    let prepared = prepare::prepare(a, &run_id, &dir.path).and_then(|mut p| {
        if a.record == RecordTo::DefaultFile {
            target = Some(record::Target::claim(
                &record::default_path(&p),
                a.force,
                run_id.as_str(),
            )?);
        }
        let c = a.to_config(target.as_ref().map(|t| t.path.as_path()));
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
    let remote = match &a.remote {
        Some(sensors) => match remote::remote_indices(&plan, &sensors.sensors) {
            Ok(r) => match a
                .link
                .bridge_args(&sensors.listen, etp_runtime::link_keys::AGENT_HOST)
            {
                Ok(link) => Some(remote::RemoteSpec {
                    listen: sensors.listen.clone(),
                    remote: r,
                    join_timeout: sensors.join_timeout,
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
        Duration::from_secs_f64(a.deadline),
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

/// A run's `--json` report object (used by `etp demo` and Python) and its
/// problems (pass them to [`exit_for`] once the report is shown).
pub fn execute(a: &RunRequest) -> Result<(serde_json::Value, Vec<(u8, String)>)> {
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
