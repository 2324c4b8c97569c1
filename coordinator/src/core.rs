//! The coordinator's decisions, as pure functions of its state: no ports, no
//! clock. [`crate::session`] is the thin iceoryx2 adapter around it (receive,
//! call, publish the [`ThresholdAction`]s), so every decision here is
//! unit-tested without processes:
//!
//! * which δ at which decision point: the agent's covariance classified into
//!   the strategy's region, δ drawn from ω with uniform numbers from stream
//!   `COORDINATOR` (one per waypoint, in order);
//! * closing the previous leg at its sensor (which answers with its ledger);
//! * the outcome's bookkeeping (per-leg counts, dead links as faults) and the
//!   report: ledgers joined to the agent's received counts, a missing ledger
//!   degrades its episode.

use crate::CoordinatorError;
use etp_runtime::wire::OutcomeCode;
use etp_runtime::wire::agent_to_coordinator::{Outcome, Waypoint};
use etp_runtime::wire::report::{EpisodeRecord, FaultRecord, LegRecord, RunReport, SensorTotals};
use etp_runtime::wire::sensor_to_coordinator::Ledger;
use etp_shared::rng::{SimRng, stream_rng, streams};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Strategy;
use nalgebra::DMatrix;
use rand::RngExt;
use std::collections::HashMap;

/// A `threshold` message the adapter must publish (and wake its reader).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ThresholdAction {
    /// Close `leg` at `sensor` (it answers with its ledger).
    Close { episode: u64, leg: u32, sensor: u32 },
    /// Open `leg` at `sensor` with δ = `delta` (index `delta_index` in Δ).
    Open {
        episode: u64,
        leg: u32,
        sensor: u32,
        delta_index: u32,
        delta: f64,
    },
}

/// The episode in progress.
struct Running {
    episode: u64,
    rng: SimRng,
    legs: Vec<LegRecord>,
}

/// The coordinator's state between messages.
pub struct CoordinatorCore<'a> {
    scenario: &'a Scenario,
    strategy: &'a Strategy,
    seed: u64,
    tag: u64,
    running: Option<Running>,
    records: Vec<EpisodeRecord>,
    faults: Vec<FaultRecord>,
    ledgers: HashMap<(u64, u32), Ledger>,
}

impl<'a> CoordinatorCore<'a> {
    /// The coordinator of a run with tag `tag` (messages of other runs are ignored).
    pub fn new(scenario: &'a Scenario, strategy: &'a Strategy, seed: u64, tag: u64) -> Self {
        Self {
            scenario,
            strategy,
            seed,
            tag,
            running: None,
            records: Vec::new(),
            faults: Vec::new(),
            ledgers: HashMap::new(),
        }
    }

    /// Episode `episode` starts (after the previous one's outcome).
    pub fn start_episode(&mut self, episode: u64) {
        self.running = Some(Running {
            episode,
            rng: stream_rng(self.seed, streams::COORDINATOR, episode),
            legs: Vec::new(),
        });
    }

    /// The run seed (the agent's and sensors' streams derive from it).
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Episodes recorded so far.
    pub fn finished(&self) -> usize {
        self.records.len()
    }

    /// Decision point `w.header.leg` of the running episode: close the
    /// previous leg (its counts come with the waypoint), classify the
    /// covariance, draw δ, open the leg. Nothing for another run or episode.
    pub fn on_waypoint(&mut self, w: &Waypoint) -> Vec<ThresholdAction> {
        let Some(run) = self
            .running
            .as_mut()
            .filter(|r| w.header.run == self.tag && w.header.episode == r.episode)
        else {
            return Vec::new();
        };
        let (episode, leg) = (w.header.episode, w.header.leg);
        let mut actions = Vec::with_capacity(2);
        if leg > 0 {
            if let Some(prev) = run.legs.last_mut() {
                prev.steps = w.prev_steps;
                prev.received = w.prev_received;
            }
            actions.push(close(self.scenario, episode, leg - 1));
        }
        let n = self.scenario.dim;
        let cov = DMatrix::from_fn(n, n, |r, c| w.cov[r][c]);
        let u: f64 = run.rng.random();
        let index = self.strategy.draw(leg as usize, &cov, u);
        let delta = self.strategy.deltas[index];
        let sensor = self.scenario.legs[leg as usize].sensor as u32;
        run.legs.push(LegRecord {
            leg,
            sensor,
            delta,
            steps: 0,
            received: 0,
            transmitted: None,
            slots: None,
        });
        actions.push(ThresholdAction::Open {
            episode,
            leg,
            sensor,
            delta_index: index as u32,
            delta,
        });
        actions
    }

    fn close(&self, episode: u64, leg: u32) -> ThresholdAction {
        close(self.scenario, episode, leg)
    }

    /// The running episode's `outcome`: record it and close its last leg.
    /// `None` for a message of another run or episode.
    pub fn on_outcome(&mut self, o: &Outcome) -> Result<Option<ThresholdAction>, CoordinatorError> {
        let episode = o.header.episode;
        if o.header.run != self.tag || self.running.as_ref().is_none_or(|r| r.episode != episode) {
            return Ok(None);
        }
        let outcome = OutcomeCode::try_from(o.outcome)
            .map_err(|c| CoordinatorError::Protocol(format!("outcome: unknown outcome code {c}")))?
            .name();
        let Some(mut run) = self.running.take() else {
            return Ok(None);
        };
        if let Some(last) = run.legs.last_mut() {
            last.steps = o.last_steps;
            last.received = o.last_received;
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
        tracing::debug!(episode, outcome, steps = o.steps, "episode end");
        self.records.push(EpisodeRecord {
            episode,
            outcome: outcome.to_string(),
            degraded: o.degraded != 0,
            steps: o.steps,
            energy: 0.0,
            legs: run.legs,
        });
        Ok(Some(self.close(episode, o.header.leg)))
    }

    /// A sensor's `ledger` (of any episode of this run).
    pub fn on_ledger(&mut self, l: &Ledger) {
        if l.header.run == self.tag {
            self.ledgers.insert((l.header.episode, l.header.leg), *l);
        }
    }

    /// The sensors whose ledgers of recorded legs are still missing (sorted, once each).
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

    fn sensor_name(&self, i: u32) -> String {
        self.scenario
            .sensors
            .get(i as usize)
            .map_or_else(|| format!("#{i}"), |s| s.name.clone())
    }

    /// The run's report: every recorded episode with its legs joined to the
    /// sensors' ledgers (a missing ledger degrades the episode; its energy is
    /// then the agent's received count × c_m).
    pub fn report(
        self,
        run_id: String,
        requested: u64,
        seconds: f64,
        aborted: Option<String>,
    ) -> RunReport {
        let s = self.scenario;
        let mut records = self.records;
        let mut sensors: Vec<SensorTotals> = s
            .sensors
            .iter()
            .map(|x| SensorTotals {
                name: x.name.clone(),
                transmitted: 0,
                received: 0,
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
                t.received += u64::from(l.received);
                match self.ledgers.get(&(r.episode, l.leg)) {
                    Some(led) => {
                        l.transmitted = Some(led.transmissions);
                        l.slots = Some(led.slots);
                        t.transmitted += u64::from(led.transmissions);
                        t.slots += u64::from(led.slots);
                        t.energy += led.energy;
                        energy += led.energy;
                    }
                    None => {
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
            strategy_label: self.strategy.label.clone(),
            seed: self.seed,
            requested_episodes: requested,
            episodes: records.len() as u64,
            target: count("target"),
            collision: count("collision"),
            free: count("free"),
            degraded: records.iter().filter(|r| r.degraded).count() as u64,
            steps: records.iter().map(|r| u64::from(r.steps)).sum(),
            seconds,
            predicted: self.strategy.predicted,
            sensors,
            faults: self.faults,
            episode_results: records,
            aborted,
        }
    }
}

/// Close `leg` at the sensor the scenario gives it.
fn close(scenario: &Scenario, episode: u64, leg: u32) -> ThresholdAction {
    ThresholdAction::Close {
        episode,
        leg,
        sensor: scenario.legs[leg as usize].sensor as u32,
    }
}

#[cfg(test)]
mod tests;
