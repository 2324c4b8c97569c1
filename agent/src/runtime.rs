//! The agent's episodes over IPC: the thin adapter around
//! [`crate::core::EpisodeCore`] (whose step is the in-process simulation's,
//! `replay verify`'s and the sensor replica's `AgentCore`), with the slot
//! served by a sensor process and the threshold chosen by the coordinator.
//! Here are only ports and waits; every decision is the core's.
//!
//! The agent waits in exactly one place, [`Agent::wait_until`], on its
//! wake-up event; what a silence means depends on whom it waits for
//! ([`Awaiting`]): the coordinator (idle, or a decision point) is checked by
//! the watchdog every [`IDLE_CHECK`]; the serving sensor is checked in the
//! node list every [`SLOT_CHECK`] of silence. A live process is waited for,
//! however slow or paused; only a dead one (or, with `--slot-deadline`, a
//! late one) makes a dead link.

use crate::core::{AfterSlot, EpisodeCore, EpisodeEnd, Fault, SlotRequest, SlotResult, Step};
use crate::link::Links;
use crate::{AgentError, AgentStats, Exit, IDLE_CHECK, SLOT_CHECK};
use etp_runtime::live::{LiveTap, SlotFrame, Totals};
use etp_runtime::report::DriftRecord;
use etp_runtime::wire::PortError;
use etp_runtime::wire::agent_to_coordinator::{Drift, Outcome, Waypoint};
use etp_runtime::wire::coordinator_to_agent::Control;
use etp_runtime::wire::to_coordinator::Hello;
use etp_runtime::wire::{
    self, AGENT_NODE, COORDINATOR_NODE, ControlKind, Liveness, Notifier, OutcomeCode, Ports, Pub,
    SENDER_AGENT, ServiceId, Stamper, Sub, Waiter, Wake, Watchdog, belief_to_wire,
};
use etp_shared::drift::{Flag, Monitor};
use etp_shared::episode::CompiledScenario;
use etp_shared::radio::Transmission;
use etp_shared::scenario::Scenario;
use iceoryx2::prelude::*;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Whom a wait is for (decides what a silence means).
#[derive(Debug, Clone, Copy)]
enum Awaiting {
    /// The coordinator: a start, a stop, or a leg's threshold.
    Coordinator,
    /// Sensor `sensor`'s slot, waited for since `since`.
    Slot {
        sensor: usize,
        since: Instant,
        since_wall: SystemTime,
    },
}

/// How a wait ended.
enum Waited<T> {
    Got(T),
    /// The awaited sensor is dead (or late past `--slot-deadline`).
    DeadLink(Fault),
    Exit(Exit),
}

/// The agent process: its scenario, ports and counters.
pub struct Agent<const N: usize> {
    c: CompiledScenario<N>,
    node: Node<ipc::Service>,
    stamp: Stamper,
    links: Links,
    waiter: Waiter,
    watchdog: Watchdog,
    slot_deadline: Option<Duration>,
    control: Sub<Control>,
    waypoint: Pub<Waypoint>,
    outcome: Pub<Outcome>,
    drift: Pub<Drift>,
    /// The channel monitor, fed every closed slot.
    monitor: Monitor,
    coordinator_wake: Notifier,
    stats: AgentStats,
    /// `etp run --live`: the view's feed (never blocks, never fails the run).
    live: Option<LiveTap>,
    /// The sensors' names (the view's drift flags name them).
    sensor_names: Vec<String>,
    _hello: Option<Pub<Hello>>,
}

fn unix_ns(t: SystemTime) -> u64 {
    t.duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

impl<const N: usize> Agent<N> {
    pub fn new(
        run: &wire::RunId,
        scenario: &Scenario,
        slot_deadline: Option<Duration>,
        live: Option<LiveTap>,
        monitor: Monitor,
    ) -> Result<Self, AgentError> {
        let node = wire::create_node(run, AGENT_NODE)?;
        let sensors = scenario.sensors.len();
        let ports = Ports {
            node: &node,
            run,
            sensors,
        };
        let links = Links::new(&ports)?;
        let waiter = Waiter::new(ports.listener(ServiceId::AgentWake)?)?;
        let control = ports.subscriber::<Control>(ServiceId::Control)?;
        let waypoint = ports.publisher::<Waypoint>(ServiceId::Waypoint)?;
        let outcome = ports.publisher::<Outcome>(ServiceId::Outcome)?;
        let drift = ports.publisher::<Drift>(ServiceId::Drift)?;
        let coordinator_wake = ports.notifier(ServiceId::CoordinatorWake)?;
        let mut stamp = Stamper::new(run, SENDER_AGENT);
        let hello = wire::say_hello(&ports, &coordinator_wake, &mut stamp)?;
        Ok(Self {
            c: CompiledScenario::<N>::new(scenario),
            stamp,
            links,
            waiter,
            // `say_hello` waited for the coordinator's subscriber: it was alive.
            watchdog: Watchdog::new(COORDINATOR_NODE, true, 1),
            slot_deadline,
            control,
            waypoint,
            outcome,
            drift,
            monitor,
            coordinator_wake,
            stats: AgentStats::default(),
            live,
            sensor_names: scenario.sensors.iter().map(|s| s.name.clone()).collect(),
            _hello: Some(hello),
            node,
        })
    }

    fn notify_coordinator(&self) -> Result<(), AgentError> {
        self.coordinator_wake
            .notify()
            .map(|_| ())
            .map_err(|e| PortError::notify("coordinator wake", e).into())
    }

    /// Serve episodes until stopped.
    pub fn serve(mut self) -> Result<(Exit, AgentStats), AgentError> {
        loop {
            let start = self.wait_until(Awaiting::Coordinator, |a| a.take_control())?;
            match start {
                Waited::Got(Some((episode, seed))) => {
                    let started = Instant::now();
                    let r = self.episode(episode, seed)?;
                    self.stats.busy_seconds += started.elapsed().as_secs_f64();
                    if let Some(exit) = r {
                        return Ok((exit, self.stats));
                    }
                }
                Waited::Got(None) => return Ok((Exit::Stopped, self.stats)),
                Waited::Exit(exit) => return Ok((exit, self.stats)),
                Waited::DeadLink(_) => unreachable!("no slot awaited"),
            }
        }
    }

    /// `control`: `Some(Some(start))`, `Some(None)` for stop, `None` if nothing.
    fn take_control(&mut self) -> Result<Option<Option<(u64, u64)>>, AgentError> {
        let tag = self.stamp.tag();
        while let Some(s) = self
            .control
            .receive()
            .map_err(|e| PortError::receive("control", e))?
        {
            let c: Control = *s;
            if c.header.run != tag {
                continue;
            }
            match ControlKind::try_from(c.kind) {
                Ok(ControlKind::Start) => return Ok(Some(Some((c.header.episode, c.seed)))),
                Ok(ControlKind::Stop) => return Ok(Some(None)),
                Err(code) => tracing::warn!(code, "unknown control kind ignored"),
            }
        }
        Ok(None)
    }

    /// THE wait of the agent: poll, then block on the wake-up event until
    /// `poll` yields something. Interrupted waits resume (`Waiter`); a
    /// silence is checked against whom we await.
    fn wait_until<T>(
        &mut self,
        awaiting: Awaiting,
        mut poll: impl FnMut(&mut Self) -> Result<Option<T>, AgentError>,
    ) -> Result<Waited<T>, AgentError> {
        loop {
            if let Some(v) = poll(self)? {
                return Ok(Waited::Got(v));
            }
            let timeout = match awaiting {
                Awaiting::Coordinator => IDLE_CHECK,
                Awaiting::Slot { .. } => SLOT_CHECK,
            };
            match self.waiter.wait(&self.node, timeout)? {
                Wake::Notified { .. } => continue,
                Wake::Terminate => return Ok(Waited::Exit(Exit::Signal)),
                Wake::Silence => {}
            }
            match awaiting {
                Awaiting::Coordinator => {
                    if self.watchdog.gone(self.node.config(), false) {
                        return Ok(Waited::Exit(Exit::CoordinatorGone));
                    }
                }
                Awaiting::Slot {
                    sensor,
                    since,
                    since_wall,
                } => {
                    if self.watchdog.parent_gone() {
                        return Ok(Waited::Exit(Exit::CoordinatorGone));
                    }
                    let late = self.slot_deadline.is_some_and(|d| since.elapsed() >= d);
                    let name = wire::sensor_node_name(sensor);
                    if late || wire::peek_liveness(self.node.config(), &name) != Liveness::Alive {
                        // The verdict's time, before the dead node's cleanup,
                        // which can take tens of milliseconds.
                        let fault = Fault {
                            sensor: sensor as u32,
                            detect_us: since.elapsed().as_micros() as u64,
                            wait_started_unix_ns: unix_ns(since_wall),
                            detected_unix_ns: unix_ns(SystemTime::now()),
                        };
                        // One last look: the slot may have closed just before.
                        if let Some(v) = poll(self)? {
                            return Ok(Waited::Got(v));
                        }
                        return Ok(Waited::DeadLink(fault));
                    }
                }
            }
        }
    }

    /// One slot at `sensor` for (episode, leg, step k).
    fn slot(
        &mut self,
        episode: u64,
        leg: u32,
        k: u32,
        sensor: usize,
        x: &etp_shared::etkf::Vector<N>,
    ) -> Result<Result<(SlotResult, Option<Fault>), Exit>, AgentError> {
        if !self.links.alive[sensor] {
            return Ok(Ok((SlotResult::Dead(None), None)));
        }
        let header = self.stamp.header(episode, leg, k);
        self.links.open_slot(sensor, header, x)?;
        let who = sensor as u32;
        let awaiting = Awaiting::Slot {
            sensor,
            since: Instant::now(),
            since_wall: SystemTime::now(),
        };
        // The coordinator starts an episode only after the previous one's
        // outcome: a control message now is its stop (Ctrl-C, SIGTERM). The
        // episode ends here unfinished, without an outcome: its sensors are
        // stopping too, and going on prediction-only would publish an
        // outcome that never happened.
        match self.wait_until(awaiting, |a| {
            if a.take_control()?.is_some() {
                return Ok(Some(None));
            }
            Ok(a.links.take_slot(episode, k, who, &mut a.stamp)?.map(Some))
        })? {
            Waited::Got(Some((y, digest))) => Ok(Ok((SlotResult::Closed(y, digest), None))),
            Waited::Got(None) => Ok(Err(Exit::Stopped)),
            Waited::Exit(e) => Ok(Err(e)),
            Waited::DeadLink(fault) => {
                self.links.alive[sensor] = false;
                let y = self
                    .links
                    .take_measurement(episode, k, who)?
                    .map(|(y, _)| y);
                tracing::warn!(
                    episode,
                    leg,
                    step = k,
                    sensor,
                    detect_us = fault.detect_us,
                    "dead link: prediction only from here"
                );
                // Its ports go, so the others' counts drop and listeners get
                // the dead-notifier event.
                wire::remove_dead_nodes(self.node.config());
                Ok(Ok((SlotResult::Dead(y), Some(fault))))
            }
        }
    }

    /// One episode; `Some(exit)` if the process must stop.
    fn episode(&mut self, episode: u64, seed: u64) -> Result<Option<Exit>, AgentError> {
        tracing::debug!(episode, "episode start");
        let mut core = EpisodeCore::start(&self.c, episode, seed)?;
        self.monitor.start_episode(episode);
        let tag = self.stamp.tag();
        loop {
            let point = core.decision_point();
            let (mean, cov) = belief_to_wire(&point.belief);
            let header = self.stamp.header(episode, point.leg, point.step);
            self.waypoint
                .publish(Waypoint {
                    header,
                    dim: N as u32,
                    prev_steps: point.prev.steps,
                    prev_received: point.prev.received,
                    prev_degraded: u32::from(point.prev.degraded),
                    mean,
                    cov,
                })
                .map_err(|e| PortError::send("waypoint", e))?;
            self.notify_coordinator()?;
            let opened = self.wait_until(Awaiting::Coordinator, |a| {
                // The coordinator starts an episode only after the previous
                // one's outcome: a control message now is its stop.
                if a.take_control()?.is_some() {
                    return Ok(Some(None));
                }
                Ok(a.links.take_open(tag, episode, point.leg)?.map(Some))
            })?;
            let (delta, sensor) = match opened {
                Waited::Got(Some(v)) => v,
                Waited::Got(None) => return Ok(Some(Exit::Stopped)),
                Waited::Exit(e) => return Ok(Some(e)),
                Waited::DeadLink(_) => unreachable!("no slot awaited"),
            };
            core.open_leg(&self.c, delta, sensor)?;
            if self.links.alive[sensor] {
                let header = self.stamp.header(episode, point.leg, point.step);
                self.links.hand_over(sensor, header, &point.belief)?;
                self.stats.handovers += 1;
            }
            loop {
                let request = match core.begin_step(&self.c)? {
                    Step::Slot(request) => request,
                    Step::Ended(end) => return self.finish(episode, end).map(|()| None),
                };
                let served =
                    self.slot(episode, request.leg, request.step, request.sensor, core.x())?;
                let (result, fault) = match served {
                    Ok(r) => r,
                    Err(exit) => return Ok(Some(exit)),
                };
                if self.live.is_some() {
                    self.feed_view(episode, delta, &core, &request, &result);
                }
                if let (SlotResult::Closed(y, _), Some(slot_delta)) = (&result, core.slot_delta()) {
                    let t = Transmission {
                        attempts: self.links.last_attempts,
                        delivered: y.is_some(),
                    };
                    for flag in self
                        .monitor
                        .observe(request.sensor, request.step, slot_delta, t)
                    {
                        self.publish_flag(request.leg, flag)?;
                    }
                }
                match core.close_slot(&self.c, request, result, fault)? {
                    AfterSlot::Continue => {}
                    AfterSlot::LegEnded => break,
                    AfterSlot::Ended(end) => return self.finish(episode, end).map(|()| None),
                }
            }
        }
    }

    /// Count a closed slot for the live view and send it if a frame is due.
    fn feed_view(
        &mut self,
        episode: u64,
        delta: f64,
        core: &EpisodeCore<N>,
        request: &SlotRequest<N>,
        result: &SlotResult,
    ) {
        let Some(tap) = self.live.as_mut() else {
            return;
        };
        let (attempts, delivered) = match result {
            SlotResult::Closed(y, _) => (self.links.last_attempts, y.is_some()),
            // A dead link's attempts are in no slot message.
            SlotResult::Dead(y) => (0, y.is_some()),
        };
        if tap.count_slot(request.sensor, attempts, delivered) {
            let prior = request.prior();
            tap.send_slot(SlotFrame {
                episode,
                leg: request.leg,
                step: request.step,
                sensor: request.sensor as u32,
                delta,
                x: core.x().as_slice().to_vec(),
                mean: prior.mean.as_slice().to_vec(),
                // Symmetric: column-major is row-major.
                cov: prior.cov.as_slice().to_vec(),
                attempts,
                delivered,
                totals: Totals::default(),
            });
        }
    }

    /// Publish a flag of the monitor as a `drift` message (the coordinator
    /// reads it with the next waypoint or outcome).
    fn publish_flag(&mut self, leg: u32, f: Flag) -> Result<(), AgentError> {
        tracing::info!(
            episode = f.episode,
            step = f.step,
            sensor = f.sensor,
            quantity = f.quantity.name(),
            statistic = f.statistic,
            threshold = f.threshold,
            "channel drift flagged"
        );
        let d = Drift::of_flag(self.stamp.header(f.episode, leg, f.step), &f);
        self.drift
            .publish(d)
            .map_err(|e| PortError::send("drift", e))?;
        if let Some(tap) = self.live.as_mut() {
            let names = &self.sensor_names;
            let name = |i: u32| {
                names
                    .get(i as usize)
                    .cloned()
                    .unwrap_or_else(|| i.to_string())
            };
            if let Some(record) = DriftRecord::from_wire(&d, name) {
                tap.note_drift(record);
            }
        }
        Ok(())
    }

    /// Publish the episode's outcome.
    fn finish(&mut self, episode: u64, end: EpisodeEnd) -> Result<(), AgentError> {
        let mut o = end.outcome;
        o.header = self.stamp.header(episode, end.leg, end.step);
        self.stats.episodes += 1;
        self.stats.steps += u64::from(o.steps);
        self.stats.received += u64::from(o.received);
        self.stats.dead_slots += u64::from(o.dead_slots);
        tracing::debug!(
            episode,
            outcome = OutcomeCode::try_from(o.outcome).map_or("?", OutcomeCode::name),
            steps = o.steps,
            received = o.received,
            degraded = o.degraded,
            "episode end"
        );
        self.outcome
            .publish(o)
            .map_err(|e| PortError::send("outcome", e))?;
        self.notify_coordinator()?;
        if let Some(tap) = self.live.as_mut() {
            tap.send_outcome(episode, o.outcome, o.steps, o.degraded != 0);
        }
        Ok(())
    }
}
