//! One measurement slot over IPC, with dead-link detection.

use crate::{AgentError, SLOT_CHECK, SLOT_DEADLINE};
use etp_shared::etkf::{Belief, Vector};
use etp_shared::wire::agent_to_sensor::{Prior, Truth};
use etp_shared::wire::sensor_to_agent::{Measurement, Slot};
use etp_shared::wire::{
    self, Header, Listener, Liveness, Notifier, Ports, Pub, ServiceId, Sub, WireVec,
    belief_to_wire, to_wire_vec,
};
use iceoryx2::config::Config;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// What one slot brought.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlotResult {
    /// The slot closed: `Some(y)` if the sensor transmitted, `None` if silent
    /// (silence from a live sensor is information: implicit update).
    Closed(Option<WireVec>),
    /// The sensor is dead or hung: no information from silence. A measurement
    /// that did arrive before the death is still returned.
    Dead(Option<WireVec>),
}

/// A dead link as the agent saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fault {
    pub sensor: u32,
    /// From the start of the wait on the slot to the verdict.
    pub detect_us: u64,
    pub wait_started_unix_ns: u64,
    pub detected_unix_ns: u64,
}

/// The agent's ports towards the sensors.
pub struct Links {
    truth: Vec<Pub<Truth>>,
    prior: Vec<Pub<Prior>>,
    wake: Vec<Notifier>,
    slot: Sub<Slot>,
    measurement: Sub<Measurement>,
    /// Liveness as far as the agent knows; a dead sensor stays dead for the run.
    pub alive: Vec<bool>,
    cfg: Config,
}

fn unix_ns(t: SystemTime) -> u64 {
    t.duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

impl Links {
    pub fn new(ports: &Ports<'_>) -> Result<Self, AgentError> {
        let n = ports.sensors;
        Ok(Self {
            truth: (0..n)
                .map(|i| ports.publisher::<Truth>(ServiceId::Truth(i)))
                .collect::<Result<_, _>>()?,
            prior: (0..n)
                .map(|i| ports.publisher::<Prior>(ServiceId::Prior(i)))
                .collect::<Result<_, _>>()?,
            wake: (0..n)
                .map(|i| ports.notifier(ServiceId::SensorWake(i)))
                .collect::<Result<_, _>>()?,
            slot: ports.subscriber::<Slot>(ServiceId::Slot)?,
            measurement: ports.subscriber::<Measurement>(ServiceId::Measurement)?,
            alive: vec![true; n],
            cfg: ports.node.config().clone(),
        })
    }

    /// Run slot `header.step` at sensor `sensor`: publish truth and prior,
    /// wake the sensor, wait for its slot. `wake` is the agent's own listener.
    pub fn exchange<const N: usize>(
        &mut self,
        wake: &Listener,
        mut header: Header,
        sensor: usize,
        x: &Vector<N>,
        prior: &Belief<N>,
    ) -> Result<(SlotResult, Option<Fault>), AgentError> {
        let (mean, cov) = belief_to_wire(prior);
        self.truth[sensor]
            .send_copy(Truth {
                header,
                dim: N as u32,
                _pad: 0,
                x: to_wire_vec(x.as_slice()),
            })
            .map_err(|e| AgentError::Send("truth", format!("{e:?}")))?;
        header.seq = header.seq.wrapping_add(1);
        self.prior[sensor]
            .send_copy(Prior {
                header,
                dim: N as u32,
                _pad: 0,
                mean,
                cov,
            })
            .map_err(|e| AgentError::Send("prior", format!("{e:?}")))?;
        self.wake[sensor]
            .notify()
            .map_err(|e| AgentError::Send("sensor wake", format!("{e:?}")))?;

        let started = Instant::now();
        let started_wall = SystemTime::now();
        let who = sensor as u32;
        loop {
            if let Some(transmitted) = self.take_slot(header.episode, header.step, who)? {
                let y = self.take_measurement(header.episode, header.step, who)?;
                if transmitted && y.is_none() {
                    return Err(AgentError::Protocol(format!(
                        "sensor {sensor} closed slot {} of episode {} as transmitted but no measurement arrived",
                        header.step, header.episode
                    )));
                }
                return Ok((SlotResult::Closed(y), None));
            }
            let woke = wake
                .timed_wait(|_| {}, SLOT_CHECK)
                .map_err(|e| AgentError::Receive("agent wake", format!("{e:?}")))?;
            if woke > 0 {
                continue;
            }
            let silent = started.elapsed();
            let dead = silent >= SLOT_DEADLINE
                || wire::peek_liveness(&self.cfg, &wire::sensor_node_name(sensor))
                    != Liveness::Alive;
            if dead {
                // The verdict's time, before the dead node's cleanup (below),
                // which can take tens of milliseconds.
                let detect_us = started.elapsed().as_micros() as u64;
                let detected_unix_ns = unix_ns(SystemTime::now());
                // One last look: the slot may have closed just before the verdict.
                if let Some(transmitted) = self.take_slot(header.episode, header.step, who)? {
                    let y = self.take_measurement(header.episode, header.step, who)?;
                    if !transmitted || y.is_some() {
                        return Ok((SlotResult::Closed(y), None));
                    }
                }
                self.alive[sensor] = false;
                let y = self.take_measurement(header.episode, header.step, who)?;
                let fault = Fault {
                    sensor: who,
                    detect_us,
                    wait_started_unix_ns: unix_ns(started_wall),
                    detected_unix_ns,
                };
                // Its ports go, so the others' counts drop and listeners get
                // the dead-notifier event.
                wire::remove_dead_nodes(&self.cfg);
                return Ok((SlotResult::Dead(y), Some(fault)));
            }
        }
    }

    /// The slot record of (episode, step, sensor) if it arrived; older records are dropped.
    fn take_slot(
        &mut self,
        episode: u64,
        step: u32,
        sensor: u32,
    ) -> Result<Option<bool>, AgentError> {
        let mut found = None;
        while let Some(s) = self
            .slot
            .receive()
            .map_err(|e| AgentError::Receive("slot", format!("{e:?}")))?
        {
            let h = s.header;
            if h.episode == episode && h.step == step && h.sender == sensor {
                found = Some(s.transmitted == 1);
            }
        }
        Ok(found)
    }

    fn take_measurement(
        &mut self,
        episode: u64,
        step: u32,
        sensor: u32,
    ) -> Result<Option<WireVec>, AgentError> {
        let mut found = None;
        while let Some(s) = self
            .measurement
            .receive()
            .map_err(|e| AgentError::Receive("measurement", format!("{e:?}")))?
        {
            let h = s.header;
            if h.episode == episode && h.step == step && h.sender == sensor {
                found = Some(s.y);
            }
        }
        Ok(found)
    }
}
