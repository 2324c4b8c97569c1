//! The run's summary from a recording alone: episodes, outcomes, per-sensor
//! transmissions (`measurement` messages beside the sensors' ledgers and what
//! the agent received; on a lossy radio the attempts recorded in `slot`
//! beside the ledgers' attempts = delivered + lost), energy vs prediction.

use crate::error::{Context, Result};
use etp_runtime::recording::{self, Contents, Recorded};
use etp_shared::stats::verdict::{Measured, Outcomes};
use etp_shared::strategy::Strategy;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::Path;

/// One sensor, in the vocabulary of `crate::vocab`, over the complete
/// episodes.
#[derive(Debug, Default, Clone, serde::Serialize)]
struct SensorSummary {
    name: String,
    /// `measurement` messages sent by this sensor (delivered attempts).
    measurements: u64,
    /// Sum of the sensor's ledgers: transmission attempts, delivered, lost.
    transmissions: u64,
    delivered: u64,
    lost: u64,
    /// Attempts recorded slot by slot (`slot.attempts`).
    attempts_recorded: u64,
    /// `measurement` messages on the legs of degraded episodes that have no
    /// ledger (a dead sensor's open leg): excused from the identities.
    measurements_without_ledger: u64,
    /// Measurements the agent received from this sensor (per leg: the next
    /// waypoint's `prev_received`, the outcome's `last_received`).
    received: u64,
    /// Sum of the sensor's ledgers (energy).
    energy: f64,
    predicted_energy: Option<f64>,
}

/// What one episode left in the recording.
#[derive(Debug, Default)]
struct EpisodeTally {
    outcome: Option<etp_runtime::wire::agent_to_coordinator::Outcome>,
    /// Leg → its ledger.
    ledgers: BTreeMap<u32, etp_runtime::wire::sensor_to_coordinator::Ledger>,
    /// (Leg, sensor) → attempts recorded in its slots.
    attempts: BTreeMap<(u32, u32), u64>,
    /// Leg → measurements the agent received in it (from the next waypoint).
    received: BTreeMap<u32, u64>,
    /// (Leg, sensor) → `measurement` messages.
    measurements: BTreeMap<(u32, u32), u64>,
    /// The channel monitor's flags raised in the episode, in order.
    drift: Vec<etp_runtime::wire::agent_to_coordinator::Drift>,
    messages: u64,
}

impl EpisodeTally {
    /// Complete: the outcome and the ledger of every leg it ran are recorded
    /// (the last leg's ledger follows the outcome, so a cut between them
    /// leaves the episode partial) — or the outcome of a degraded episode
    /// (a dead link), or an outcome whose legs without a ledger are all of
    /// sensors the run found dead (`excused`: a sensor stopped after its
    /// leg closed and before its ledger, found dead in a later episode).
    /// Those legs are excused, as `etp run --allow-degraded` excuses them,
    /// their measurements counted apart. Without the `ledger` channel (a
    /// selection of topics), the outcome alone.
    fn complete(&self, ledgers_recorded: bool, excused: impl Fn(u32) -> bool) -> bool {
        self.outcome.is_some_and(|o| {
            !ledgers_recorded
                || o.degraded != 0
                || (0..=o.header.leg).all(|l| self.ledgers.contains_key(&l) || excused(l))
        })
    }

    /// Degraded as `etp run` counts it: a dead link met in the episode, or a
    /// leg it ran without a ledger.
    fn degraded(&self, ledgers_recorded: bool) -> bool {
        self.outcome.is_some_and(|o| {
            o.degraded != 0
                || (ledgers_recorded && (0..=o.header.leg).any(|l| !self.ledgers.contains_key(&l)))
        })
    }

    /// Received per leg, the last leg's from the outcome.
    fn received_of(&self, leg: u32) -> u64 {
        match self.outcome {
            Some(o) if o.header.leg == leg => u64::from(o.last_received),
            _ => self.received.get(&leg).copied().unwrap_or(0),
        }
    }
}

/// Sensor `i`'s summary, made (named after the scenario) on first use.
fn sensor_entry<'a>(
    sensors: &'a mut BTreeMap<u32, SensorSummary>,
    names: &[String],
    i: u32,
) -> &'a mut SensorSummary {
    sensors.entry(i).or_insert_with(|| SensorSummary {
        name: names
            .get(i as usize)
            .cloned()
            .unwrap_or_else(|| format!("sensor {i}")),
        ..SensorSummary::default()
    })
}

/// What the summary counts, message by message: every episode's tally, by
/// episode number, and the messages per channel. Fed from memory
/// ([`summarize`]) or streamed from disk ([`summarize_file`]): it holds a
/// few numbers per episode, never a message.
#[derive(Debug, Default)]
pub struct Tally {
    eps: BTreeMap<u64, EpisodeTally>,
    counts: BTreeMap<String, u64>,
    messages: u64,
}

impl Tally {
    /// An empty tally of the channels of `c`.
    pub fn new(c: &Contents) -> Self {
        Self {
            counts: c.channels.keys().map(|t| (t.clone(), 0)).collect(),
            ..Self::default()
        }
    }

    /// Count one message of the recording `c`.
    pub fn add(&mut self, c: &Contents, m: &recording::RawMessage) -> Result<()> {
        self.messages += 1;
        *self.counts.entry(m.topic.clone()).or_default() += 1;
        if !crate::export::is_etp_channel(c, &m.topic) {
            return Ok(());
        }
        let rec = m
            .decode()
            .at_message(|| format!("message at log time {}", m.log_time))?;
        let h = *rec.header();
        // `hello` and the like belong to no episode.
        if h.episode == u64::MAX {
            return Ok(());
        }
        let e = self.eps.entry(h.episode).or_default();
        e.messages += 1;
        match rec {
            Recorded::Measurement(_) => {
                *e.measurements.entry((h.leg, h.sender)).or_default() += 1;
            }
            Recorded::Ledger(l) => {
                e.ledgers.insert(h.leg, l);
            }
            Recorded::Slot(sl) => {
                *e.attempts.entry((h.leg, h.sender)).or_default() += u64::from(sl.attempts);
            }
            Recorded::Waypoint(w) if h.leg > 0 => {
                e.received.insert(h.leg - 1, u64::from(w.prev_received));
            }
            Recorded::Outcome(o) => e.outcome = Some(o),
            Recorded::Drift(d) => e.drift.push(d),
            _ => {}
        }
        Ok(())
    }
}

/// [`summarize`] of a finished file streamed from disk, one chunk at a time
/// (two passes: the channels and metadata first, then the messages): peak
/// memory does not grow with the messages. The file's contents without
/// its messages are returned beside the summary. `None` when the stream
/// does not read as a sound finished file: the caller reads it whole, which
/// says precisely what is wrong with it (cut, damaged).
pub fn summarize_file(path: &Path) -> Result<Option<(Value, Contents)>> {
    let c = recording::stream_finished(path, |_| -> Result<()> { Ok(()) })?;
    if c.damaged || !c.finished {
        return Ok(None);
    }
    let mut t = Tally::new(&c);
    let again = recording::stream_finished(path, |m| t.add(&c, &m))?;
    if again.damaged || !again.finished {
        return Ok(None);
    }
    Ok(Some((summarize_tally(&c, t)?, c)))
}

/// The channels the summary counts with: `outcome` (episodes, P_tar,
/// P_coll, received), `ledger` (transmissions, energy), `measurement` (the
/// messages beside the ledgers), `waypoint` (received per leg). A copy
/// without one of them (`etp replay filter --topics`) is summarised on what
/// it holds; what needs a missing channel is null and named.
pub const SUMMARY_CHANNELS: [&str; 4] = ["outcome", "ledger", "measurement", "waypoint"];

/// [`SUMMARY_CHANNELS`] that `c` lacks.
pub fn missing_channels(c: &Contents) -> Vec<&'static str> {
    SUMMARY_CHANNELS
        .into_iter()
        .filter(|t| !c.channels.contains_key(*t))
        .collect()
}

/// The identities a complete episode keeps, per sensor: ledger attempts =
/// delivered + lost; `measurement` messages = ledger delivered, and =
/// received unless the episode was degraded (a dead link); attempts
/// recorded in `slot` = ledger attempts (when `slot` is recorded). Each
/// failure, in words. Only identities whose both sides are recorded.
fn identity_failures(
    sensors: &BTreeMap<u32, SensorSummary>,
    degraded: u64,
    has: &dyn Fn(&str) -> bool,
) -> Vec<String> {
    let mut out = Vec::new();
    let (ledger, measurement) = (has("ledger"), has("measurement"));
    let received = has("outcome") && has("waypoint");
    for s in sensors.values() {
        if ledger && s.transmissions != s.delivered + s.lost {
            out.push(format!(
                "{}: its ledgers count {} attempts but {} delivered + {} lost",
                s.name, s.transmissions, s.delivered, s.lost
            ));
        }
        if ledger && measurement && s.measurements != s.delivered {
            out.push(format!(
                "{}: {} measurement messages but {} delivered in its ledgers",
                s.name, s.measurements, s.delivered
            ));
        }
        if ledger && has("slot") && s.attempts_recorded != s.transmissions {
            out.push(format!(
                "{}: {} attempts recorded in its slots but {} in its ledgers",
                s.name, s.attempts_recorded, s.transmissions
            ));
        }
        if received && measurement && degraded == 0 && s.received != s.measurements {
            out.push(format!(
                "{}: {} measurement messages but the agent received {}",
                s.name, s.measurements, s.received
            ));
        }
    }
    out
}

/// The summary object of a recording: complete episodes only (outcome and
/// every ledger recorded); the rest (the episode a crash or Ctrl-C cut) under
/// `partial`. `identities_hold` is false when a count identity fails on the
/// complete episodes (`etp replay` then exits 4).
pub fn summarize(c: &Contents) -> Result<Value> {
    let mut t = Tally::new(c);
    for m in &c.messages {
        t.add(c, m)?;
    }
    summarize_tally(c, t)
}

/// The summary object from the tally of `c`'s messages (see [`summarize`]).
pub fn summarize_tally(c: &Contents, t: Tally) -> Result<Value> {
    let facts = RunFacts::read(c);
    let ledgers_recorded = c.channels.contains_key("ledger");
    let mut totals = tally_episodes(t.eps, ledgers_recorded, &facts);
    let RunFacts { names, per_ep, .. } = facts;
    // Every sensor of the scenario, those that never sent anything included.
    for i in 0..names.len().max(per_ep.len()) {
        sensor_entry(&mut totals.sensors, &names, i as u32);
    }
    for (i, s) in &mut totals.sensors {
        s.predicted_energy = per_ep
            .get(*i as usize)
            .map(|e| crate::vocab::round_energy(e * totals.episodes as f64));
        s.energy = crate::vocab::round_energy(s.energy);
    }
    let has = |t: &str| c.channels.contains_key(t);
    let failures = identity_failures(&totals.sensors, totals.degraded, &has);
    let measurements: u64 = totals.sensors.values().map(|s| s.measurements).sum();
    let ledgers: u64 = totals.sensors.values().map(|s| s.transmissions).sum();
    let delivered: u64 = totals.sensors.values().map(|s| s.delivered).sum();
    let lost: u64 = totals.sensors.values().map(|s| s.lost).sum();
    // What the recording lets us measure (`etp_shared::stats`, the same
    // function as `etp run`'s report: the same numbers on the same episodes).
    let missing = missing_channels(c);
    let outcome_recorded = has("outcome");
    let proportion = |k: u64| {
        outcome_recorded.then_some(Measured::Proportion {
            k,
            n: totals.episodes,
        })
    };
    let measured = Outcomes {
        p_target: proportion(totals.counts.target),
        p_collision: proportion(totals.counts.collision),
        energy: (outcome_recorded && ledgers_recorded).then(|| Measured::mean_of(&totals.energies)),
    };
    let mut unmeasured = Vec::new();
    if !outcome_recorded {
        for k in ["p_target", "p_collision", "energy_mean"] {
            unmeasured.push((k, "the recording has no `outcome` channel".to_string()));
        }
    } else if !ledgers_recorded {
        unmeasured.push((
            "energy_mean",
            "the recording has no `ledger` channel".to_string(),
        ));
    }
    let energy: f64 = totals.sensors.values().map(|s| s.energy).sum();
    let predicted_energy: Option<f64> = if per_ep.is_empty() {
        None
    } else {
        Some(crate::vocab::round_energy(
            per_ep.iter().sum::<f64>() * totals.episodes as f64,
        ))
    };
    let num = |k: &str| {
        c.meta(recording::META_RUN, k)
            .and_then(|v| v.parse::<u64>().ok())
    };
    let strategy: Option<Strategy> = c
        .meta(recording::META_STRATEGY, "json")
        .and_then(|t| Strategy::from_json(t).ok());
    let scenario = c
        .meta(recording::META_RUN, "scenario_name")
        .map(str::to_string)
        .or_else(|| strategy.as_ref().map(|s| s.policy.scenario_name.clone()));
    let mut v = json!({
        "run_id": c.meta(recording::META_RUN, "run_id"),
        "scenario": scenario,
        "seed": num("seed"),
        "strategy": strategy.as_ref().map(|s| s.provenance.label.clone()),
        "delta": strategy.as_ref().and_then(|s| crate::vocab::constant_delta(&s.policy)),
        "predicted": crate::vocab::prediction(strategy.as_ref().and_then(|s| s.predictions.predicted.as_ref())),
        "predicted_ci95": strategy.as_ref().and_then(|s| s.predictions.predicted_ci95).map(|c| json!({
            "p_target": c.p_target, "p_collision": c.p_collision, "energy_mean": c.energy_mean})),
        "prediction_check": crate::vocab::prediction_check(
            strategy.as_ref().and_then(|s| s.predictions.predicted.as_ref()),
            strategy.as_ref().and_then(|s| s.predictions.predicted_ci95.as_ref()),
            &measured,
            &unmeasured,
        ),
        "software_version": c.meta(recording::META_RUN, "software_version"),
        "format_version": num("format_version"),
        "requested_episodes": num("episodes"),
        "finished": c.finished,
        "truncated": c.truncated,
        "messages": t.messages,
        "counts": t.counts,
        "episodes": totals.episodes,
        "degraded_episodes": totals.degraded,
        "partial": {
            "episodes": totals.partial,
            "messages": totals.partial_messages,
            "measurements": totals.partial_measurements,
        },
        "target": totals.counts.target, "collision": totals.counts.collision, "free": totals.counts.free,
        "steps": totals.steps,
        "measurements": measurements,
        "transmissions": ledgers,
        "delivered": delivered,
        "lost": lost,
        "received": totals.received,
        "energy": crate::vocab::round_energy(energy),
        "predicted_energy": predicted_energy,
        "sensors": totals.sensors.values().collect::<Vec<_>>(),
        "drift": drift_records(&totals.drift, &names),
        "identities_hold": failures.is_empty(),
        "identity_failures": failures,
        "missing_channels": missing,
    });
    if let Some(m) = v.as_object_mut() {
        m.extend(crate::vocab::outcome_fields(
            &measured,
            proportion(totals.counts.free),
        ));
    }
    null_what_is_missing(&mut v, &has);
    Ok(v)
}

/// The recorded flags as `etp run --json` reports them (`drift[]`).
fn drift_records(
    flags: &[etp_runtime::wire::agent_to_coordinator::Drift],
    names: &[String],
) -> Vec<etp_runtime::report::DriftRecord> {
    flags
        .iter()
        .filter_map(|d| {
            etp_runtime::report::DriftRecord::from_wire(d, |i| {
                names
                    .get(i as usize)
                    .cloned()
                    .unwrap_or_else(|| format!("sensor {i}"))
            })
        })
        .collect()
}

/// What the recording says of its run beside the messages: the sensors'
/// names and predicted energy per episode (the prediction's metadata), and
/// the scenario (each leg's sensor and its cost).
struct RunFacts {
    names: Vec<String>,
    per_ep: Vec<f64>,
    scenario: Option<etp_shared::scenario::Scenario>,
}

impl RunFacts {
    fn read(c: &Contents) -> Self {
        let prediction: Option<Value> = c
            .meta(recording::META_PREDICTION, "json")
            .and_then(|t| serde_json::from_str(t).ok());
        let names: Vec<String> = prediction
            .as_ref()
            .and_then(|p| p.get("sensors"))
            .and_then(|s| serde_json::from_value(s.clone()).ok())
            .unwrap_or_default();
        let per_ep: Vec<f64> = prediction
            .as_ref()
            .and_then(|p| p.get("sensor_energy_per_episode"))
            .and_then(|s| serde_json::from_value(s.clone()).ok())
            .unwrap_or_default();
        let scenario = c
            .meta(recording::META_SCENARIO, "toml")
            .and_then(|t| etp_shared::scenario::Scenario::from_toml(t).ok());
        Self {
            names,
            per_ep,
            scenario,
        }
    }
}

/// The sums over the recording's complete episodes, and what the
/// incomplete ones (`partial`) held.
struct Totals {
    sensors: BTreeMap<u32, SensorSummary>,
    counts: crate::OutcomeCounts,
    steps: u64,
    received: u64,
    degraded: u64,
    episodes: u64,
    energies: Vec<f64>,
    partial: Vec<u64>,
    partial_messages: u64,
    partial_measurements: u64,
    /// The flags of the complete episodes (as `etp run` reports them).
    drift: Vec<etp_runtime::wire::agent_to_coordinator::Drift>,
}

/// Each complete episode's outcome, measurements, ledgers and energy
/// summed as `etp run` sums them; an episode that did not finish is
/// `partial`.
fn tally_episodes(
    eps: BTreeMap<u64, EpisodeTally>,
    ledgers_recorded: bool,
    facts: &RunFacts,
) -> Totals {
    let (names, scenario) = (&facts.names, &facts.scenario);
    let mut sensors: BTreeMap<u32, SensorSummary> = BTreeMap::new();
    let mut counts = crate::OutcomeCounts::default();
    let (mut steps, mut received, mut degraded) = (0u64, 0u64, 0u64);
    let mut episodes = 0u64;
    let mut energies: Vec<f64> = Vec::new();
    let mut drift = Vec::new();
    let (mut partial, mut partial_messages, mut partial_measurements) = (Vec::new(), 0u64, 0u64);
    let cost_of_leg = |leg: u32| {
        scenario.as_ref().map_or(0.0, |s| {
            s.legs
                .get(leg as usize)
                .and_then(|l| s.sensors.get(l.sensor))
                .map_or(0.0, |x| x.cost)
        })
    };
    // The sensors the run found dead: each is named by the outcome of the
    // episode its link died in (`dead_sensor`), the run's `faults`.
    let dead: std::collections::BTreeSet<u32> = eps
        .values()
        .filter_map(|e| e.outcome)
        .map(|o| o.dead_sensor)
        .filter(|s| *s != u32::MAX)
        .collect();
    let excused = |leg: u32| {
        scenario.as_ref().is_some_and(|s| {
            s.legs
                .get(leg as usize)
                .is_some_and(|l| dead.contains(&(l.sensor as u32)))
        })
    };
    for (number, e) in eps {
        let Some(o) = e.outcome.filter(|_| e.complete(ledgers_recorded, excused)) else {
            partial.push(number);
            partial_messages += e.messages;
            partial_measurements += e.measurements.values().sum::<u64>();
            continue;
        };
        episodes += 1;
        drift.extend(e.drift.iter().copied());
        steps += u64::from(o.steps);
        received += u64::from(o.received);
        let episode_degraded = e.degraded(ledgers_recorded);
        degraded += u64::from(episode_degraded);
        counts.add(&o);
        for ((leg, i), n) in &e.measurements {
            let s = sensor_entry(&mut sensors, names, *i);
            // A degraded episode's legs without a ledger (a dead sensor's
            // open leg and its later ones) are excused, counted apart.
            if ledgers_recorded && !e.ledgers.contains_key(leg) {
                s.measurements_without_ledger += n;
            } else {
                s.measurements += n;
            }
        }
        // The episode's energy as `etp run` sums it, leg by leg in order: a
        // ledger's energy, or on a dead link's leg without one what the agent
        // received there times the sensor's cost.
        let mut energy = 0.0;
        let legs = e
            .ledgers
            .keys()
            .last()
            .copied()
            .unwrap_or(0)
            .max(o.header.leg);
        for leg in 0..=legs {
            let Some(l) = e.ledgers.get(&leg) else {
                if episode_degraded {
                    energy += e.received_of(leg) as f64 * cost_of_leg(leg);
                }
                // `received`, as `etp run` reports it, covers the legs the
                // ledgers cover: what came on an excused leg is apart.
                if ledgers_recorded {
                    received -= e.received_of(leg).min(received);
                }
                continue;
            };
            let i = l.header.sender;
            let s = sensor_entry(&mut sensors, names, i);
            s.transmissions += u64::from(l.transmissions);
            s.delivered += u64::from(l.delivered);
            s.lost += u64::from(l.lost);
            s.attempts_recorded += e.attempts.get(&(leg, i)).copied().unwrap_or(0);
            s.energy += l.energy;
            s.received += e.received_of(leg);
            energy += l.energy;
        }
        energies.push(energy);
    }
    Totals {
        sensors,
        counts,
        steps,
        received,
        degraded,
        episodes,
        energies,
        partial,
        partial_messages,
        partial_measurements,
        drift,
    }
}

/// Null the counts whose channel the recording lacks (a filtered copy):
/// never a 0 that would read as measured.
fn null_what_is_missing(v: &mut Value, has: &dyn Fn(&str) -> bool) {
    // `drift` needs its channel (older recordings have none) and the
    // outcomes that say which episodes are complete.
    let needs: [(&str, &[&str]); 5] = [
        (
            "outcome",
            &[
                "episodes",
                "target",
                "collision",
                "free",
                "steps",
                "received",
                "partial",
                "degraded_episodes",
                "predicted_energy",
                "drift",
            ],
        ),
        ("ledger", &["transmissions", "delivered", "lost", "energy"]),
        ("measurement", &["measurements"]),
        ("waypoint", &[]),
        ("drift", &["drift"]),
    ];
    let per_sensor: [(&str, &[&str]); 4] = [
        ("outcome", &["received", "predicted_energy"]),
        (
            "ledger",
            &[
                "transmissions",
                "delivered",
                "lost",
                "energy",
                "attempts_recorded",
            ],
        ),
        (
            "measurement",
            &["measurements", "measurements_without_ledger"],
        ),
        ("waypoint", &["received"]),
    ];
    for (channel, keys) in needs {
        if has(channel) {
            continue;
        }
        for k in keys {
            v[*k] = Value::Null;
        }
    }
    if let Some(sensors) = v.get_mut("sensors").and_then(Value::as_array_mut) {
        for s in sensors {
            for (channel, keys) in per_sensor {
                if has(channel) {
                    continue;
                }
                for k in keys {
                    s[*k] = Value::Null;
                }
            }
        }
    }
}

pub use text::render;

mod text;

#[cfg(test)]
mod tests;
