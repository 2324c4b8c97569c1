//! The agent's episodes over IPC: the step of `etp_shared::episode::step`
//! (the same functions the in-process simulation and `replay --verify` use),
//! with the slot served by a sensor process and the threshold chosen by the
//! coordinator.
//!
//! The agent waits in exactly one place, [`Agent::wait_until`], on its
//! wake-up event; what a silence means depends on whom it waits for
//! ([`Awaiting`]): the coordinator (idle, or a decision point) is checked by
//! the watchdog every [`IDLE_CHECK`]; the serving sensor is checked in the
//! node list every [`SLOT_CHECK`] of silence. A live process is waited for,
//! however slow or paused; only a dead one (or, with `--slot-deadline`, a
//! late one) makes a dead link.

use crate::link::{Fault, Links, SlotResult};
use crate::{AgentError, AgentStats, Exit, IDLE_CHECK, SLOT_CHECK};
use etp_runtime::wire::PortError;
use etp_runtime::wire::agent_to_coordinator::{Outcome, Waypoint};
use etp_runtime::wire::coordinator_to_agent::Control;
use etp_runtime::wire::to_coordinator::Hello;
use etp_runtime::wire::{
    self, AGENT_NODE, COORDINATOR_NODE, ControlKind, Liveness, Notifier, OutcomeCode, Ports, Pub,
    SENDER_AGENT, ServiceId, Stamper, Sub, Waiter, Wake, Watchdog, belief_to_wire,
};
use etp_shared::episode::{CompiledScenario, SlotOutcome, belief_digest};
use etp_shared::rng::{stream_rng, streams};
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
    coordinator_wake: Notifier,
    stats: AgentStats,
    _hello: Option<Pub<Hello>>,
}

/// Counts of the leg in progress.
#[derive(Debug, Clone, Copy, Default)]
struct LegCounts {
    steps: u32,
    received: u32,
    degraded: bool,
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
            coordinator_wake,
            stats: AgentStats::default(),
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
        match self.wait_until(awaiting, |a| {
            a.links.take_slot(episode, k, who, &mut a.stamp)
        })? {
            Waited::Got((y, digest)) => Ok(Ok((SlotResult::Closed(y, digest), None))),
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
        let mut rng = stream_rng(seed, streams::AGENT, episode);
        let mut state = self.c.initial_state(&mut rng);
        let mut k: u32 = 0;
        let mut prev = LegCounts::default();
        let mut totals = Outcome {
            dead_sensor: u32::MAX,
            ..Outcome::default()
        };
        let legs = self.c.legs.len();
        let tag = self.stamp.tag();
        for leg in 0..legs {
            let leg32 = leg as u32;
            let (mean, cov) = belief_to_wire(&state.belief);
            let header = self.stamp.header(episode, leg32, k);
            self.waypoint
                .send_copy(Waypoint {
                    header,
                    dim: N as u32,
                    prev_steps: prev.steps,
                    prev_received: prev.received,
                    prev_degraded: u32::from(prev.degraded),
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
                Ok(a.links.take_open(tag, episode, leg32)?.map(Some))
            })?;
            let (delta, sensor) = match opened {
                Waited::Got(Some(v)) => v,
                Waited::Got(None) => return Ok(Some(Exit::Stopped)),
                Waited::Exit(e) => return Ok(Some(e)),
                Waited::DeadLink(_) => unreachable!("no slot awaited"),
            };
            if sensor != self.c.legs[leg].sensor {
                return Err(AgentError::Protocol(format!(
                    "coordinator opened leg {leg} at sensor {sensor}, the scenario says {}",
                    self.c.legs[leg].sensor
                )));
            }
            // β(δ), or the radio's factor on a lossy link (docs/MODEL.md §8).
            let beta = self.c.silence_beta(sensor, delta);
            if self.links.alive[sensor] {
                let header = self.stamp.header(episode, leg32, k);
                self.links.hand_over(sensor, header, &state.belief)?;
                self.stats.handovers += 1;
            }
            let mut counts = LegCounts::default();
            loop {
                // docs/MODEL.md §3 through episode::step, in this order.
                let u = self.c.input(leg, &state.belief.mean);
                let collided = self.c.move_plant(&mut state.x, &u, &mut rng);
                k += 1;
                counts.steps += 1;
                totals.steps += 1;
                if collided.is_some() {
                    totals.outcome = OutcomeCode::Collision.code();
                    return self
                        .finish(episode, leg32, k, counts, totals)
                        .map(|()| None);
                }
                let prior = self.c.prior(&state.belief, &u);
                let (result, fault) = match self.slot(episode, leg32, k, sensor, &state.x)? {
                    Ok(r) => r,
                    Err(exit) => return Ok(Some(exit)),
                };
                if let Some(f) = fault {
                    record_fault(&mut totals, &f);
                }
                totals.slots += 1;
                let (slot, y) = match result {
                    SlotResult::Closed(y, digest) => {
                        // The sensor triggered on its replica's prior: it
                        // must be ours, bit for bit (docs/MODEL.md §3.2).
                        if digest != belief_digest(&prior) {
                            return Err(AgentError::Protocol(format!(
                                "sensor {sensor}'s replica diverged at episode {episode} step {k}: \
                                 prior digest {digest:#018x}, the agent's {:#018x}",
                                belief_digest(&prior)
                            )));
                        }
                        (true, y)
                    }
                    SlotResult::Dead(y) => {
                        counts.degraded = true;
                        totals.degraded = 1;
                        totals.dead_slots += 1;
                        (false, y)
                    }
                };
                counts.received += u32::from(y.is_some());
                let outcome = match (&y, slot) {
                    (Some(y), _) => SlotOutcome::Transmitted(&y[..]),
                    (None, true) => SlotOutcome::Silent,
                    (None, false) => SlotOutcome::Dead,
                };
                state.belief = self.c.close_slot(leg, &prior, outcome, beta);
                if self.c.leg_ends(leg, &state.belief, counts.steps) {
                    break;
                }
            }
            if leg + 1 == legs {
                totals.outcome = match self.c.classify_end(&state.x) {
                    etp_shared::episode::Outcome::Target => OutcomeCode::Target,
                    _ => OutcomeCode::Free,
                }
                .code();
                return self
                    .finish(episode, leg32, k, counts, totals)
                    .map(|()| None);
            }
            totals.received += counts.received;
            prev = counts;
        }
        Err(AgentError::Protocol("scenario without legs".into()))
    }

    fn finish(
        &mut self,
        episode: u64,
        leg: u32,
        k: u32,
        last: LegCounts,
        mut o: Outcome,
    ) -> Result<(), AgentError> {
        o.header = self.stamp.header(episode, leg, k);
        o.last_steps = last.steps;
        o.last_received = last.received;
        o.received += last.received;
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
            .send_copy(o)
            .map_err(|e| PortError::send("outcome", e))?;
        self.notify_coordinator()
    }
}

fn record_fault(o: &mut Outcome, f: &Fault) {
    if o.dead_sensor == u32::MAX {
        o.dead_sensor = f.sensor;
        o.detect_us = f.detect_us;
        o.wait_started_unix_ns = f.wait_started_unix_ns;
        o.detected_unix_ns = f.detected_unix_ns;
    }
}
