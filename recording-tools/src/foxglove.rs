//! `--foxglove OUT`: a copy of a recording that Foxglove draws, in JSON with
//! the official Foxglove JSON schemas (schema encoding `jsonschema`, message
//! encoding `json`, schema names `foxglove.*`), frame `world`:
//!
//! * `/scene` (`foxglove.SceneUpdate`): obstacles, target, route, sensors;
//!   at the start and again at every episode start (same ids: replaced),
//!   so a seek finds it again within one episode.
//! * `/agent` (`SceneUpdate`, one per slot): the true position (from
//!   `sensor/<i>/truth`), coloured orange if the sensor transmitted in that
//!   slot and blue if not, the belief mean and the 3σ ellipse of the
//!   **prior** x̂⁻_k, P⁻_k (the belief the sensor's replica triggered on,
//!   before slot k's update; not sent per step, so recomputed here by the
//!   estimator re-run of `recording::priors`, which `--verify` checks
//!   against every slot's digest).
//! * `/trajectories` (`SceneUpdate`, one per finished episode): the true
//!   path, green target / red collision / grey free; one id per episode, so
//!   they accumulate.
//! * `/transmissions` (`foxglove.Log`, one per `measurement` message) and
//!   `/outcomes` (`foxglove.Log`, one per `outcome`).
//!
//! Times ([`Clock`]): by default a step clock — plant step k of an episode
//! at 10 ms × k after the episode's start, episodes one after another — so
//! Foxglove plays the motion smoothly at 1×. `--foxglove-clock recorded`
//! keeps the recorded `log_time`s instead (when the recorder took the
//! sample; it drains in batches, so a few consecutive slots share one and a
//! whole episode lasts some tens of milliseconds). The copy is written in
//! time order (the source is in drain order).

pub mod geometry;
pub mod map;
mod msg;
mod scene;
#[cfg(test)]
mod tests;

use crate::error::{Context, Error, IoContext, Result};
use etp_runtime::recording::{self, Contents, Recorded};
use etp_runtime::wire::coordinator_to_agent::Control;
use etp_runtime::wire::coordinator_to_sensor::Threshold;
use etp_runtime::wire::{Header, agent_to_coordinator::Outcome, sensor_to_agent::Measurement};
use etp_shared::scenario::Scenario;
use geometry::{block3, point3};
use msg::{Log, Time};
use scene::AgentView;
use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};
use std::io::Write;
use std::path::Path;

pub use scene::SIGMA;

/// Topics of the copy.
pub const SCENE: &str = "/scene";
pub const AGENT: &str = "/agent";
pub const TRAJECTORIES: &str = "/trajectories";
pub const TRANSMISSIONS: &str = "/transmissions";
pub const OUTCOMES: &str = "/outcomes";

/// What was written (`"foxglove"` in `etp replay --json`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct FoxgloveStats {
    /// Messages per topic, and in all.
    pub topics: BTreeMap<String, u64>,
    pub messages: u64,
    /// Episodes with an `outcome` (each has a path on `/trajectories`), and
    /// episodes cut off by the end of the file (drawn, but without a path).
    pub episodes: u64,
    pub incomplete_episodes: u64,
    /// Ellipses are drawn at this many σ of the prior covariance.
    pub sigma: f64,
    /// The times of the copy.
    pub clock: Clock,
    /// Size of the written file.
    pub bytes: u64,
}

/// Which times the copy carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Clock {
    /// Plant step k at 10 ms × k after its episode's start; the
    /// episodes follow each other with one step of gap.
    #[default]
    Step,
    /// The recorder's `log_time`s.
    Recorded,
}

impl Clock {
    /// Every clock's name, as its `FromStr` reads it.
    pub const NAMES: [&'static str; 2] = ["step", "recorded"];
}

impl std::str::FromStr for Clock {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "step" => Ok(Clock::Step),
            "recorded" => Ok(Clock::Recorded),
            other => Err(format!("unknown clock `{other}`: step or recorded")),
        }
    }
}

/// One plant step on the step clock: 10 ms (100 steps per second).
pub const STEP_NS: u64 = 10_000_000;

/// Put the episodes on the step clock, starting at `t0`.
fn retime(eps: &mut BTreeMap<u64, Episode>, t0: u64) {
    let mut offset = 0u64;
    for ep in eps.values_mut() {
        let at = |k: u32| t0.saturating_add((offset + u64::from(k)).saturating_mul(STEP_NS));
        ep.start = Some(at(0));
        for (k, s) in &mut ep.steps {
            s.time = at(*k);
        }
        for (t, m) in &mut ep.measurements {
            *t = at(m.header.step);
        }
        let mut last = ep.steps.keys().next_back().copied().unwrap_or(0);
        if let Some((t, o)) = &mut ep.outcome {
            *t = at(o.header.step);
            last = last.max(o.header.step);
        }
        offset += u64::from(last) + 2;
    }
}

/// One slot of an episode as gathered from its channels.
#[derive(Debug, Clone, Default)]
struct Step {
    view: AgentView,
    /// The serving sensor (index).
    sensor: Option<u32>,
    /// The latest `log_time` of the slot's truth, prior and slot messages.
    time: u64,
}

#[derive(Debug, Clone, Default)]
struct Episode {
    /// `log_time` of the episode's earliest message.
    start: Option<u64>,
    steps: BTreeMap<u32, Step>,
    measurements: Vec<(u64, Measurement)>,
    outcome: Option<(u64, Outcome)>,
    /// δ per leg (the coordinator's `threshold` OPEN).
    deltas: BTreeMap<u32, f64>,
}

fn earliest(slot: &mut Option<u64>, t: u64) {
    *slot = Some(slot.map_or(t, |s| s.min(t)));
}

/// `sensor/<i>/truth` → i.
fn sensor_of_topic(topic: &str) -> Option<u32> {
    use etp_runtime::wire::ServiceId;
    match recording::service_of_topic(topic)? {
        ServiceId::Truth(i) => u32::try_from(i).ok(),
        _ => None,
    }
}

/// The slot `header.step` of an episode, its fields from `header` and the
/// message's time, dimension and sensor.
fn step_of<'a>(
    ep: &'a mut Episode,
    header: &Header,
    t: u64,
    dim: Option<u32>,
    sensor: Option<u32>,
) -> &'a mut Step {
    let s = ep.steps.entry(header.step).or_default();
    s.view.episode = header.episode;
    s.view.step = header.step;
    s.view.leg = header.leg;
    if let Some(d) = dim {
        s.view.dim = d as usize;
    }
    if sensor.is_some() {
        s.sensor = sensor;
    }
    s.time = s.time.max(t);
    s
}

/// Gather the recording by episode and slot.
fn gather(c: &Contents) -> Result<BTreeMap<u64, Episode>> {
    let mut eps: BTreeMap<u64, Episode> = BTreeMap::new();
    for m in &c.messages {
        let rec = m
            .decode()
            .at_message(|| format!("{} message at log time {}", m.topic, m.log_time))?;
        let t = m.log_time;
        let (header, rec) = match rec {
            Recorded::Control(x) if x.kind == Control::START => (x.header, Recorded::Control(x)),
            Recorded::Threshold(x) if x.kind == Threshold::OPEN => {
                (x.header, Recorded::Threshold(x))
            }
            Recorded::Truth(x) => (x.header, Recorded::Truth(x)),
            // The first message of a leg: it only dates the episode's start.
            Recorded::Handover(x) => (x.header, Recorded::Handover(x)),
            Recorded::Slot(x) => (x.header, Recorded::Slot(x)),
            Recorded::Measurement(x) => (x.header, Recorded::Measurement(x)),
            Recorded::Outcome(x) => (x.header, Recorded::Outcome(x)),
            _ => continue,
        };
        let ep = eps.entry(header.episode).or_default();
        earliest(&mut ep.start, t);
        match rec {
            Recorded::Threshold(x) => {
                ep.deltas.insert(header.leg, x.delta);
            }
            Recorded::Truth(x) => {
                let s = step_of(ep, &header, t, Some(x.dim), sensor_of_topic(&m.topic));
                s.view.truth = Some(point3(&x.x, x.dim as usize));
            }
            Recorded::Slot(x) => {
                let s = step_of(ep, &header, t, None, Some(header.sender));
                s.view.transmitted = Some(x.delivered != 0);
            }
            Recorded::Measurement(x) => ep.measurements.push((t, x)),
            Recorded::Outcome(x) => ep.outcome = Some((t, x)),
            _ => {}
        }
    }
    // The agent's prior of every slot, re-run from the recorded inputs
    // (episodes that cannot be re-run, e.g. degraded ones, have none).
    let priors = match recording::priors(c) {
        Ok((_, p)) => p,
        Err(e) => {
            eprintln!("warning: no belief ellipses: the estimator cannot be re-run ({e})");
            Default::default()
        }
    };
    for ((e, k), (dim, mean, cov)) in priors {
        if let Some(s) = eps.get_mut(&e).and_then(|ep| ep.steps.get_mut(&k)) {
            let d = dim as usize;
            s.view.prior = Some((point3(&mean, d), block3(&cov, d.min(3))));
        }
    }
    Ok(eps)
}

/// Sensor names: the scenario's, else the prediction's, else `sensor i`.
fn sensor_names(c: &Contents, s: Option<&Scenario>) -> Vec<String> {
    if let Some(s) = s {
        return s.sensors.iter().map(|x| x.name.clone()).collect();
    }
    c.meta(recording::META_PREDICTION, "json")
        .and_then(|t| serde_json::from_str::<serde_json::Value>(t).ok())
        .and_then(|p| serde_json::from_value(p.get("sensors")?.clone()).ok())
        .unwrap_or_default()
}

fn name_of(names: &[String], i: u32) -> String {
    names
        .get(i as usize)
        .cloned()
        .unwrap_or_else(|| format!("sensor {i}"))
}

/// One message to write: time, topic index, JSON.
type Item = (u64, usize, Vec<u8>);

fn json<T: serde::Serialize>(time: u64, topic: usize, m: &T) -> Result<Item> {
    let data = serde_json::to_vec(m).map_err(|source| Error::Json {
        what: "encoding JSON".into(),
        source,
    })?;
    Ok((time, topic, data))
}

const TOPICS: [(&str, &str); 5] = [
    (SCENE, msg::SCENE_UPDATE),
    (AGENT, msg::SCENE_UPDATE),
    (TRAJECTORIES, msg::SCENE_UPDATE),
    (TRANSMISSIONS, msg::LOG),
    (OUTCOMES, msg::LOG),
];
const T_SCENE: usize = 0;
const T_AGENT: usize = 1;
const T_TRAJ: usize = 2;
const T_TRANS: usize = 3;
const T_OUT: usize = 4;

fn y_text(m: &Measurement) -> String {
    let n = (m.dim as usize).min(m.y.len());
    let parts: Vec<String> = m.y[..n].iter().map(|v| format!("{v:.4}")).collect();
    parts.join(", ")
}

/// The messages of one episode (the map first).
fn episode_items(
    e: u64,
    ep: &Episode,
    names: &[String],
    scenario: Option<&Scenario>,
    scene_time: u64,
) -> Result<Vec<Item>> {
    let mut items = Vec::new();
    if let Some(s) = scenario {
        let t = scene_time;
        items.push(json(t, T_SCENE, &scene::scene(s, Time::from_ns(t)))?);
    }
    let mut path = Vec::with_capacity(ep.steps.len());
    for s in ep.steps.values() {
        let mut view = s.view.clone();
        view.sensor = s.sensor.map(|i| name_of(names, i));
        view.delta = ep.deltas.get(&view.leg).copied();
        if let Some(x) = view.truth {
            path.push(x);
        }
        items.push(json(
            s.time,
            T_AGENT,
            &scene::agent(&view, Time::from_ns(s.time)),
        )?);
    }
    for (t, m) in &ep.measurements {
        let h = m.header;
        let name = name_of(names, h.sender);
        let log = Log {
            timestamp: Time::from_ns(*t),
            level: msg::INFO,
            message: format!(
                "{name} transmitted: episode {e} step {} leg {} (#{} this episode) y = [{}]",
                h.step,
                h.leg,
                m.sequence,
                y_text(m)
            ),
            name,
            file: "",
            line: 0,
        };
        items.push(json(*t, T_TRANS, &log)?);
    }
    if let Some((t, o)) = &ep.outcome {
        let ts = Time::from_ns(*t);
        let level = match o.outcome {
            Outcome::TARGET => msg::INFO,
            Outcome::FREE => msg::WARNING,
            _ => msg::ERROR,
        };
        let log = Log {
            timestamp: ts,
            level,
            message: format!(
                "episode {e}: {} after {} steps, {} of {} slots transmitted{}",
                scene::outcome_name(o.outcome),
                o.steps,
                o.received,
                o.slots,
                if o.degraded != 0 {
                    format!(" (degraded: {} dead slots)", o.dead_slots)
                } else {
                    String::new()
                }
            ),
            name: "agent".into(),
            file: "",
            line: 0,
        };
        items.push(json(*t, T_OUT, &log)?);
        items.push(json(
            *t,
            T_TRAJ,
            &scene::trajectory(e, &path, o.outcome, ts),
        )?);
    }
    Ok(items)
}

/// Write the Foxglove copy of a recording to `out` (through a temporary
/// sibling renamed into place, like `--repair`).
pub fn write_foxglove(c: &Contents, out: &Path, clock: Clock) -> Result<FoxgloveStats> {
    let scenario = match c.meta(recording::META_SCENARIO, "toml") {
        Some(text) => Some(Scenario::from_toml(text).map_err(|source| Error::Scenario {
            what: "the recording's scenario (metadata etp.scenario)".into(),
            source,
        })?),
        None => {
            eprintln!("warning: the recording holds no scenario: no map on {SCENE}");
            None
        }
    };
    let names = sensor_names(c, scenario.as_ref());
    let mut eps = gather(c)?;
    if clock == Clock::Step {
        retime(
            &mut eps,
            c.messages.iter().map(|m| m.log_time).min().unwrap_or(0),
        );
    }
    let mut stats = etp_files::write::write_via_temp(out, |tmp| {
        write_file(c, tmp, scenario.as_ref(), &names, &eps, clock)
    })?;
    stats.bytes = std::fs::metadata(out)
        .doing(|| format!("reading the size of {}", out.display()))?
        .len();
    Ok(stats)
}

fn write_file(
    c: &Contents,
    tmp: &Path,
    scenario: Option<&Scenario>,
    names: &[String],
    eps: &BTreeMap<u64, Episode>,
    clock: Clock,
) -> Result<FoxgloveStats> {
    // The source's metadata (run, scenario, strategy) travels along, with a
    // note on what the drawing means.
    let mut w = crate::copy_writer(c, tmp, "", "--foxglove")?;
    w.write_metadata(&mcap::records::Metadata {
        name: "etp.foxglove".into(),
        metadata: BTreeMap::from([
            ("frame".into(), msg::FRAME.into()),
            (
                "ellipse".into(),
                format!("{SIGMA} sigma of the prior covariance (before the slot's update)"),
            ),
            (
                "agent_color".into(),
                "orange: the sensor transmitted in this slot; blue: silent".into(),
            ),
        ]),
    })?;
    let scene_schema = w.add_schema(
        msg::SCENE_UPDATE,
        "jsonschema",
        msg::SCENE_UPDATE_SCHEMA.as_bytes(),
    )?;
    let log_schema = w.add_schema(msg::LOG, "jsonschema", msg::LOG_SCHEMA.as_bytes())?;
    let mut ids = Vec::with_capacity(TOPICS.len());
    for (topic, schema) in TOPICS {
        let sid = if schema == msg::LOG {
            log_schema
        } else {
            scene_schema
        };
        ids.push(w.add_channel(sid, topic, "json", &BTreeMap::new())?);
    }
    let mut seq = [0u32; TOPICS.len()];
    let mut stats = FoxgloveStats {
        topics: TOPICS.iter().map(|(t, _)| (t.to_string(), 0)).collect(),
        messages: 0,
        episodes: 0,
        incomplete_episodes: 0,
        sigma: SIGMA,
        clock,
        bytes: 0,
    };
    let mut write = |w: &mut mcap::Writer<_>, (time, topic, data): Item| -> Result<()> {
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ids[topic],
                sequence: seq[topic],
                log_time: time,
                publish_time: time,
            },
            &data,
        )?;
        seq[topic] = seq[topic].wrapping_add(1);
        *stats.topics.entry(TOPICS[topic].0.to_string()).or_default() += 1;
        stats.messages += 1;
        Ok(())
    };
    let first = c.messages.iter().map(|m| m.log_time).min();
    if eps.is_empty()
        && let Some(s) = scenario
    {
        // No episode: the map alone, at the start of the file.
        let t = first.unwrap_or(0);
        write(
            &mut w,
            json(t, T_SCENE, &scene::scene(s, Time::from_ns(t)))?,
        )?;
    }
    // Episodes overlap at their ends: the recorder drains its channels in
    // batches, so the last slots of one episode can be stamped after the
    // first message of the next. Items wait in a heap until no later
    // episode can have an earlier one, so the file is in time order.
    let starts: Vec<u64> = eps.values().map(|ep| ep.start.unwrap_or(0)).collect();
    let mut later_min = vec![u64::MAX; starts.len() + 1];
    for i in (0..starts.len()).rev() {
        later_min[i] = later_min[i + 1].min(starts[i]);
    }
    let mut pending = BinaryHeap::new();
    let mut order = 0u64;
    for (i, (e, ep)) in eps.iter().enumerate() {
        // The first map is at the very start of the file, so it is on
        // screen from the first frame.
        let scene_time = if i == 0 {
            first.map_or(starts[i], |f| f.min(starts[i]))
        } else {
            starts[i]
        };
        for (time, topic, data) in episode_items(*e, ep, names, scenario, scene_time)? {
            pending.push(Reverse((time, order, topic, data)));
            order += 1;
        }
        while pending
            .peek()
            .is_some_and(|Reverse(top)| top.0 < later_min[i + 1])
        {
            if let Some(Reverse((time, _, topic, data))) = pending.pop() {
                write(&mut w, (time, topic, data))?;
            }
        }
    }
    while let Some(Reverse((time, _, topic, data))) = pending.pop() {
        write(&mut w, (time, topic, data))?;
    }
    let (done, cut) = eps.values().fold((0, 0), |(d, u), ep| {
        if ep.outcome.is_some() {
            (d + 1, u)
        } else {
            (d, u + 1)
        }
    });
    stats.episodes = done;
    stats.incomplete_episodes = cut;
    w.finish().map_err(|source| Error::Mcap {
        what: "finishing the Foxglove copy".into(),
        source,
    })?;
    let mut inner = w.into_inner();
    inner
        .flush()
        .doing(|| "flushing the Foxglove copy".into())?;
    drop(inner);
    Ok(stats)
}
