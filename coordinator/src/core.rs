//! What the coordinator decides, as pure functions of its state: no ports,
//! no clock, no waiting. [`crate::session`] is the thin iceoryx2 adapter
//! around it (send, wait, take), so every decision here is unit-tested
//! without processes.
//!
//! The decisions: who has said hello ([`RollCall`]); at each decision point
//! of an episode, which leg to close and which δ to open at which sensor
//! (the strategy's ω for the agent's covariance, the uniform number from
//! `streams::COORDINATOR`); the episode's record from the agent's outcome;
//! which sensors' ledgers are still missing; and the run report, where each
//! leg's ledger is joined to the agent's counts (a leg without one is
//! priced at what the agent received, and degrades its episode).

use crate::CoordinatorError;
use etp_runtime::report::{
    DriftRecord, EpisodeRecord, FaultRecord, LegRecord, RunReport, SensorTotals,
};
use etp_runtime::wire::agent_to_coordinator::{Drift, Outcome, Waypoint};
use etp_runtime::wire::sensor_to_coordinator::Ledger;
use etp_runtime::wire::{Header, OutcomeCode, SENDER_AGENT};
use etp_shared::rng::{SimRng, stream_rng, streams};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Policy;
use nalgebra::DMatrix;
use rand::RngExt;
use std::collections::HashMap;

/// Who has said hello.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RollCall {
    tag: u64,
    agent: bool,
    sensors: Vec<bool>,
}

impl RollCall {
    /// For a run of tag `tag` with `sensors` sensors.
    pub fn new(tag: u64, sensors: usize) -> Self {
        Self {
            tag,
            agent: false,
            sensors: vec![false; sensors],
        }
    }

    /// A hello's header (another run's, or an unknown sender's, is ignored).
    pub fn on_hello(&mut self, h: &Header) {
        if h.run != self.tag {
            return;
        }
        if h.sender == SENDER_AGENT {
            self.agent = true;
        } else if let Some(seen) = self.sensors.get_mut(h.sender as usize) {
            *seen = true;
        }
    }

    pub fn all_present(&self) -> bool {
        self.agent && self.sensors.iter().all(|&x| x)
    }

    /// The names of who has not said hello (the agent first).
    pub fn missing(&self, scenario: &Scenario) -> Vec<String> {
        let agent = (!self.agent).then(|| "agent".to_string());
        let sensors = self
            .sensors
            .iter()
            .zip(&scenario.sensors)
            .filter(|(seen, _)| !**seen)
            .map(|(_, s)| s.name.clone());
        agent.into_iter().chain(sensors).collect()
    }
}

/// A leg of an episode at its sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LegAt {
    pub episode: u64,
    pub leg: u32,
    pub sensor: u32,
}

/// What to send at a decision point: close the previous leg (from leg 1
/// on), open this one at δ = `deltas[delta_index]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Opening {
    pub close: Option<LegAt>,
    pub open: LegAt,
    pub delta_index: u32,
    pub delta: f64,
}

/// One thing the coordinator does at a decision point, in
/// [`Opening::sends`]' order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Send {
    /// A CLOSE of the leg on its sensor's `threshold` service.
    Close(LegAt),
    /// The OPEN of the leg on its sensor's `threshold` service.
    Open(LegAt),
    /// The sensor's wake-up event.
    WakeSensor(u32),
    /// The agent's wake-up event.
    WakeAgent,
}

impl Send {
    /// Closing leg `at`: its CLOSE, then its sensor's wake-up (the sensor
    /// answers with its ledger) — at a decision point and at an episode's end.
    pub fn closing(at: LegAt) -> [Send; 2] {
        [Send::Close(at), Send::WakeSensor(at.sensor)]
    }
}

impl Opening {
    /// The sends of this decision point, in order. Every `threshold` is
    /// followed by its sensor's wake-up: the service has two readers (the
    /// sensor and the agent) and iceoryx2 hands a sample to them one after
    /// the other, so the agent can read the OPEN, hand over and send the
    /// leg's first truth (waking the sensor) before the OPEN is in the
    /// sensor's queue. The sensor then keeps that truth until its leg
    /// opens, and only a wake-up after the OPEN makes it look again; the
    /// agent waits for the slot meanwhile (docs/MODEL.md §3, "a wake-up
    /// after every message a reader may wait for").
    pub fn sends(&self) -> Vec<Send> {
        let mut sends = Vec::with_capacity(5);
        if let Some(prev) = self.close {
            sends.extend(Send::closing(prev));
        }
        sends.extend([
            Send::Open(self.open),
            Send::WakeSensor(self.open.sensor),
            Send::WakeAgent,
        ]);
        sends
    }
}

/// The episode in progress.
#[derive(Debug)]
struct Running {
    episode: u64,
    /// The uniform numbers of the δ draws.
    rng: SimRng,
    legs: Vec<LegRecord>,
}

/// The coordinator's state between messages.
#[derive(Debug)]
pub struct CoordinatorCore<'a> {
    scenario: &'a Scenario,
    policy: &'a Policy,
    seed: u64,
    tag: u64,
    running: Option<Running>,
    records: Vec<EpisodeRecord>,
    faults: Vec<FaultRecord>,
    ledgers: HashMap<(u64, u32), Ledger>,
    /// The channel monitor's flags, as the agent raised them.
    drift: Vec<DriftRecord>,
}

impl<'a> CoordinatorCore<'a> {
    /// The run of tag `tag` (messages of other runs are ignored) under
    /// `policy` with run seed `seed`.
    pub fn new(scenario: &'a Scenario, policy: &'a Policy, seed: u64, tag: u64) -> Self {
        Self {
            scenario,
            policy,
            seed,
            tag,
            running: None,
            records: Vec::new(),
            faults: Vec::new(),
            drift: Vec::new(),
            ledgers: HashMap::new(),
        }
    }

    /// The run seed (every process's streams derive from it).
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Episodes recorded so far.
    pub fn finished(&self) -> usize {
        self.records.len()
    }

    /// Episode `episode` starts (its δ draws from its own stream).
    pub fn start_episode(&mut self, episode: u64) {
        self.running = Some(Running {
            episode,
            rng: stream_rng(self.seed, streams::COORDINATOR, episode),
            legs: Vec::new(),
        });
    }

    /// A message of this run about the episode in progress.
    pub fn is_current(&self, h: &Header) -> bool {
        h.run == self.tag
            && self
                .running
                .as_ref()
                .is_some_and(|r| r.episode == h.episode)
    }

    /// A `drift` message: kept if it is this run's and names a sensor and a
    /// quantity this build knows (returned, for the adapter's log and its
    /// `--on-drift`).
    pub fn on_drift(&mut self, d: &Drift) -> Option<&DriftRecord> {
        let sensors = &self.scenario.sensors;
        if d.header.run != self.tag
            || d.header.sender != SENDER_AGENT
            || d.sensor as usize >= sensors.len()
        {
            return None;
        }
        let record = DriftRecord::from_wire(d, |i| sensors[i as usize].name.clone())?;
        self.drift.push(record);
        self.drift.last()
    }

    fn sensor_of(&self, leg: u32) -> Result<u32, CoordinatorError> {
        self.scenario
            .legs
            .get(leg as usize)
            .map(|l| l.sensor as u32)
            .ok_or_else(|| {
                CoordinatorError::Protocol(format!(
                    "leg {leg} of a scenario with {} legs",
                    self.scenario.legs.len()
                ))
            })
    }

    /// Decision point `w.header.leg` of the episode in progress: the
    /// previous leg's counts are recorded and it is closed; δ is drawn from
    /// ω for the agent's covariance. `None` for another run's or episode's
    /// waypoint.
    pub fn on_waypoint(&mut self, w: &Waypoint) -> Result<Option<Opening>, CoordinatorError> {
        if !self.is_current(&w.header) {
            return Ok(None);
        }
        let (episode, leg) = (w.header.episode, w.header.leg);
        let sensor = self.sensor_of(leg)?;
        let close = match leg.checked_sub(1) {
            Some(prev) => Some(LegAt {
                episode,
                leg: prev,
                sensor: self.sensor_of(prev)?,
            }),
            None => None,
        };
        let n = self.scenario.dim;
        let cov = DMatrix::from_fn(n, n, |r, c| w.cov[r][c]);
        let Some(running) = self.running.as_mut() else {
            return Ok(None);
        };
        if close.is_some()
            && let Some(prev) = running.legs.last_mut()
        {
            prev.steps = w.prev_steps;
            prev.received = w.prev_received;
        }
        let u: f64 = running.rng.random();
        let index = self.policy.draw(leg as usize, &cov, u);
        let delta = self.policy.deltas[index];
        running.legs.push(LegRecord {
            leg,
            sensor,
            delta,
            steps: 0,
            received: 0,
            transmitted: None,
            delivered: None,
            lost: None,
            triggers: None,
            slots: None,
        });
        Ok(Some(Opening {
            close,
            open: LegAt {
                episode,
                leg,
                sensor,
            },
            delta_index: index as u32,
            delta,
        }))
    }

    /// The agent's outcome of the episode in progress: record it (and its
    /// dead link, if any); the last leg is to be closed.
    pub fn end_episode(&mut self, o: &Outcome) -> Result<LegAt, CoordinatorError> {
        let code = OutcomeCode::try_from(o.outcome).map_err(|c| {
            CoordinatorError::Protocol(format!("outcome: unknown outcome code {c}"))
        })?;
        let last = LegAt {
            episode: o.header.episode,
            leg: o.header.leg,
            sensor: self.sensor_of(o.header.leg)?,
        };
        let Some(mut running) = self.running.take() else {
            return Err(CoordinatorError::Protocol(format!(
                "outcome of episode {} with no episode running",
                o.header.episode
            )));
        };
        let episode = running.episode;
        if let Some(l) = running.legs.last_mut() {
            l.steps = o.last_steps;
            l.received = o.last_received;
        }
        if o.dead_sensor != u32::MAX {
            let sensor = self.sensor_name(o.dead_sensor);
            tracing::warn!(episode, %sensor, detect_us = o.detect_us, "dead link");
            self.faults.push(FaultRecord {
                episode,
                sensor,
                detect_ms: o.detect_us as f64 / 1000.0,
                wait_started_unix_ns: o.wait_started_unix_ns,
                detected_unix_ns: o.detected_unix_ns,
                dead_slots: o.dead_slots,
            });
        }
        tracing::debug!(
            episode,
            outcome = code.name(),
            steps = o.steps,
            "episode end"
        );
        self.records.push(EpisodeRecord {
            episode,
            outcome: code.name().to_string(),
            degraded: o.degraded != 0,
            steps: o.steps,
            energy: 0.0,
            legs: running.legs,
        });
        Ok(last)
    }

    fn sensor_name(&self, i: u32) -> String {
        self.scenario
            .sensors
            .get(i as usize)
            .map_or_else(|| format!("#{i}"), |s| s.name.clone())
    }

    /// A sensor's ledger of a closed leg (another run's is ignored).
    pub fn on_ledger(&mut self, l: Ledger) {
        if l.header.run == self.tag {
            self.ledgers.insert((l.header.episode, l.header.leg), l);
        }
    }

    /// The sensors of `missing` (whose ledgers did not come) are dead: each
    /// one the agent never found dead (it was not awaited again after it
    /// died: a link that lost every remote sensor at once, say) gets a fault
    /// of its own, at the first episode whose ledger is missing, so its
    /// missing ledgers are a named dead link and not a live sensor's.
    pub fn dead_without_ledger(&mut self, missing: &[u32]) {
        for &sensor in missing {
            let name = self.sensor_name(sensor);
            if self.faults.iter().any(|f| f.sensor == name) {
                continue;
            }
            let Some(episode) = self
                .records
                .iter()
                .find(|r| {
                    r.legs.iter().any(|l| {
                        l.sensor == sensor && !self.ledgers.contains_key(&(r.episode, l.leg))
                    })
                })
                .map(|r| r.episode)
            else {
                continue;
            };
            tracing::warn!(episode, %name, "dead link: the sensor died before its ledger came");
            self.faults.push(FaultRecord {
                episode,
                sensor: name,
                detect_ms: 0.0,
                wait_started_unix_ns: 0,
                detected_unix_ns: 0,
                dead_slots: 0,
            });
        }
    }

    /// The sensors whose ledger of a recorded leg has not come (sorted, once
    /// each).
    pub fn missing_ledgers(&self) -> Vec<u32> {
        let mut missing: Vec<u32> = self
            .records
            .iter()
            .flat_map(|r| r.legs.iter().map(move |l| (r.episode, l)))
            .filter(|(e, l)| !self.ledgers.contains_key(&(*e, l.leg)))
            .map(|(_, l)| l.sensor)
            .collect();
        missing.sort_unstable();
        missing.dedup();
        missing
    }

    /// The run report of the episodes recorded (taken out of the core): each
    /// leg joined to its sensor's ledger.
    pub fn report(
        &mut self,
        run_id: String,
        requested: u64,
        seconds: f64,
        aborted: Option<String>,
    ) -> RunReport {
        let s = self.scenario;
        let mut records = std::mem::take(&mut self.records);
        let mut sensors: Vec<SensorTotals> = s
            .sensors
            .iter()
            .map(|x| SensorTotals {
                name: x.name.clone(),
                transmitted: 0,
                delivered: 0,
                lost: 0,
                triggers: 0,
                received: 0,
                received_without_ledger: 0,
                slots: 0,
                energy: 0.0,
                missing_ledgers: 0,
            })
            .collect();
        for r in &mut records {
            let mut energy = 0.0;
            for l in &mut r.legs {
                let cost = s.sensors[l.sensor as usize].cost;
                let t = &mut sensors[l.sensor as usize];
                // `received` over exactly the legs `transmitted` covers.
                match self.ledgers.get(&(r.episode, l.leg)) {
                    Some(led) => {
                        t.received += u64::from(l.received);
                        l.transmitted = Some(led.transmissions);
                        l.delivered = Some(led.delivered);
                        l.lost = Some(led.lost);
                        l.triggers = Some(led.triggers);
                        l.slots = Some(led.slots);
                        t.transmitted += u64::from(led.transmissions);
                        t.delivered += u64::from(led.delivered);
                        t.lost += u64::from(led.lost);
                        t.triggers += u64::from(led.triggers);
                        t.slots += u64::from(led.slots);
                        t.energy += led.energy;
                        energy += led.energy;
                    }
                    None => {
                        t.received_without_ledger += u64::from(l.received);
                        t.missing_ledgers += 1;
                        r.degraded = true;
                        energy += f64::from(l.received) * cost;
                    }
                }
            }
            r.energy = energy;
        }
        let count = |o: &str| records.iter().filter(|r| r.outcome == o).count() as u64;
        RunReport {
            run_id,
            scenario: s.name.clone(),
            scenario_hash: s.content_hash.clone(),
            // The strategy's label and predictions: the coordinator runs its
            // policy only; [`crate::run`] names the strategy in the report.
            strategy_label: String::new(),
            seed: self.seed,
            requested_episodes: requested,
            episodes: records.len() as u64,
            target: count("target"),
            collision: count("collision"),
            free: count("free"),
            degraded: records.iter().filter(|r| r.degraded).count() as u64,
            steps: records.iter().map(|r| u64::from(r.steps)).sum(),
            seconds,
            predicted: None,
            predicted_ci95: None,
            sensors,
            faults: std::mem::take(&mut self.faults),
            // A flag of an episode that did not finish is not reported, as
            // the episode is not (the recording's summary does the same).
            drift: std::mem::take(&mut self.drift)
                .into_iter()
                .filter(|d| records.iter().any(|r| r.episode == d.episode))
                .collect(),
            episode_results: records,
            aborted,
        }
    }
}

#[cfg(test)]
mod tests;
