//! `etp replay verify`: re-run the agent's estimator on a recording and
//! check that it reproduces every recorded belief bit for bit.
//!
//! The estimator's inputs are all in the file: the scenario (metadata), the
//! threshold δ of each leg (`threshold` OPEN), the transmitted measurements
//! (`measurement`) and the closed slots (`slot`). From the initial belief
//! (x̂₀, P₀) the re-run applies docs/MODEL.md §3 through the agent's own step
//! (`episode::AgentCore`: input from the posterior, prior, the slot's
//! update, the leg's end rule; the world is the recording, a collision is
//! where the recorded outcome puts it) and compares, with `f64::to_bits`, every belief
//! the agent published — the posterior at each decision point (`waypoint`)
//! and the belief handed over to the serving sensor (`sensor/<i>/handover`) —
//! and, through `episode::belief_digest`, the prior the sensor's replica
//! triggered on in every slot (`slot.prior_digest`). It also checks that legs
//! and episodes end at the recorded steps. [`priors`] gives the re-run's
//! prior of every slot (what the agent believed, for drawing).
//!
//! The radio (docs/MODEL.md §8) is re-drawn too: every slot that recorded
//! attempts gets its fate drawn again from the sensor link's own stream
//! (`LinkChannel::of_episode` with stream `AGENT`, the seed from the
//! episode's `control`), which must give the recorded attempts and delivery;
//! a silence after lost attempts is re-run with the radio's silence factor
//! ([`CompiledScenario::silence_beta`]), bit for bit.
//!
//! So is the sensor's decision: from the recorded true state of each slot
//! (`sensor/<i>/truth`) and the run's seed, the re-run measures again and
//! decides again with the scenario's trigger family
//! ([`CompiledScenario::redecide_slot`]: the same noise, and for the
//! stochastic family the same draw, as the sensor process took); the
//! decision must be the slot's (sent iff it made attempts) and a delivered
//! measurement must have the recorded bits.
//!
//! The channel monitor's flags (`drift`) are raised again from the recorded
//! slots and must be the recorded ones, bit for bit (`drift`).
//!
//! Degraded episodes (a dead link) are skipped and counted: whether a late
//! slot was taken as closed or dead depended on wall-clock timing the file
//! does not hold. An episode cut by the end of an unfinished file is checked
//! up to its last complete slot and counted as incomplete.

mod drift;
mod slot;

use super::{
    META_CHANNEL_SCHEDULE, META_RUN, META_SCENARIO, Recorded, RecordingError, read::Contents,
};
use crate::wire::agent_to_coordinator::{Drift, Outcome, Waypoint};
use crate::wire::agent_to_sensor::{Handover, Truth};
use crate::wire::coordinator_to_agent::Control;
use crate::wire::coordinator_to_sensor::Threshold;
use crate::wire::sensor_to_agent::{Measurement, Slot};
use crate::wire::{WireMat, WireVec, belief_to_wire};
use etp_shared::episode::{AgentCore, Begun, CompiledScenario, SlotOutcome, World};
use etp_shared::etkf::{Belief, Vector};
use etp_shared::radio::schedule::ChannelSchedule;
use etp_shared::scenario::Scenario;
use slot::{SlotAt, Stop};
use std::collections::BTreeMap;

/// Mismatches kept in the report (the count is always exact).
const MAX_LISTED: usize = 50;

/// One belief (or end of leg) the re-run did not reproduce.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Mismatch {
    pub episode: u64,
    pub leg: u32,
    pub step: u32,
    /// What differs (`prior`, `belief at waypoint`, `end of leg`, …).
    pub what: String,
    /// Largest absolute difference over mean and covariance entries (0 when
    /// the mismatch is not numeric).
    pub max_abs_diff: f64,
}

/// What `verify` checked and found.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct VerifyReport {
    /// Episodes with an outcome, re-run to their end.
    pub episodes_checked: u64,
    /// Episodes cut by the end of an unfinished file (checked as far as recorded).
    pub episodes_incomplete: u64,
    /// Episodes with a dead link, not re-run.
    pub episodes_degraded_skipped: u64,
    /// Slots whose replica prior digest (the sensor's) equals the re-run's prior.
    pub priors_checked: u64,
    /// Recorded handovers (belief at the start of a leg, to its sensor) reproduced bit for bit.
    pub handovers_checked: u64,
    /// Recorded decision-point beliefs reproduced bit for bit.
    pub waypoints_checked: u64,
    /// Plant steps re-run through their slot (`explicit_updates +
    /// implicit_updates`; the step a collision ends has no slot).
    pub steps: u64,
    /// Steps a recorded collision ended: re-run up to the collision, which
    /// comes before the step's slot, so they have none. `steps +
    /// collision_steps` are the steps of the episodes re-run, as the
    /// summary counts them.
    pub collision_steps: u64,
    /// Explicit updates (recorded measurements) and implicit updates (silent slots).
    pub explicit_updates: u64,
    pub implicit_updates: u64,
    /// Transmission attempts re-drawn from the radio's stream and found as
    /// recorded (`slot.attempts`), and of those the lost ones.
    pub attempts_redrawn: u64,
    pub lost_redrawn: u64,
    /// Slots whose sensor decision (and delivered measurement) was re-drawn
    /// from the recorded true state and found as recorded.
    pub decisions_checked: u64,
    /// The channel monitor's recorded flags raised again, bit for bit, by
    /// the monitor fed the recorded slots (`None`: the recording does not
    /// say the monitor's false-alarm rate, as recordings before it did not).
    pub drift_flags_reproduced: Option<u64>,
    pub mismatch_count: u64,
    /// The first mismatches (at most 50), in episode order.
    pub mismatches: Vec<Mismatch>,
}

impl VerifyReport {
    /// True when beliefs were checked and every one was reproduced exactly.
    pub fn passed(&self) -> bool {
        self.mismatch_count == 0 && self.priors_checked + self.waypoints_checked > 0
    }

    fn mismatch(&mut self, m: Mismatch) {
        self.mismatch_count += 1;
        if self.mismatches.len() < MAX_LISTED {
            self.mismatches.push(m);
        }
    }

    /// Count one re-run episode by how it ended.
    fn count(&mut self, ended: Result<Ended, Mismatch>) {
        match ended {
            Ok(Ended::Done) => self.episodes_checked += 1,
            Ok(Ended::Cut) => self.episodes_incomplete += 1,
            Err(m) => {
                self.episodes_checked += 1;
                self.mismatch(m);
            }
        }
    }
}

/// The recorded inputs and outputs of the agent's estimator in one episode.
#[derive(Debug, Default)]
struct EpisodeRecord {
    control: Option<Control>,
    /// Leg → the agent's belief at that decision point.
    waypoints: BTreeMap<u32, Waypoint>,
    /// Leg → δ opened by the coordinator.
    opens: BTreeMap<u32, f64>,
    /// Leg → belief handed over to its serving sensor.
    handovers: BTreeMap<u32, Handover>,
    measurements: BTreeMap<u32, Measurement>,
    slots: BTreeMap<u32, Slot>,
    /// Step → the true state the agent sent the serving sensor.
    truths: BTreeMap<u32, Truth>,
    outcome: Option<Outcome>,
    /// The channel monitor's flags, in the order published.
    drift: Vec<Drift>,
    /// Two messages of one kind for one step or leg.
    duplicate: Option<String>,
}

fn insert<T>(map: &mut BTreeMap<u32, T>, key: u32, v: T, dup: &mut Option<String>, what: &str) {
    if map.insert(key, v).is_some() && dup.is_none() {
        *dup = Some(format!("two `{what}` messages for {key}"));
    }
}

/// The messages of each episode, and the first episode that a cut file may
/// hold only in part: the smallest, over the streams verify reads (one per
/// channel and sender), of the last episode recorded on it. Each stream of a
/// cut file is a prefix of what was published, but the recorder drains the
/// streams at different moments, so one may stop an episode or more before
/// another (a `slot` stream was seen an episode behind `measurement`); an
/// episode before the horizon is whole on every stream.
fn group(c: &Contents) -> Result<(BTreeMap<u64, EpisodeRecord>, u64), RecordingError> {
    let mut eps: BTreeMap<u64, EpisodeRecord> = BTreeMap::new();
    let mut last_of_stream: BTreeMap<(&str, u32), u64> = BTreeMap::new();
    for m in &c.messages {
        let rec = m.decode()?;
        let header = match &rec {
            Recorded::Control(x) => Some(x.header),
            Recorded::Threshold(x) => Some(x.header),
            Recorded::Handover(x) => Some(x.header),
            Recorded::Measurement(x) => Some(x.header),
            Recorded::Slot(x) => Some(x.header),
            Recorded::Truth(x) => Some(x.header),
            Recorded::Waypoint(x) => Some(x.header),
            Recorded::Outcome(x) => Some(x.header),
            _ => None,
        };
        if let Some(h) = header {
            let last = last_of_stream.entry((&m.topic, h.sender)).or_default();
            *last = (*last).max(h.episode);
        }
        let r = match &rec {
            Recorded::Control(x) if x.kind == Control::START => eps.entry(x.header.episode),
            Recorded::Threshold(x) if x.kind == Threshold::OPEN => eps.entry(x.header.episode),
            Recorded::Handover(x) => eps.entry(x.header.episode),
            Recorded::Measurement(x) => eps.entry(x.header.episode),
            Recorded::Slot(x) => eps.entry(x.header.episode),
            Recorded::Truth(x) => eps.entry(x.header.episode),
            Recorded::Waypoint(x) => eps.entry(x.header.episode),
            Recorded::Outcome(x) => eps.entry(x.header.episode),
            Recorded::Drift(x) => eps.entry(x.header.episode),
            _ => continue,
        }
        .or_default();
        let dup = &mut r.duplicate;
        match rec {
            Recorded::Control(x) => r.control = Some(x),
            Recorded::Threshold(x) => insert(&mut r.opens, x.header.leg, x.delta, dup, "open"),
            Recorded::Handover(x) => insert(&mut r.handovers, x.header.leg, x, dup, "handover"),
            Recorded::Measurement(x) => {
                insert(&mut r.measurements, x.header.step, x, dup, "measurement");
            }
            Recorded::Slot(x) => insert(&mut r.slots, x.header.step, x, dup, "slot"),
            Recorded::Truth(x) => insert(&mut r.truths, x.header.step, x, dup, "truth"),
            Recorded::Waypoint(x) => insert(&mut r.waypoints, x.header.leg, x, dup, "waypoint"),
            Recorded::Outcome(x) => r.outcome = Some(x),
            Recorded::Drift(x) => r.drift.push(x),
            _ => {}
        }
    }
    let horizon = last_of_stream.values().copied().min().unwrap_or(0);
    Ok((eps, horizon))
}

/// Re-run the estimator of every episode of a recording (see the module doc).
pub fn verify(c: &Contents) -> Result<VerifyReport, RecordingError> {
    verify_with(c, &mut |_, _, _, _| {})
}

/// The agent's prior (dim, mean, cov) of every re-run slot, by (episode,
/// step), with the verification report: the recording holds the estimator's
/// inputs, not its per-step outputs (the sensors compute those themselves).
pub fn priors(c: &Contents) -> Result<(VerifyReport, PriorTable), RecordingError> {
    let mut table = PriorTable::new();
    let report = verify_with(c, &mut |e, k, dim, (mean, cov)| {
        table.insert((e, k), (dim, mean, cov));
    })?;
    Ok((report, table))
}

/// (episode, step) → (dim, mean, cov) of the agent's prior.
pub type PriorTable = BTreeMap<(u64, u32), (u32, WireVec, WireMat)>;

/// Where the re-run reports each prior: (episode, step, dim, (mean, cov)).
type PriorSink<'a> = dyn FnMut(u64, u32, u32, (WireVec, WireMat)) + 'a;

fn verify_with(c: &Contents, sink: &mut PriorSink<'_>) -> Result<VerifyReport, RecordingError> {
    let text = c
        .meta(META_SCENARIO, "toml")
        .ok_or_else(|| RecordingError::Metadata(format!("no `{META_SCENARIO}` record")))?;
    let scenario = Scenario::from_toml(text)
        .map_err(|e| RecordingError::Metadata(format!("the recorded scenario: {e}")))?;
    let schedule = match c.meta(META_CHANNEL_SCHEDULE, "toml") {
        None => ChannelSchedule::default(),
        Some(text) => {
            let names: Vec<String> = scenario.sensors.iter().map(|s| s.name.clone()).collect();
            ChannelSchedule::parse(text, META_CHANNEL_SCHEDULE, &scenario.radio, &names).map_err(
                |e| RecordingError::Metadata(format!("the recorded channel schedule: {e}")),
            )?
        }
    };
    let (episodes, horizon) = group(c)?;
    // Was the recording cut (recorder killed)? Then the episodes from the
    // horizon on (see `group`) may miss messages.
    let outcomes = episodes.values().filter(|r| r.outcome.is_some()).count() as u64;
    let cut = match c
        .meta(META_RUN, "episodes")
        .and_then(|t| t.parse::<u64>().ok())
    {
        Some(requested) => outcomes < requested,
        None => !c.finished,
    };
    let mut report = VerifyReport::default();
    etp_shared::with_dim!(scenario.dim, N => {
        let compiled = CompiledScenario::<N>::new(&scenario);
        for (e, r) in &episodes {
            if r.outcome.is_some_and(|o| o.degraded != 0) {
                report.episodes_degraded_skipped += 1;
                continue;
            }
            let may_be_cut = cut && *e >= horizon;
            let ended = rerun(&compiled, &schedule, *e, r, may_be_cut, &mut report, sink);
            report.count(ended);
        }
    });
    let false_alarm = c
        .meta(META_RUN, "drift_false_alarm")
        .and_then(|t| t.parse::<f64>().ok());
    let requested = c
        .meta(META_RUN, "episodes")
        .and_then(|t| t.parse::<u64>().ok());
    if let (Some(false_alarm), Some(requested)) = (false_alarm, requested) {
        let config = etp_shared::drift::MonitorConfig {
            false_alarm,
            episodes: requested,
        };
        drift::check(
            &scenario,
            config,
            &episodes,
            cut.then_some(horizon),
            &mut report,
        );
    }
    Ok(report)
}

/// `None` if `b` has exactly the recorded bits, else the largest difference.
fn differs<const N: usize>(b: &Belief<N>, dim: u32, mean: &WireVec, cov: &WireMat) -> Option<f64> {
    if dim as usize != N {
        return Some(f64::INFINITY);
    }
    let mut same = true;
    let mut worst = 0.0f64;
    for r in 0..N {
        let pairs = std::iter::once((b.mean[r], mean[r]))
            .chain((0..N).map(|col| (b.cov[(r, col)], cov[r][col])));
        for (ours, theirs) in pairs {
            if ours.to_bits() != theirs.to_bits() {
                same = false;
                worst = worst.max((ours - theirs).abs());
            }
        }
    }
    (!same).then_some(worst)
}

/// The re-run's world: no true state, only where the recorded outcome puts
/// a collision (the episode step of a recorded collision).
struct RecordedWorld {
    collision_at: Option<u32>,
}

impl<const N: usize> World<N> for RecordedWorld {
    type Collision = ();
    fn moved(&mut self, _: &CompiledScenario<N>, _: &Vector<N>, step: u32) -> Option<()> {
        (self.collision_at == Some(step)).then_some(())
    }
}

enum Ended {
    /// Re-run to the recorded outcome (possibly with a mismatch).
    Done,
    /// The file ends inside this episode.
    Cut,
}

/// The end of a leg at step `k` (`ends`: the estimator ends it there)
/// against the step the record ends it at, if in the file: what differs.
fn leg_end_differs(recorded_end: Option<u32>, ends: bool, k: u32) -> Option<String> {
    match recorded_end {
        Some(end) if ends && end != k => Some(format!(
            "the estimator ends the leg here, the record at step {end}"
        )),
        Some(end) if !ends && end == k => {
            Some("the record ends the leg here, the estimator does not".into())
        }
        _ => None,
    }
}

fn rerun<const N: usize>(
    c: &CompiledScenario<N>,
    schedule: &ChannelSchedule,
    episode: u64,
    r: &EpisodeRecord,
    may_be_cut: bool,
    rep: &mut VerifyReport,
    sink: &mut PriorSink<'_>,
) -> Result<Ended, Mismatch> {
    let miss = |leg: u32, step: u32, what: String, d: f64| Mismatch {
        episode,
        leg,
        step,
        what,
        max_abs_diff: d,
    };
    // A message the agent must have published is not in the file.
    let missing = |leg: u32, step: u32, what: &str| {
        if may_be_cut {
            Ok(Ended::Cut)
        } else {
            Err(miss(leg, step, what.to_string(), 0.0))
        }
    };
    if let Some(d) = &r.duplicate {
        return Err(miss(0, 0, d.clone(), 0.0));
    }
    let mut belief = c.initial;
    if let Some(ctrl) = &r.control
        && let Some(d) = differs(&belief, ctrl.dim, &ctrl.initial_mean, &ctrl.initial_cov)
    {
        return Err(miss(0, 0, "initial belief (control)".into(), d));
    }
    let outcome = r.outcome;
    let mut channels = slot::Channels::new(schedule);
    let mut k: u32 = 0;
    let legs = c.legs.len() as u32;
    for leg in 0..legs {
        let Some(wp) = r.waypoints.get(&leg) else {
            return missing(leg, k, "no waypoint recorded for this leg");
        };
        // A belief the agent published at this decision point: at step k,
        // with exactly the re-run's bits.
        let same = |what: &str, step: u32, dim: u32, mean: &WireVec, cov: &WireMat| {
            if step != k {
                return Err(miss(leg, k, format!("{what} recorded at step {step}"), 0.0));
            }
            match differs(&belief, dim, mean, cov) {
                Some(d) => Err(miss(leg, k, what.to_string(), d)),
                None => Ok(()),
            }
        };
        same(
            "belief at waypoint",
            wp.header.step,
            wp.dim,
            &wp.mean,
            &wp.cov,
        )?;
        rep.waypoints_checked += 1;
        let Some(&delta) = r.opens.get(&leg) else {
            return missing(leg, k, "no threshold opened this leg");
        };
        let sensor = c.legs[leg as usize].sensor;
        let Some(h) = r.handovers.get(&leg) else {
            return missing(leg, k, "no handover recorded for this leg");
        };
        same("belief handed over", h.header.step, h.dim, &h.mean, &h.cov)?;
        rep.handovers_checked += 1;
        // The step at which the record ends this leg, if it is in the file.
        let recorded_end = match (r.waypoints.get(&(leg + 1)), outcome) {
            (Some(next), _) => Some(next.header.step),
            (None, Some(o)) if o.header.leg == leg => Some(o.header.step),
            _ => None,
        };
        let mut core = AgentCore::for_delta(c, leg as usize, delta, belief, k);
        // The leg's slot number (the periodic family decides on it).
        let mut slot_in_leg: u32 = 0;
        let mut world = RecordedWorld {
            collision_at: outcome
                .filter(|o| o.outcome == Outcome::COLLISION)
                .map(|o| o.header.step),
        };
        loop {
            // MODEL.md §3 in the agent's order (the agent's own step): input,
            // the move (a recorded collision ends the episode before the
            // slot), prediction; then the slot as recorded.
            let begun = core.begin(c, &mut world);
            k = core.step();
            let open = match begun {
                Begun::Slot(open) => open,
                // The re-run collides only at the recorded collision's step:
                // the record must put it in this leg.
                Begun::Collided(()) => match outcome.map_or(leg, |o| o.header.leg) {
                    at_leg if at_leg == leg => {
                        rep.collision_steps += 1;
                        return Ok(Ended::Done);
                    }
                    at_leg => {
                        let what = format!("collision recorded in leg {at_leg}");
                        return Err(miss(leg, k, what, 0.0));
                    }
                },
            };
            let prior = *open.prior();
            sink(episode, k, N as u32, belief_to_wire(&prior));
            let at = SlotAt {
                episode,
                leg,
                k,
                sensor,
                delta,
                slot_in_leg,
                prior: &prior,
                reference: core.reference(),
            };
            let checked = match slot::check(c, r, &at, &mut channels, rep) {
                Ok(checked) => checked,
                Err(Stop::Mismatch(m)) => return Err(m),
                Err(Stop::Missing(what)) => return missing(leg, k, what),
            };
            slot_in_leg += 1;
            let slot = match checked.measurement {
                Some(m) => SlotOutcome::Transmitted(&m.y[..]),
                None => SlotOutcome::Silent,
            };
            let ends = core.close(c, open, slot);
            belief = *core.posterior();
            if let Some(what) = leg_end_differs(recorded_end, ends, k) {
                return Err(miss(leg, k, what, 0.0));
            }
            if ends {
                break;
            }
        }
        if leg + 1 == legs {
            return match outcome {
                None => missing(leg, k, "no outcome recorded"),
                Some(o) if o.outcome != Outcome::COLLISION && o.header.step == k => Ok(Ended::Done),
                Some(o) => Err(miss(
                    leg,
                    k,
                    format!("outcome {} recorded at step {}", o.outcome, o.header.step),
                    0.0,
                )),
            };
        }
    }
    Ok(Ended::Done)
}
