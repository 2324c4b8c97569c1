//! The agent's episodes over IPC: the thin adapter around the shared step
//! (`etp_shared::episode::AgentCore`, the one the in-process simulation,
//! the sensor's replica and `replay --verify` run) and the agent's pure
//! decisions ([`crate::core`]): the world is the agent's true plant, each
//! slot is served by a sensor process, each threshold chosen by the
//! coordinator.
//!
//! The agent waits in exactly one place, [`Agent::wait_until`], on its
//! wake-up event; what a silence means depends on whom it waits for
//! ([`Awaiting`]): the coordinator (idle, or a decision point) is checked by
//! the watchdog every [`IDLE_CHECK`]; the serving sensor is checked in the
//! node list every [`SLOT_CHECK`] of silence. A live process is waited for,
//! however slow or paused; only a dead one (or, with `--slot-deadline`, a
//! late one) makes a dead link.

use crate::core::{EpisodeBook, end_code, measurement};
use crate::link::{Fault, Links, SlotResult};
use crate::{AgentError, AgentStats, Exit, IDLE_CHECK, SLOT_CHECK};
use etp_runtime::wire::PortError;
use etp_runtime::wire::agent_to_coordinator::{Outcome, Waypoint};
use etp_runtime::wire::coordinator_to_agent::Control;
use etp_runtime::wire::to_coordinator::Hello;
use etp_runtime::wire::{
    self, AGENT_NODE, COORDINATOR_NODE, ControlKind, Liveness, Notifier, OutcomeCode, Ports, Pub,
    SENDER_AGENT, ServiceId, Stamper, Sub, Waiter, Wake, Watchdog,
};
use etp_shared::episode::{AgentCore, CompiledScenario, OpenSlot, SlotOutcome, Step, StepDriver};
use etp_shared::etkf::Vector;
use etp_shared::rng::{SimRng, stream_rng, streams};
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
    io: AgentIo,
}

/// The agent's ports, its one wait point and its counters.
struct AgentIo {
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
        let hello = wire::say_hello(
            &ports,
            &coordinator_wake,
            Hello {
                header: stamp.header(0, 0, 0),
                pid: std::process::id(),
                _pad: 0,
            },
            wire::HELLO_TIMEOUT,
        )?;
        let io = AgentIo {
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
        };
        Ok(Self {
            c: CompiledScenario::<N>::new(scenario),
            io,
        })
    }

    /// Serve episodes until stopped.
    pub fn serve(self) -> Result<(Exit, AgentStats), AgentError> {
        let Self { c, mut io } = self;
        loop {
            let start = io.wait_until(Awaiting::Coordinator, |a| a.take_control())?;
            match start {
                Waited::Got(Some((episode, seed))) => {
                    let started = Instant::now();
                    let r = io.episode(&c, episode, seed)?;
                    io.stats.busy_seconds += started.elapsed().as_secs_f64();
                    if let Some(exit) = r {
                        return Ok((exit, io.stats));
                    }
                }
                Waited::Got(None) => return Ok((Exit::Stopped, io.stats)),
                Waited::Exit(exit) => return Ok((exit, io.stats)),
                Waited::DeadLink(_) => unreachable!("no slot awaited"),
            }
        }
    }
}

impl AgentIo {
    fn notify_coordinator(&self) -> Result<(), AgentError> {
        self.coordinator_wake
            .notify()
            .map(|_| ())
            .map_err(|e| PortError::notify("coordinator wake", e).into())
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
    fn slot<const N: usize>(
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
        match self.wait_until(awaiting, |a| a.links.take_slot(episode, k, who))? {
            Waited::Got((y, digest)) => Ok(Ok((SlotResult::Closed(y, digest), None))),
            Waited::Exit(e) => Ok(Err(e)),
            Waited::DeadLink(fault) => {
                self.links.alive[sensor] = false;
                let y = self.links.take_measurement(episode, k, who)?;
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
    fn episode<const N: usize>(
        &mut self,
        c: &CompiledScenario<N>,
        episode: u64,
        seed: u64,
    ) -> Result<Option<Exit>, AgentError> {
        tracing::debug!(episode, "episode start");
        let mut rng = stream_rng(seed, streams::AGENT, episode);
        let initial = c.initial_state(&mut rng);
        let mut book = EpisodeBook::new();
        let mut live = Live {
            io: self,
            c,
            x: initial.x,
            rng,
            episode,
            leg: 0,
            book: &mut book,
        };
        let (mut belief, mut k) = (initial.belief, 0);
        let legs = c.legs.len();
        let tag = live.io.stamp.tag();
        for leg in 0..legs {
            let leg32 = leg as u32;
            let header = live.io.stamp.header(episode, leg32, k);
            let waypoint = live.book.waypoint(header, &belief);
            live.io
                .waypoint
                .send_copy(waypoint)
                .map_err(|e| PortError::send("waypoint", e))?;
            live.io.notify_coordinator()?;
            let opened = live.io.wait_until(Awaiting::Coordinator, |a| {
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
            EpisodeBook::check_open(c, leg, sensor)?;
            if live.io.links.alive[sensor] {
                let header = live.io.stamp.header(episode, leg32, k);
                live.io.links.hand_over(sensor, header, &belief)?;
                live.io.stats.handovers += 1;
            }
            live.leg = leg32;
            let mut core = AgentCore::event_triggered(c, leg, delta, belief, k);
            loop {
                // docs/MODEL.md §3, the one step.
                let step = match core.step_any(c, &mut live) {
                    Ok(step) => step,
                    Err(Halt::Exit(exit)) => return Ok(Some(exit)),
                    Err(Halt::Error(e)) => return Err(e),
                };
                match step {
                    Step::Collided { .. } => {
                        live.io.finish(
                            *live.book,
                            (episode, leg32, core.step),
                            &core,
                            OutcomeCode::Collision,
                        )?;
                        return Ok(None);
                    }
                    Step::Closed { leg_ends: true, .. } => break,
                    Step::Closed { .. } => {}
                }
            }
            (belief, k) = (core.belief, core.step);
            if leg + 1 == legs {
                let code = end_code(c, &live.x);
                live.io
                    .finish(*live.book, (episode, leg32, k), &core, code)?;
                return Ok(None);
            }
            live.book.end_leg(&core.counts());
        }
        Err(AgentError::Protocol("scenario without legs".into()))
    }

    /// The episode ended during the leg of `core`: publish its `outcome`.
    fn finish<const N: usize>(
        &mut self,
        book: EpisodeBook,
        (episode, leg, k): (u64, u32, u32),
        core: &AgentCore<N>,
        code: OutcomeCode,
    ) -> Result<(), AgentError> {
        let header = self.stamp.header(episode, leg, k);
        let o = book.finish(header, &core.counts(), code);
        self.stats.episodes += 1;
        self.stats.steps += u64::from(o.steps);
        self.stats.received += u64::from(o.received);
        self.stats.dead_slots += u64::from(o.dead_slots);
        tracing::debug!(
            episode,
            outcome = o.outcome,
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

/// Why a step stopped the episode.
enum Halt {
    Exit(Exit),
    Error(AgentError),
}

impl From<AgentError> for Halt {
    fn from(e: AgentError) -> Self {
        Self::Error(e)
    }
}

/// The agent process as the driver of the shared step: the world is its
/// true plant (stream `AGENT`), each slot is served by the leg's sensor
/// process and judged by the [`EpisodeBook`].
struct Live<'a, const N: usize> {
    io: &'a mut AgentIo,
    c: &'a CompiledScenario<N>,
    x: Vector<N>,
    rng: SimRng,
    episode: u64,
    leg: u32,
    book: &'a mut EpisodeBook,
}

impl<const N: usize, const M: usize> StepDriver<N, M> for Live<'_, N> {
    type Stop = Halt;

    fn advance(&mut self, _step: u32, u: &Vector<N>) -> Result<Option<usize>, Halt> {
        Ok(self.c.move_plant(&mut self.x, u, &mut self.rng))
    }

    fn slot(&mut self, slot: &OpenSlot<'_, N, M>) -> Result<SlotOutcome<Vector<M>>, Halt> {
        let sensor = self.c.legs[slot.leg].sensor;
        let (result, fault) = self
            .io
            .slot(self.episode, self.leg, slot.step, sensor, &self.x)?
            .map_err(Halt::Exit)?;
        let outcome =
            self.book
                .on_slot((self.episode, slot.step, sensor), slot.prior, result, fault)?;
        Ok(match outcome {
            SlotOutcome::Delivered(y) => SlotOutcome::Delivered(measurement::<M>(&y)),
            SlotOutcome::Silent => SlotOutcome::Silent,
            SlotOutcome::Dead => SlotOutcome::Dead,
        })
    }
}
