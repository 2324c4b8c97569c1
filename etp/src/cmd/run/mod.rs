//! `etp run`: the multi-process run of a strategy.
//!
//! Spawns `etp-coordinator`, `etp-agent` and one `etp-sensor-node` per sensor
//! (binaries found next to the running `etp`), supervises them with tokio
//! (exit codes, ctrl-c, a deadline), cleans the run's iceoryx2 files and
//! prints the report: outcomes with 95 % intervals beside the strategy's
//! prediction, and per sensor its ledger (transmitted), what the agent
//! received, and its predicted energy.
//!
//! * `prepare` — strategy and scenario (a strategy file, or `--scenario
//!   NAME --delta D` for a constant-δ strategy made on the fly), the run
//!   folder, `--clone-sensors K` for the scaling benchmark.
//! * `supervise` — spawning and supervising the processes.
//! * `report` — the table and the `--json` object.
//! * [`config`] — `--config RUN.toml`, the launch file of a run.

pub mod config;
mod figure;
pub mod link;
mod prepare;
mod process;
mod record;
mod remote;
mod report;
mod rundir;
pub mod sensor_host;
mod supervise;

use anyhow::{Context, Result, bail};
use etp_runtime::cleanup;
use etp_runtime::wire::RunId;
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

/// Exit codes (`etp run --help`; README "Exit codes").
const EXIT_CODES: &str = "Exit codes: 0 a clean run; 4 an accounting identity fails (ledger \
≠ received, a live sensor's ledger missing) or the recording failed (unfinished, its file \
removed or replaced during the run, or the target changed by another writer: the recording \
is then kept at FILE.<run-id>.partial) — never waived by --allow-degraded; 5 an episode ran \
with a dead link, or the link to remote sensors refused a message (garbage, forged, out of \
place), without --allow-degraded; 130 interrupted (Ctrl-C/SIGTERM: the report \
covers the complete episodes); 1 an error before any report (nothing recorded, no file \
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
    /// Number of episodes [default: 100].
    #[arg(long)]
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
    pub radio: crate::input::RadioArgs,
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
    /// (with `--record`), else `run-<run-id>-report.png` here.
    #[arg(long)]
    pub plot: bool,
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
}

/// Why a completed run is not clean (empty: exit 0), checked leg by leg: a
/// ledger's attempts must equal its delivered + lost (docs/MODEL.md §8), and
/// its delivered what the agent received on that leg; a missing ledger
/// is excused only for a sensor the run found dead (its episodes are then
/// degraded), never for a live one.
///
/// What is excused for a dead sensor is exactly its legs without a ledger
/// (the leg it died in, and its later legs): what the agent received on
/// them is counted apart (`received_without_ledger`) and compared with
/// nothing. Everything else is checked, dead sensor included: per leg
/// attempts = delivered + lost and delivered = received, and per sensor the
/// same over the sums (`transmitted`, `delivered`, `lost` of the ledgers,
/// `received` over the same legs), each equal to the sums of the episode
/// records. None of this is waived by `--allow-degraded`, which accepts the
/// degraded episodes only.
pub fn verdict(
    report: &etp_runtime::report::RunReport,
    recording_ok: bool,
    allow_degraded: bool,
) -> Vec<(u8, String)> {
    let dead: std::collections::BTreeSet<&str> =
        report.faults.iter().map(|f| f.sensor.as_str()).collect();
    let name = |i: u32| {
        report
            .sensors
            .get(i as usize)
            .map_or_else(|| format!("#{i}"), |s| s.name.clone())
    };
    let mut v = Vec::new();
    let (mut unequal, mut lost) = (0u64, 0u64);
    let mut first = None;
    for e in &report.episode_results {
        for l in &e.legs {
            let sensor = name(l.sensor);
            match (
                l.transmitted,
                l.delivered.or(l.transmitted),
                l.lost.unwrap_or(0),
            ) {
                (Some(t), Some(d), lost) if t != d + lost || d != l.received => {
                    unequal += 1;
                    first.get_or_insert(format!(
                        "episode {} leg {}: sensor {sensor} ledger {t} attempts = {d} delivered + {lost} lost, agent received {}",
                        e.episode, l.leg, l.received
                    ));
                }
                (None, _, _) if !dead.contains(sensor.as_str()) => {
                    lost += 1;
                    first.get_or_insert(format!(
                        "episode {} leg {}: no ledger from live sensor {sensor}",
                        e.episode, l.leg
                    ));
                }
                _ => {}
            }
        }
    }
    if unequal + lost > 0 {
        v.push((
            EXIT_ACCOUNTING,
            format!(
                "accounting mismatch: {unequal} leg(s) with attempts ≠ delivered + lost or delivered ≠ received, {lost} ledger(s) of live sensors missing (first: {})",
                first.unwrap_or_default()
            ),
        ));
    }
    // The totals, over exactly the legs they claim to cover.
    let mut totals = Vec::new();
    for (i, t) in report.sensors.iter().enumerate() {
        let legs = report
            .episode_results
            .iter()
            .flat_map(|e| &e.legs)
            .filter(|l| l.sensor as usize == i);
        let (mut led, mut delivered, mut lost, mut got, mut unledgered) = (0u64, 0, 0, 0, 0);
        for l in legs {
            match l.transmitted {
                Some(x) => {
                    led += u64::from(x);
                    delivered += u64::from(l.delivered.unwrap_or(x));
                    lost += u64::from(l.lost.unwrap_or(0));
                    got += u64::from(l.received);
                }
                None => unledgered += u64::from(l.received),
            }
        }
        let mine = (
            t.transmitted,
            t.delivered,
            t.lost,
            t.received,
            t.received_without_ledger,
        );
        if t.transmitted != t.delivered + t.lost
            || t.delivered != t.received
            || mine != (led, delivered, lost, got, unledgered)
        {
            totals.push(format!(
                "sensor {}: ledgers {} attempts = {} delivered + {} lost vs received {} on legs with a ledger (+{} on legs without; episode records: {led} = {delivered} + {lost} vs {got}, +{unledgered})",
                t.name, t.transmitted, t.delivered, t.lost, t.received, t.received_without_ledger
            ));
        }
    }
    // A leg already found unequal explains unequal totals: one problem.
    if unequal == 0 && !totals.is_empty() {
        v.push((
            EXIT_ACCOUNTING,
            format!("accounting mismatch in the totals: {}", totals.join("; ")),
        ));
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

/// Where `--plot` writes (`{run}` = the run id, known once the run starts).
fn plot_stem(a: &Args) -> PathBuf {
    match (&a.record, &a.run_id) {
        (Some(r), _) => r.with_extension("").with_file_name(format!(
            "{}-report",
            r.file_stem().and_then(|x| x.to_str()).unwrap_or("run")
        )),
        (None, Some(id)) => PathBuf::from(format!("run-{id}-report")),
        (None, None) => PathBuf::from("run-{run}-report"),
    }
}

/// Spawn, supervise and clean up one run (`a` resolved: see
/// [`config::resolve`]); the report data.
fn execute_run(a: &Args) -> Result<(prepare::Plan, supervise::Supervised)> {
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
    // `--record PATH` is claimed before any work (an existing file is
    // refused without --force); `--record-default` once its name is known.
    let mut target = match &a.record {
        Some(p) => Some(record::Target::claim(p, a.force, run_id.as_str())?),
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
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
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
        &plan,
        Duration::from_secs_f64(a.deadline()),
        target.as_ref().map(|t| t.partial.as_path()),
        a.slot_deadline,
        remote.as_ref(),
        a.json,
    ));
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

/// What is wrong with a finished run, most important first (empty: clean).
fn problems(a: &Args, outcome: &supervise::Supervised) -> Vec<(u8, String)> {
    let recording_ok = outcome.recording.as_ref().is_none_or(|r| r.finished);
    let mut problems = verdict(&outcome.report, recording_ok, a.allow_degraded);
    if let Some(why) = outcome.recording.as_ref().and_then(|r| r.problem.clone()) {
        problems.push((EXIT_ACCOUNTING, why));
    }
    // Refused traffic never got in: the run is intact, but somebody sent
    // what a sensor host may not (or the link broke order for good).
    if let Some(why) = outcome.link.as_ref().and_then(|l| l.faults())
        && !a.allow_degraded
    {
        problems.push((
            EXIT_DEGRADED,
            format!("{why} (accept with --allow-degraded)"),
        ));
    }
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

/// Run, print the report; the exit code is 0 only for a clean run, else
/// [`EXIT_INTERRUPTED`], [`EXIT_ACCOUNTING`] or [`EXIT_DEGRADED`] (the
/// report and stderr say why).
pub fn run(a: Args) -> Result<()> {
    let a = config::resolve(a)?;

    let stem = a.plot.then(|| plot_stem(&a));
    if let Some(stem) = &stem {
        for p in [stem.with_extension("png"), stem.with_extension("svg")] {
            crate::output::refuse_existing(&p, a.force)?;
        }
    }
    let (plan, outcome) = execute_run(&a)?;
    report::print(&a, &plan, &outcome)?;
    if let Some(stem) = &stem {
        let stem = stem
            .to_string_lossy()
            .replace("{run}", plan.run_id.as_str());
        let stem = std::path::Path::new(&stem);
        etp_figures::report_plot(&figure::figure(&plan, &outcome), stem)?;
        eprintln!("wrote {} and .svg", stem.with_extension("png").display());
    }
    exit_for(&problems(&a, &outcome))
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_runtime::report::{EpisodeRecord, FaultRecord, LegRecord, RunReport, SensorTotals};
    use etp_shared::strategy::Prediction;

    fn leg(sensor: u32, received: u32, transmitted: Option<u32>) -> LegRecord {
        LegRecord {
            leg: sensor,
            sensor,
            delta: 1.0,
            steps: 10,
            received,
            transmitted,
            delivered: transmitted,
            lost: transmitted.map(|_| 0),
            triggers: transmitted,
            slots: transmitted.map(|_| 10),
        }
    }

    fn report(legs: Vec<LegRecord>, degraded: bool, dead: Option<&str>) -> RunReport {
        // Totals as the coordinator sums them.
        let sensor = |name: &str| {
            let i = u32::from(name != "s0");
            let mine = || legs.iter().filter(move |l| l.sensor == i);
            SensorTotals {
                name: name.into(),
                transmitted: mine().filter_map(|l| l.transmitted).map(u64::from).sum(),
                delivered: mine().filter_map(|l| l.delivered).map(u64::from).sum(),
                lost: mine().filter_map(|l| l.lost).map(u64::from).sum(),
                triggers: mine().filter_map(|l| l.triggers).map(u64::from).sum(),
                received: mine()
                    .filter(|l| l.transmitted.is_some())
                    .map(|l| u64::from(l.received))
                    .sum(),
                received_without_ledger: mine()
                    .filter(|l| l.transmitted.is_none())
                    .map(|l| u64::from(l.received))
                    .sum(),
                slots: 0,
                energy: 0.0,
                missing_ledgers: mine().filter(|l| l.transmitted.is_none()).count() as u64,
            }
        };
        RunReport {
            run_id: "r".into(),
            scenario: "s".into(),
            scenario_hash: "h".into(),
            strategy_label: "l".into(),
            seed: 0,
            requested_episodes: 1,
            episodes: 1,
            target: 1,
            collision: 0,
            free: 0,
            degraded: u64::from(degraded),
            steps: 20,
            seconds: 1.0,
            predicted: Some(Prediction {
                p_target: 1.0,
                p_collision: 0.0,
                p_free: 0.0,
                energy_mean: 1.0,
            }),
            predicted_ci95: None,
            sensors: vec![sensor("s0"), sensor("s1")],
            faults: dead
                .map(|d| FaultRecord {
                    episode: 0,
                    sensor: d.into(),
                    detect_ms: 1.0,
                    wait_started_unix_ns: 0,
                    detected_unix_ns: 0,
                    dead_slots: 1,
                })
                .into_iter()
                .collect(),
            episode_results: vec![EpisodeRecord {
                episode: 0,
                outcome: "target".into(),
                degraded,
                steps: 20,
                energy: 3.0,
                legs,
            }],
            aborted: None,
        }
    }

    fn codes(v: &[(u8, String)]) -> Vec<u8> {
        v.iter().map(|p| p.0).collect()
    }

    #[test]
    fn a_clean_run_has_no_problem() {
        let r = report(vec![leg(0, 3, Some(3)), leg(1, 0, Some(0))], false, None);
        assert!(verdict(&r, true, false).is_empty());
    }

    #[test]
    fn a_lost_ledger_of_a_live_sensor_is_an_accounting_failure_even_if_marked_degraded() {
        // Defect 1 of issue 12: reported as `degraded 1` with exit 0.
        let r = report(vec![leg(0, 3, Some(3)), leg(1, 2, None)], true, None);
        let v = verdict(&r, true, true);
        assert_eq!(codes(&v), vec![EXIT_ACCOUNTING]);
        assert!(
            v[0].1.contains("no ledger from live sensor s1"),
            "{}",
            v[0].1
        );
    }

    #[test]
    fn a_ledger_unequal_to_received_fails() {
        let r = report(vec![leg(0, 3, Some(2))], false, None);
        assert_eq!(codes(&verdict(&r, true, true)), vec![EXIT_ACCOUNTING]);
    }

    /// A lossy radio (docs/MODEL.md §8): attempts = delivered + lost and
    /// delivered = received, per leg and in the totals.
    #[test]
    fn lost_attempts_are_counted_and_both_identities_are_checked() {
        let lossy = |received: u32, attempts: u32, delivered: u32, lost: u32| LegRecord {
            delivered: Some(delivered),
            lost: Some(lost),
            ..leg(0, received, Some(attempts))
        };
        let clean = report(vec![lossy(3, 5, 3, 2), leg(1, 0, Some(0))], false, None);
        assert!(verdict(&clean, true, false).is_empty());
        for (bad, what) in [
            (lossy(3, 5, 3, 1), "attempts ≠ delivered + lost"),
            (lossy(4, 5, 3, 2), "delivered ≠ received"),
        ] {
            let r = report(vec![bad, leg(1, 0, Some(0))], false, None);
            let v = verdict(&r, true, true);
            assert_eq!(codes(&v), vec![EXIT_ACCOUNTING], "{what}");
        }
        // Totals that drop the lost attempts fail though every leg holds.
        let mut r = clean;
        r.sensors[0].lost = 0;
        let v = verdict(&r, true, true);
        assert_eq!(codes(&v), vec![EXIT_ACCOUNTING]);
        assert!(v[0].1.contains("in the totals"), "{}", v[0].1);
    }

    #[test]
    fn a_dead_sensor_degrades_and_is_accepted_only_on_request() {
        let r = report(vec![leg(0, 3, Some(3)), leg(1, 1, None)], true, Some("s1"));
        assert_eq!(codes(&verdict(&r, true, false)), vec![EXIT_DEGRADED]);
        assert!(verdict(&r, true, true).is_empty());
    }

    #[test]
    fn totals_must_hold_over_exactly_the_legs_they_cover() {
        // Issue 24 item 2: a dead sensor's open leg (no ledger) excused,
        // but totals that count its received measurements against the
        // ledgers, or that disagree with the episode records, fail even
        // with --allow-degraded.
        let mut r = report(vec![leg(0, 3, Some(3)), leg(1, 7, None)], true, Some("s1"));
        assert!(verdict(&r, true, true).is_empty());
        r.sensors[1].received += 7;
        r.sensors[1].received_without_ledger = 0;
        let v = verdict(&r, true, true);
        assert_eq!(codes(&v), vec![EXIT_ACCOUNTING]);
        assert!(
            v[0].1
                .contains("sensor s1: ledgers 0 attempts = 0 delivered + 0 lost vs received 7"),
            "{}",
            v[0].1
        );
        let mut r = report(vec![leg(0, 3, Some(3))], false, None);
        r.sensors[0].transmitted = 4;
        r.sensors[0].received = 4;
        assert_eq!(codes(&verdict(&r, true, true)), vec![EXIT_ACCOUNTING]);
    }

    #[test]
    fn an_unfinished_recording_fails() {
        let r = report(vec![leg(0, 3, Some(3))], false, None);
        assert_eq!(codes(&verdict(&r, false, false)), vec![EXIT_ACCOUNTING]);
    }
}
