//! Is a finished run clean? The accounting identities checked leg by leg
//! and over the totals ([`verdict`]), the recording, refused link traffic
//! and an interrupt ([`problems`]), and the exit code of the first problem
//! ([`exit_for`]).

use super::{EXIT_ACCOUNTING, EXIT_DEGRADED, EXIT_INTERRUPTED, supervise};
use crate::error::{Error, Result};

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
    } else if !report.faults.is_empty() && !allow_degraded {
        // A sensor that died between its slots and its ledger degraded no
        // episode, but its ledger is missing: a dead link all the same.
        v.push((
            EXIT_DEGRADED,
            format!(
                "dead link: sensor(s) {} died before their ledger came (accept with --allow-degraded)",
                dead.iter().copied().collect::<Vec<_>>().join(", ")
            ),
        ));
    }
    v
}

/// What is wrong with a finished run, most important first (empty: clean).
pub fn problems(a: &super::RunRequest, outcome: &supervise::Supervised) -> Vec<(u8, String)> {
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
    if a.drift.on_drift == etp_shared::drift::OnDrift::Stop
        && let Some(first) = outcome.report.drift.first()
        && outcome.report.episodes < outcome.report.requested_episodes
    {
        problems.push((
            crate::EXIT_DRIFT,
            format!(
                "stopped on channel drift (--on-drift stop) after {} of {} episodes: {}",
                outcome.report.episodes,
                outcome.report.requested_episodes,
                first.describe()
            ),
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
        Some(&(code, _)) => Err(Error::Exit(etp_runtime::shell::ExitWith {
            code,
            message: problems
                .iter()
                .map(|(_, why)| format!("etp run: {why}"))
                .collect::<Vec<_>>()
                .join("\n"),
        })),
    }
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
            drift: Vec::new(),
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

    /// A link that lost every remote sensor at once: the agent found one of
    /// them dead, the coordinator the others by their missing ledgers. Each
    /// is a named dead link (exit 5), accepted only on request, never an
    /// accounting failure of a live sensor.
    #[test]
    fn a_sensor_dead_before_its_ledger_is_a_dead_link_even_with_nothing_degraded() {
        let r = report(vec![leg(0, 3, Some(3)), leg(1, 2, None)], false, Some("s1"));
        let v = verdict(&r, true, false);
        assert_eq!(codes(&v), vec![EXIT_DEGRADED]);
        assert!(v[0].1.contains("sensor(s) s1 died"), "{}", v[0].1);
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
