//! The agent's episodes over IPC: the rules of `etp_shared::episode`, with the
//! slot done by a sensor process and the threshold chosen by the coordinator.

use crate::link::{Fault, Links, SlotResult};
use crate::{AgentError, AgentStats, Exit, IDLE_CHECK};
use etp_shared::controller::{reached, waypoint_input};
use etp_shared::episode::CompiledScenario;
use etp_shared::etkf::Threshold as Th;
use etp_shared::geometry::first_containing;
use etp_shared::rng::{stream_rng, streams};
use etp_shared::scenario::Scenario;
use etp_shared::wire::agent_to_coordinator::{Outcome, Waypoint};
use etp_shared::wire::coordinator_to_agent::Control;
use etp_shared::wire::coordinator_to_all::Threshold;
use etp_shared::wire::to_coordinator::Hello;
use etp_shared::wire::{
    self, AGENT_NODE, COORDINATOR_NODE, Header, Listener, Liveness, Notifier, Ports, Pub,
    SENDER_AGENT, ServiceId, Sub, belief_to_wire,
};
use iceoryx2::prelude::*;
use std::time::Instant;

/// What the agent waits for between episodes and at decision points.
enum Next<T> {
    Go(T),
    Exit(Exit),
}

/// The agent process: its scenario, ports and counters.
pub struct Agent<const N: usize> {
    c: CompiledScenario<N>,
    node: Node<ipc::Service>,
    tag: u64,
    seq: u32,
    links: Links,
    wake: Listener,
    control: Sub<Control>,
    threshold: Sub<Threshold>,
    waypoint: Pub<Waypoint>,
    outcome: Pub<Outcome>,
    coordinator_wake: Notifier,
    parent: u32,
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

impl<const N: usize> Agent<N> {
    pub fn new(run: &wire::RunId, scenario: &Scenario) -> Result<Self, AgentError> {
        let node = wire::create_node(run, AGENT_NODE)?;
        let sensors = scenario.sensors.len();
        let ports = Ports {
            node: &node,
            run,
            sensors,
        };
        let links = Links::new(&ports)?;
        let wake = ports.listener(ServiceId::AgentWake)?;
        let control = ports.subscriber::<Control>(ServiceId::Control)?;
        let threshold = ports.subscriber::<Threshold>(ServiceId::Threshold)?;
        let waypoint = ports.publisher::<Waypoint>(ServiceId::Waypoint)?;
        let outcome = ports.publisher::<Outcome>(ServiceId::Outcome)?;
        let coordinator_wake = ports.notifier(ServiceId::CoordinatorWake)?;
        let mut agent = Self {
            c: CompiledScenario::<N>::new(scenario),
            tag: run.tag(),
            seq: 0,
            links,
            wake,
            control,
            threshold,
            waypoint,
            outcome,
            coordinator_wake,
            parent: std::os::unix::process::parent_id(),
            stats: AgentStats::default(),
            _hello: None,
            node,
        };
        let h = agent.header(0, 0, 0);
        agent._hello = Some(wire::say_hello(
            &Ports {
                node: &agent.node,
                run,
                sensors,
            },
            Hello {
                header: h,
                pid: std::process::id(),
                _pad: 0,
            },
            wire::HELLO_TIMEOUT,
        )?);
        Ok(agent)
    }

    fn header(&mut self, episode: u64, leg: u32, step: u32) -> Header {
        self.seq = self.seq.wrapping_add(2);
        Header {
            run: self.tag,
            episode,
            step,
            leg,
            sender: SENDER_AGENT,
            seq: self.seq,
        }
    }

    fn notify_coordinator(&self) -> Result<(), AgentError> {
        self.coordinator_wake
            .notify()
            .map(|_| ())
            .map_err(|e| AgentError::Send("coordinator wake", format!("{e:?}")))
    }

    /// Serve episodes until stopped.
    pub fn serve(mut self) -> Result<(Exit, AgentStats), AgentError> {
        // `say_hello` waited for the coordinator's subscriber: it was alive.
        let mut seen_coordinator = true;
        loop {
            let next = self.wait(&mut seen_coordinator, |a| {
                while let Some(s) = a
                    .control
                    .receive()
                    .map_err(|e| AgentError::Receive("control", format!("{e:?}")))?
                {
                    let c: Control = *s;
                    if c.header.run != a.tag {
                        continue;
                    }
                    match c.kind {
                        Control::START => return Ok(Some(Next::Go((c.header.episode, c.seed)))),
                        Control::STOP => return Ok(Some(Next::Exit(Exit::Stopped))),
                        _ => {}
                    }
                }
                Ok(None)
            })?;
            match next {
                Next::Go((episode, seed)) => {
                    let started = Instant::now();
                    let r = self.episode(episode, seed, &mut seen_coordinator)?;
                    self.stats.busy_seconds += started.elapsed().as_secs_f64();
                    if let Some(exit) = r {
                        return Ok((exit, self.stats));
                    }
                }
                Next::Exit(exit) => return Ok((exit, self.stats)),
            }
        }
    }

    /// Block on the agent's wake-up event until `poll` yields something;
    /// every [`IDLE_CHECK`] of silence, check signals and the coordinator.
    fn wait<T>(
        &mut self,
        seen_coordinator: &mut bool,
        mut poll: impl FnMut(&mut Self) -> Result<Option<Next<T>>, AgentError>,
    ) -> Result<Next<T>, AgentError> {
        loop {
            if let Some(n) = poll(self)? {
                return Ok(n);
            }
            let woke = match self.wake.timed_wait(|_| {}, IDLE_CHECK) {
                Ok(n) => n,
                // A signal interrupts the wait: it is a termination request.
                Err(_) if wire::termination_requested(&self.node) => {
                    return Ok(Next::Exit(Exit::Signal));
                }
                Err(e) => return Err(AgentError::Receive("agent wake", format!("{e:?}"))),
            };
            if woke > 0 {
                continue;
            }
            if wire::termination_requested(&self.node) {
                return Ok(Next::Exit(Exit::Signal));
            }
            if std::os::unix::process::parent_id() != self.parent {
                return Ok(Next::Exit(Exit::CoordinatorGone));
            }
            match wire::liveness(self.node.config(), COORDINATOR_NODE) {
                Liveness::Alive => *seen_coordinator = true,
                Liveness::Missing if !*seen_coordinator => {}
                Liveness::Dead | Liveness::Missing => return Ok(Next::Exit(Exit::CoordinatorGone)),
            }
        }
    }

    /// Wait for the coordinator to open `leg` of `episode`: (δ, serving sensor).
    fn wait_open(
        &mut self,
        episode: u64,
        leg: u32,
        seen: &mut bool,
    ) -> Result<Next<(f64, usize)>, AgentError> {
        self.wait(seen, |a| {
            while let Some(s) = a
                .threshold
                .receive()
                .map_err(|e| AgentError::Receive("threshold", format!("{e:?}")))?
            {
                let t: Threshold = *s;
                if t.header.run != a.tag {
                    continue;
                }
                match t.kind {
                    Threshold::STOP => return Ok(Some(Next::Exit(Exit::Stopped))),
                    Threshold::OPEN if t.header.episode == episode && t.header.leg == leg => {
                        return Ok(Some(Next::Go((t.delta, t.sensor as usize))));
                    }
                    _ => {}
                }
            }
            Ok(None)
        })
    }

    /// One episode; `Some(exit)` if the process must stop.
    fn episode(
        &mut self,
        episode: u64,
        seed: u64,
        seen: &mut bool,
    ) -> Result<Option<Exit>, AgentError> {
        let mut rng = stream_rng(seed, streams::AGENT, episode);
        let mut state = self.c.initial_state(&mut rng);
        let mut k: u32 = 0;
        let mut prev = LegCounts::default();
        let mut totals = Outcome {
            dead_sensor: u32::MAX,
            ..Outcome::default()
        };
        let legs = self.c.legs.len();
        for leg in 0..legs {
            let leg32 = leg as u32;
            let (mean, cov) = belief_to_wire(&state.belief);
            let header = self.header(episode, leg32, k);
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
                .map_err(|e| AgentError::Send("waypoint", format!("{e:?}")))?;
            self.notify_coordinator()?;
            let (delta, sensor) = match self.wait_open(episode, leg32, seen)? {
                Next::Go(v) => v,
                Next::Exit(e) => return Ok(Some(e)),
            };
            if sensor != self.c.legs[leg].sensor {
                return Err(AgentError::Protocol(format!(
                    "coordinator opened leg {leg} at sensor {sensor}, the scenario says {}",
                    self.c.legs[leg].sensor
                )));
            }
            let th = Th::new(delta);
            let w = self.c.legs[leg].waypoint;
            let mut counts = LegCounts::default();
            loop {
                // MODEL.md §3, steps 1–5, in this order.
                let u = waypoint_input(&state.belief.mean, &w, self.c.u_max);
                state.x = self.c.plant.step(&state.x, &u, &mut rng);
                k += 1;
                counts.steps += 1;
                totals.steps += 1;
                if first_containing(&self.c.obstacles, &state.x).is_some() {
                    totals.outcome = Outcome::COLLISION;
                    return self
                        .finish(episode, leg32, k, counts, totals)
                        .map(|()| None);
                }
                let prior = self.c.plant.predict(&state.belief, &u);
                let result = if self.links.alive[sensor] {
                    let h = self.header(episode, leg32, k);
                    let wake = &self.wake;
                    let (r, fault) = self.links.exchange(wake, h, sensor, &state.x, &prior)?;
                    if let Some(f) = fault {
                        record_fault(&mut totals, &f);
                    }
                    r
                } else {
                    SlotResult::Dead(None)
                };
                totals.slots += 1;
                state.belief = match result {
                    SlotResult::Closed(y) => {
                        counts.received += u32::from(y.is_some());
                        self.c.filters[sensor].posterior(
                            &prior,
                            y.as_ref().map(|y| &y[..]),
                            th.beta,
                        )
                    }
                    SlotResult::Dead(y) => {
                        counts.degraded = true;
                        totals.degraded = 1;
                        totals.dead_slots += 1;
                        counts.received += u32::from(y.is_some());
                        match y {
                            Some(y) => self.c.filters[sensor].posterior(&prior, Some(&y[..]), 0.0),
                            // Silence from a dead link carries no information.
                            None => prior,
                        }
                    }
                };
                if reached(&state.belief.mean, &w, self.c.eps_x) || counts.steps >= self.c.k_max {
                    break;
                }
            }
            if leg + 1 == legs {
                totals.outcome = if self.c.target.contains(&state.x) {
                    Outcome::TARGET
                } else {
                    Outcome::FREE
                };
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
        o.header = self.header(episode, leg, k);
        o.last_steps = last.steps;
        o.last_received = last.received;
        o.received += last.received;
        self.stats.episodes += 1;
        self.stats.steps += u64::from(o.steps);
        self.stats.received += u64::from(o.received);
        self.stats.dead_slots += u64::from(o.dead_slots);
        self.outcome
            .send_copy(o)
            .map_err(|e| AgentError::Send("outcome", format!("{e:?}")))?;
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
