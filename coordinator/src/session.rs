//! The coordinator's ports, waits and episode loop: the thin iceoryx2
//! adapter around [`crate::core::CoordinatorCore`], which makes every
//! decision (δ at each waypoint, episode records, ledgers, the report).

use crate::CoordinatorError;
use crate::core::{CoordinatorCore, LegAt, Opening, RollCall, Send};
use etp_runtime::report::RunReport;
use etp_runtime::wire::PortError;
use etp_runtime::wire::agent_to_coordinator::{Drift, Outcome, Waypoint};
use etp_runtime::wire::coordinator_to_agent::Control;
use etp_runtime::wire::coordinator_to_sensor::Threshold;
use etp_runtime::wire::sensor_to_coordinator::Ledger;
use etp_runtime::wire::to_coordinator::Hello;
use etp_runtime::wire::{
    self, AGENT_NODE, COORDINATOR_NODE, Liveness, Notifier, Ports, Pub, RunId, SENDER_COORDINATOR,
    ServiceId, Stamper, Sub, Waiter, Wake, Watchdog, to_wire_vec,
};
use etp_shared::drift::OnDrift;
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Policy;
use iceoryx2::prelude::*;
use std::time::{Duration, Instant};

/// Silence after which the coordinator checks that the agent lives.
const IDLE_CHECK: Duration = Duration::from_millis(250);
/// After a termination request: how long to wait for outstanding ledgers
/// (without one, the ledgers of live sensors are waited for, however slow).
const LEDGER_GRACE: Duration = Duration::from_secs(2);

pub struct Coordinator<'a> {
    run: RunId,
    scenario: &'a Scenario,
    core: CoordinatorCore<'a>,
    node: Node<ipc::Service>,
    stamp: Stamper,
    waiter: Waiter,
    watchdog: Watchdog,
    control: Pub<Control>,
    /// One `threshold` service per sensor (read by it and by the agent).
    threshold: Vec<Pub<Threshold>>,
    waypoint: Sub<Waypoint>,
    outcome: Sub<Outcome>,
    drift: Sub<Drift>,
    /// `--on-drift`: what a flag of the channel monitor does.
    on_drift: OnDrift,
    /// With `--on-drift stop`: the flag that ends the run after its episode.
    stop_for_drift: Option<String>,
    ledger: Sub<Ledger>,
    hello: Sub<Hello>,
    agent_wake: Notifier,
    sensor_wake: Vec<Notifier>,
    /// A termination signal was received: finish the report, do not wait.
    terminating: bool,
    /// `--progress FILE` and when it was last written.
    progress: Option<(std::path::PathBuf, Option<Instant>)>,
}

impl<'a> Coordinator<'a> {
    pub fn new(
        run: &RunId,
        scenario: &'a Scenario,
        policy: &'a Policy,
        seed: u64,
    ) -> Result<Self, CoordinatorError> {
        let node = wire::create_node(run, COORDINATOR_NODE)?;
        let sensors = scenario.sensors.len();
        let stamp = Stamper::new(run, SENDER_COORDINATOR);
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
            drift: ports.subscriber(ServiceId::Drift)?,
            on_drift: OnDrift::Warn,
            stop_for_drift: None,
            ledger: ports.subscriber(ServiceId::Ledger)?,
            hello: ports.subscriber(ServiceId::Hello)?,
            agent_wake: ports.notifier(ServiceId::AgentWake)?,
            sensor_wake: (0..sensors)
                .map(|i| ports.notifier(ServiceId::SensorWake(i)))
                .collect::<Result<_, _>>()?,
            run: run.clone(),
            scenario,
            core: CoordinatorCore::new(scenario, policy, seed, stamp.tag()),
            stamp,
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
        let mut roll = RollCall::new(self.stamp.tag(), self.scenario.sensors.len());
        let start = Instant::now();
        loop {
            while let Some(s) = self
                .hello
                .receive()
                .map_err(|e| PortError::receive("hello", e))?
            {
                roll.on_hello(&s.header);
            }
            if roll.all_present() {
                return Ok(());
            }
            if start.elapsed() >= timeout {
                let missing = roll.missing(self.scenario).join(", ");
                return Err(CoordinatorError::Startup(timeout, missing));
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
            .publish(Threshold {
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

    /// Close a leg at its sensor (the sensor answers with its ledger).
    fn close(&mut self, at: LegAt) -> Result<(), CoordinatorError> {
        for send in Send::closing(at) {
            self.execute(send, None)?;
        }
        Ok(())
    }

    fn drain_ledgers(&mut self) -> Result<(), CoordinatorError> {
        while let Some(s) = self
            .ledger
            .receive()
            .map_err(|e| PortError::receive("ledger", e))?
        {
            self.core.on_ledger(*s);
        }
        Ok(())
    }

    /// A decision point as the core decided it: close the previous leg,
    /// open this one, wake the sensors and then the agent
    /// ([`Opening::sends`] says in which order, and why).
    fn open(&mut self, o: Opening) -> Result<(), CoordinatorError> {
        for send in o.sends() {
            self.execute(send, Some(&o))?;
        }
        Ok(())
    }

    /// One send of the core's; an OPEN takes its δ from `opening`.
    fn execute(&mut self, send: Send, opening: Option<&Opening>) -> Result<(), CoordinatorError> {
        match send {
            Send::Close(at) => {
                self.send_threshold(at.episode, at.leg, Threshold::CLOSE, at.sensor, 0, 0.0)
            }
            Send::Open(at) => {
                let (index, delta) = opening.map_or((0, 0.0), |o| (o.delta_index, o.delta));
                self.send_threshold(at.episode, at.leg, Threshold::OPEN, at.sensor, index, delta)
            }
            Send::WakeSensor(sensor) => {
                Self::notify(&self.sensor_wake[sensor as usize], "sensor wake")
            }
            Send::WakeAgent => Self::notify(&self.agent_wake, "agent wake"),
        }
    }

    /// Run `episodes` episodes, stop every process, return the report.
    ///
    /// A termination request (SIGINT/SIGTERM) or the supervisor's death ends
    /// the run after the episodes completed so far: their ledgers are still
    /// collected and reported, the others stopped.
    pub fn run_episodes(&mut self, episodes: u64) -> Result<RunReport, CoordinatorError> {
        let mut aborted = None;
        let started = Instant::now();
        let initial = initial_wire(&self.scenario.plant);
        'episodes: for episode in 0..episodes {
            if self.terminating || self.watchdog.parent_gone() {
                aborted = Some(self.abort_reason(episode));
                break;
            }
            tracing::debug!(episode, "episode start");
            self.core.start_episode(episode);
            let header = self.stamp.header(episode, 0, 0);
            self.control
                .publish(Control {
                    header,
                    kind: Control::START,
                    dim: self.scenario.dim as u32,
                    seed: self.core.seed(),
                    initial_mean: initial.0,
                    initial_cov: initial.1,
                })
                .map_err(|e| PortError::send("control", e))?;
            Self::notify(&self.agent_wake, "agent wake")?;
            loop {
                let (progressed, done) = self.take_episode_messages()?;
                if let Some(o) = done {
                    let last = self.core.end_episode(&o)?;
                    self.close(last)?;
                    self.note_progress(self.core.finished(), episode + 1 == episodes);
                    if let Some(why) = self.stop_for_drift.take()
                        && episode + 1 < episodes
                    {
                        aborted = Some(why);
                        break 'episodes;
                    }
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
        self.collect_ledgers()?;
        self.stop()?;
        if let Some(why) = &aborted {
            tracing::warn!(episodes = self.core.finished(), "{why}");
        }
        Ok(self
            .core
            .report(self.run.to_string(), episodes, seconds, aborted))
    }

    /// What a flag of the channel monitor does (`--on-drift`).
    pub fn on_drift(&mut self, on_drift: OnDrift) {
        self.on_drift = on_drift;
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

    /// Drain waypoints (the core decides each), outcomes and ledgers;
    /// (anything decided, the episode's outcome if it came).
    fn take_episode_messages(&mut self) -> Result<(bool, Option<Outcome>), CoordinatorError> {
        // Flags first: the agent sends a flag before the waypoint or outcome
        // that follows its slot.
        while let Some(s) = self
            .drift
            .receive()
            .map_err(|e| PortError::receive("drift", e))?
        {
            let d: Drift = *s;
            if let Some(r) = self.core.on_drift(&d) {
                tracing::warn!("channel drift: {}", r.describe());
                if self.on_drift == OnDrift::Stop && self.stop_for_drift.is_none() {
                    self.stop_for_drift = Some(format!(
                        "stopped on channel drift (--on-drift stop) after episode {}: {}",
                        r.episode,
                        r.describe()
                    ));
                }
            }
        }
        let mut progressed = false;
        while let Some(s) = self
            .waypoint
            .receive()
            .map_err(|e| PortError::receive("waypoint", e))?
        {
            let w: Waypoint = *s;
            if let Some(opening) = self.core.on_waypoint(&w)? {
                progressed = true;
                self.open(opening)?;
            }
        }
        let mut done = None;
        while let Some(s) = self
            .outcome
            .receive()
            .map_err(|e| PortError::receive("outcome", e))?
        {
            let o: Outcome = *s;
            if self.core.is_current(&o.header) {
                done = Some(o);
            }
        }
        self.drain_ledgers()?;
        Ok((progressed, done))
    }

    /// Wait for the ledgers of every leg of every recorded episode: as long
    /// as their sensors live, however slow (a ledger is never given up on a
    /// live sensor), except after a termination request, which leaves
    /// [`LEDGER_GRACE`]. A dead sensor's ledgers are missing.
    fn collect_ledgers(&mut self) -> Result<(), CoordinatorError> {
        let mut grace_end = None;
        loop {
            self.drain_ledgers()?;
            let missing = self.core.missing_ledgers();
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
                let cfg = self.node.config().clone();
                let all_dead = missing.iter().all(|s| {
                    wire::liveness(&cfg, &wire::sensor_node_name(*s as usize)) != Liveness::Alive
                });
                if all_dead {
                    self.core.dead_without_ledger(&missing);
                    return Ok(());
                }
            }
        }
    }

    /// Tell the agent and every sensor to exit.
    fn stop(&mut self) -> Result<(), CoordinatorError> {
        let header = self.stamp.header(u64::MAX, 0, 0);
        let _ = self.control.publish(Control {
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
}

/// The initial belief of a scenario as wire arrays.
fn initial_wire(p: &etp_shared::scenario::Plant) -> (wire::WireVec, wire::WireMat) {
    let n = p.x0.len();
    (
        to_wire_vec(p.x0.as_slice()),
        wire::to_wire_mat(n, |r, c| p.p0[(r, c)]),
    )
}
