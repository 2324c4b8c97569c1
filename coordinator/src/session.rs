//! The coordinator's ports, episode loop and bookkeeping.

use crate::CoordinatorError;
use etp_runtime::report::{EpisodeRecord, FaultRecord, LegRecord, RunReport, SensorTotals};
use etp_runtime::wire::PortError;
use etp_runtime::wire::agent_to_coordinator::{Outcome, Waypoint};
use etp_runtime::wire::coordinator_to_agent::Control;
use etp_runtime::wire::coordinator_to_all::Threshold;
use etp_runtime::wire::sensor_to_coordinator::Ledger;
use etp_runtime::wire::to_coordinator::Hello;
use etp_runtime::wire::{
    self, AGENT_NODE, COORDINATOR_NODE, Liveness, Notifier, OutcomeCode, Ports, Pub, RunId,
    SENDER_AGENT, SENDER_COORDINATOR, ServiceId, Stamper, Sub, Waiter, Wake, Watchdog, to_wire_vec,
};
use etp_shared::rng::{SimRng, stream_rng, streams};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Strategy;
use iceoryx2::prelude::*;
use nalgebra::DMatrix;
use rand::RngExt;
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// Silence after which the coordinator checks that the agent lives.
const IDLE_CHECK: Duration = Duration::from_millis(250);
/// After a termination request: how long to wait for outstanding ledgers
/// (without one, the ledgers of live sensors are waited for, however slow).
const LEDGER_GRACE: Duration = Duration::from_secs(2);

pub struct Coordinator<'a> {
    run: RunId,
    scenario: &'a Scenario,
    strategy: &'a Strategy,
    seed: u64,
    node: Node<ipc::Service>,
    stamp: Stamper,
    waiter: Waiter,
    watchdog: Watchdog,
    control: Pub<Control>,
    /// One `threshold` service per sensor (read by it and by the agent).
    threshold: Vec<Pub<Threshold>>,
    waypoint: Sub<Waypoint>,
    outcome: Sub<Outcome>,
    ledger: Sub<Ledger>,
    hello: Sub<Hello>,
    agent_wake: Notifier,
    sensor_wake: Vec<Notifier>,
    ledgers: HashMap<(u64, u32), Ledger>,
    /// A termination signal was received: finish the report, do not wait.
    terminating: bool,
    /// `--progress FILE` and when it was last written.
    progress: Option<(std::path::PathBuf, Option<Instant>)>,
}

impl<'a> Coordinator<'a> {
    pub fn new(
        run: &RunId,
        scenario: &'a Scenario,
        strategy: &'a Strategy,
        seed: u64,
    ) -> Result<Self, CoordinatorError> {
        let node = wire::create_node(run, COORDINATOR_NODE)?;
        let sensors = scenario.sensors.len();
        let ports = Ports {
            node: &node,
            run,
            sensors,
        };
        Ok(Self {
            waiter: Waiter::new(ports.listener(ServiceId::CoordinatorWake)?)?,
            watchdog: Watchdog::new(AGENT_NODE, false, 1),
            control: ports.publisher(ServiceId::Control)?,
            threshold: (0..sensors)
                .map(|i| ports.publisher(ServiceId::Threshold(i)))
                .collect::<Result<_, _>>()?,
            waypoint: ports.subscriber(ServiceId::Waypoint)?,
            outcome: ports.subscriber(ServiceId::Outcome)?,
            ledger: ports.subscriber(ServiceId::Ledger)?,
            hello: ports.subscriber(ServiceId::Hello)?,
            agent_wake: ports.notifier(ServiceId::AgentWake)?,
            sensor_wake: (0..sensors)
                .map(|i| ports.notifier(ServiceId::SensorWake(i)))
                .collect::<Result<_, _>>()?,
            run: run.clone(),
            scenario,
            strategy,
            seed,
            stamp: Stamper::new(run, SENDER_COORDINATOR),
            ledgers: HashMap::new(),
            terminating: false,
            progress: None,
            node,
        })
    }

    /// THE wait of the coordinator: until notified (`true`) or a silence of
    /// `timeout` (`false`). Interrupted waits resume; a termination request
    /// is remembered in `self.terminating` and ends the wait.
    fn wait(&mut self, timeout: Duration) -> Result<bool, CoordinatorError> {
        match self.waiter.wait(&self.node, timeout)? {
            Wake::Notified { .. } => Ok(true),
            Wake::Silence => Ok(false),
            Wake::Terminate => {
                self.terminating = true;
                Ok(false)
            }
        }
    }

    /// Wait until the agent and every sensor said hello.
    pub fn wait_ready(&mut self, timeout: Duration) -> Result<(), CoordinatorError> {
        let sensors = self.scenario.sensors.len();
        let mut agent = false;
        let mut seen = vec![false; sensors];
        let start = Instant::now();
        loop {
            while let Some(s) = self
                .hello
                .receive()
                .map_err(|e| PortError::receive("hello", e))?
            {
                let h = s.header;
                if h.run != self.stamp.tag() {
                    continue;
                }
                if h.sender == SENDER_AGENT {
                    agent = true;
                } else if let Some(x) = seen.get_mut(h.sender as usize) {
                    *x = true;
                }
            }
            if agent && seen.iter().all(|&x| x) {
                return Ok(());
            }
            if start.elapsed() >= timeout {
                let mut missing: Vec<String> = seen
                    .iter()
                    .enumerate()
                    .filter(|(_, x)| !**x)
                    .map(|(i, _)| self.scenario.sensors[i].name.clone())
                    .collect();
                if !agent {
                    missing.insert(0, "agent".into());
                }
                return Err(CoordinatorError::Startup(timeout, missing.join(", ")));
            }
            self.wait(Duration::from_millis(50))?;
            if self.terminating {
                return Err(CoordinatorError::Startup(
                    start.elapsed(),
                    "interrupted before every process was ready".into(),
                ));
            }
        }
    }

    fn send_threshold(
        &mut self,
        episode: u64,
        leg: u32,
        kind: u32,
        sensor: u32,
        delta_index: u32,
        delta: f64,
    ) -> Result<(), CoordinatorError> {
        let header = self.stamp.header(episode, leg, 0);
        self.threshold[sensor as usize]
            .send_copy(Threshold {
                header,
                kind,
                sensor,
                delta_index,
                _pad: 0,
                delta,
            })
            .map(|_| ())
            .map_err(|e| PortError::send("threshold", e).into())
    }

    fn notify(n: &Notifier, what: &'static str) -> Result<(), CoordinatorError> {
        n.notify()
            .map(|_| ())
            .map_err(|e| PortError::notify(what, e).into())
    }

    /// Close `leg` at its sensor (the sensor answers with its ledger).
    fn close(&mut self, episode: u64, leg: u32) -> Result<(), CoordinatorError> {
        let sensor = self.scenario.legs[leg as usize].sensor;
        self.send_threshold(episode, leg, Threshold::CLOSE, sensor as u32, 0, 0.0)?;
        Self::notify(&self.sensor_wake[sensor], "sensor wake")
    }

    fn drain_ledgers(&mut self) -> Result<(), CoordinatorError> {
        while let Some(s) = self
            .ledger
            .receive()
            .map_err(|e| PortError::receive("ledger", e))?
        {
            let l: Ledger = *s;
            if l.header.run == self.stamp.tag() {
                self.ledgers.insert((l.header.episode, l.header.leg), l);
            }
        }
        Ok(())
    }

    /// Decision point `w.header.leg`: classify, draw δ, open the leg.
    fn decide(
        &mut self,
        w: &Waypoint,
        rng: &mut SimRng,
        legs: &mut Vec<LegRecord>,
    ) -> Result<(), CoordinatorError> {
        let episode = w.header.episode;
        let leg = w.header.leg;
        if leg > 0 {
            if let Some(prev) = legs.last_mut() {
                prev.steps = w.prev_steps;
                prev.received = w.prev_received;
            }
            self.close(episode, leg - 1)?;
        }
        let n = self.scenario.dim;
        let cov = DMatrix::from_fn(n, n, |r, c| w.cov[r][c]);
        let u: f64 = rng.random();
        let index = self.strategy.draw(leg as usize, &cov, u);
        let delta = self.strategy.deltas[index];
        let sensor = self.scenario.legs[leg as usize].sensor as u32;
        legs.push(LegRecord {
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
        self.send_threshold(episode, leg, Threshold::OPEN, sensor, index as u32, delta)?;
        Self::notify(&self.agent_wake, "agent wake")
    }

    /// Run `episodes` episodes, stop every process, return the report.
    ///
    /// A termination request (SIGINT/SIGTERM) or the supervisor's death ends
    /// the run after the episodes completed so far: their ledgers are still
    /// collected and reported, the others stopped.
    pub fn run_episodes(&mut self, episodes: u64) -> Result<RunReport, CoordinatorError> {
        let mut records: Vec<EpisodeRecord> = Vec::new();
        let mut faults: Vec<FaultRecord> = Vec::new();
        let mut aborted = None;
        let started = Instant::now();
        let initial = initial_wire(&self.scenario.plant);
        'episodes: for episode in 0..episodes {
            if self.terminating || self.watchdog.parent_gone() {
                aborted = Some(self.abort_reason(episode));
                break;
            }
            tracing::debug!(episode, "episode start");
            let mut rng = stream_rng(self.seed, streams::COORDINATOR, episode);
            let header = self.stamp.header(episode, 0, 0);
            self.control
                .send_copy(Control {
                    header,
                    kind: Control::START,
                    dim: self.scenario.dim as u32,
                    seed: self.seed,
                    initial_mean: initial.0,
                    initial_cov: initial.1,
                })
                .map_err(|e| PortError::send("control", e))?;
            Self::notify(&self.agent_wake, "agent wake")?;
            let mut legs = Vec::new();
            loop {
                let (progressed, done) =
                    self.take_episode_messages(episode, &mut rng, &mut legs)?;
                if let Some(o) = done {
                    records.push(self.end_episode(episode, &o, legs, &mut faults)?);
                    self.note_progress(records.len(), episode + 1 == episodes);
                    break;
                }
                if progressed || self.wait(IDLE_CHECK)? {
                    continue;
                }
                if self.terminating || self.watchdog.parent_gone() {
                    aborted = Some(self.abort_reason(episode));
                    break 'episodes;
                }
                // A live agent is waited for, however slow or paused.
                if self.watchdog.gone(self.node.config(), true) {
                    self.stop()?;
                    return Err(CoordinatorError::AgentDied(episode));
                }
            }
        }
        let seconds = started.elapsed().as_secs_f64();
        self.collect_ledgers(&records)?;
        self.stop()?;
        if let Some(why) = &aborted {
            tracing::warn!(episodes = records.len(), "{why}");
        }
        Ok(self.report(episodes, records, faults, seconds, aborted))
    }

    /// Progress goes to FILE (see [`Coordinator::note_progress`]).
    pub fn report_progress_to(&mut self, file: std::path::PathBuf) {
        self.progress = Some((file, None));
    }

    /// Write the number of finished episodes to the progress file, at most
    /// every 100 ms unless `last`; best effort (a failed write is logged).
    fn note_progress(&mut self, finished: usize, last: bool) {
        let Some((file, when)) = &mut self.progress else {
            return;
        };
        if !last && when.is_some_and(|t| t.elapsed() < Duration::from_millis(100)) {
            return;
        }
        *when = Some(Instant::now());
        let tmp = file.with_extension("tmp");
        if let Err(e) =
            std::fs::write(&tmp, finished.to_string()).and_then(|()| std::fs::rename(&tmp, &*file))
        {
            tracing::debug!(file = %file.display(), "progress not written: {e}");
        }
    }

    fn abort_reason(&self, episode: u64) -> String {
        if self.terminating {
            format!("interrupted during episode {episode}")
        } else {
            format!("supervisor gone during episode {episode}")
        }
    }

    /// Drain waypoints (decide each), outcomes and ledgers; (anything
    /// decided, the episode's outcome if it came).
    fn take_episode_messages(
        &mut self,
        episode: u64,
        rng: &mut SimRng,
        legs: &mut Vec<LegRecord>,
    ) -> Result<(bool, Option<Outcome>), CoordinatorError> {
        let tag = self.stamp.tag();
        let mut progressed = false;
        while let Some(s) = self
            .waypoint
            .receive()
            .map_err(|e| PortError::receive("waypoint", e))?
        {
            let w: Waypoint = *s;
            if w.header.run == tag && w.header.episode == episode {
                progressed = true;
                self.decide(&w, rng, legs)?;
            }
        }
        let mut done = None;
        while let Some(s) = self
            .outcome
            .receive()
            .map_err(|e| PortError::receive("outcome", e))?
        {
            let o: Outcome = *s;
            if o.header.run == tag && o.header.episode == episode {
                done = Some(o);
            }
        }
        self.drain_ledgers()?;
        Ok((progressed, done))
    }

    /// The episode's outcome came: close its last leg, record it.
    fn end_episode(
        &mut self,
        episode: u64,
        o: &Outcome,
        mut legs: Vec<LegRecord>,
        faults: &mut Vec<FaultRecord>,
    ) -> Result<EpisodeRecord, CoordinatorError> {
        if let Some(last) = legs.last_mut() {
            last.steps = o.last_steps;
            last.received = o.last_received;
        }
        self.close(episode, o.header.leg)?;
        if o.dead_sensor != u32::MAX {
            let sensor = self.sensor_name(o.dead_sensor);
            tracing::warn!(episode, %sensor, detect_us = o.detect_us, "dead link");
            faults.push(FaultRecord {
                episode,
                sensor,
                detect_ms: o.detect_us as f64 / 1000.0,
                wait_started_unix_ns: o.wait_started_unix_ns,
                detected_unix_ns: o.detected_unix_ns,
                dead_slots: o.dead_slots,
            });
        }
        let outcome = OutcomeCode::try_from(o.outcome)
            .map_err(|c| CoordinatorError::Protocol(format!("outcome: unknown outcome code {c}")))?
            .name();
        tracing::debug!(episode, outcome, steps = o.steps, "episode end");
        Ok(EpisodeRecord {
            episode,
            outcome: outcome.to_string(),
            degraded: o.degraded != 0,
            steps: o.steps,
            energy: 0.0,
            legs,
        })
    }

    fn sensor_name(&self, i: u32) -> String {
        self.scenario
            .sensors
            .get(i as usize)
            .map_or_else(|| format!("#{i}"), |s| s.name.clone())
    }

    /// Wait for the ledgers of every leg of every recorded episode: as long
    /// as their sensors live, however slow (a ledger is never given up on a
    /// live sensor), except after a termination request, which leaves
    /// [`LEDGER_GRACE`]. A dead sensor's ledgers are missing.
    fn collect_ledgers(&mut self, records: &[EpisodeRecord]) -> Result<(), CoordinatorError> {
        let mut grace_end = None;
        loop {
            self.drain_ledgers()?;
            let mut missing: Vec<u32> = records
                .iter()
                .flat_map(|r| r.legs.iter().map(move |l| (r.episode, l)))
                .filter(|(e, l)| !self.ledgers.contains_key(&(*e, l.leg)))
                .map(|(_, l)| l.sensor)
                .collect();
            if missing.is_empty() {
                return Ok(());
            }
            if self.terminating || self.watchdog.parent_gone() {
                let end = *grace_end.get_or_insert_with(|| Instant::now() + LEDGER_GRACE);
                if Instant::now() >= end {
                    return Ok(());
                }
            }
            if !self.wait(Duration::from_millis(50))? {
                missing.sort_unstable();
                missing.dedup();
                let cfg = self.node.config().clone();
                let all_dead = missing.iter().all(|s| {
                    wire::liveness(&cfg, &wire::sensor_node_name(*s as usize)) != Liveness::Alive
                });
                if all_dead {
                    return Ok(());
                }
            }
        }
    }

    /// Tell the agent and every sensor to exit.
    fn stop(&mut self) -> Result<(), CoordinatorError> {
        let header = self.stamp.header(u64::MAX, 0, 0);
        let _ = self.control.send_copy(Control {
            header,
            kind: Control::STOP,
            ..Control::default()
        });
        for sensor in 0..self.threshold.len() {
            self.send_threshold(u64::MAX, 0, Threshold::STOP, sensor as u32, 0, 0.0)?;
        }
        let _ = self.agent_wake.notify();
        for n in &self.sensor_wake {
            let _ = n.notify();
        }
        Ok(())
    }

    fn report(
        &self,
        requested: u64,
        mut records: Vec<EpisodeRecord>,
        faults: Vec<FaultRecord>,
        seconds: f64,
        aborted: Option<String>,
    ) -> RunReport {
        let s = self.scenario;
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
            run_id: self.run.to_string(),
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
            faults,
            episode_results: records,
            aborted,
        }
    }
}

/// The initial belief of a scenario as wire arrays.
fn initial_wire(p: &etp_shared::scenario::Plant) -> (wire::WireVec, wire::WireMat) {
    let n = p.x0.len();
    (
        to_wire_vec(p.x0.as_slice()),
        wire::to_wire_mat(n, |r, c| p.p0[(r, c)]),
    )
}
