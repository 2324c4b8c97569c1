//! The agent's ports towards the sensors: hand the belief over at the start
//! of a leg, publish each slot's truth, and take what came back.
//!
//! Waiting is not done here: the agent waits in one place
//! ([`crate::runtime::Agent`] through `wire::Waiter`) and polls
//! [`Links::take_slot`] after each wake-up.

use crate::AgentError;
use etp_runtime::wire::PortError;
use etp_runtime::wire::agent_to_sensor::{Ack, Handover, Truth};
use etp_runtime::wire::coordinator_to_sensor::Threshold;
use etp_runtime::wire::sensor_to_agent::{Measurement, Slot};
use etp_runtime::wire::{
    Header, Notifier, Ports, Pub, ServiceId, Stamper, Sub, WireVec, belief_to_wire, to_wire_vec,
};
use etp_shared::etkf::{Belief, Vector};

/// The agent's ports towards the sensors.
pub struct Links {
    truth: Vec<Pub<Truth>>,
    handover: Vec<Pub<Handover>>,
    /// The radio's ACK of each received measurement (docs/MODEL.md §8).
    ack: Vec<Pub<Ack>>,
    wake: Vec<Notifier>,
    /// Every sensor's `threshold` service (the agent takes its δ from the
    /// OPEN of the serving sensor, and drains the others so they never fill).
    threshold: Vec<Sub<Threshold>>,
    slot: Sub<Slot>,
    measurement: Sub<Measurement>,
    /// Liveness as far as the agent knows; a dead sensor stays dead for the run.
    pub alive: Vec<bool>,
    /// Transmission attempts of the last slot [`Links::take_slot`] closed
    /// (for the live view's counts only).
    pub last_attempts: u32,
}

impl Links {
    pub fn new(ports: &Ports<'_>) -> Result<Self, AgentError> {
        let n = ports.sensors;
        Ok(Self {
            truth: (0..n)
                .map(|i| ports.publisher::<Truth>(ServiceId::Truth(i)))
                .collect::<Result<_, _>>()?,
            handover: (0..n)
                .map(|i| ports.publisher::<Handover>(ServiceId::Handover(i)))
                .collect::<Result<_, _>>()?,
            ack: (0..n)
                .map(|i| ports.publisher::<Ack>(ServiceId::Ack(i)))
                .collect::<Result<_, _>>()?,
            wake: (0..n)
                .map(|i| ports.notifier(ServiceId::SensorWake(i)))
                .collect::<Result<_, _>>()?,
            threshold: (0..n)
                .map(|i| ports.subscriber::<Threshold>(ServiceId::Threshold(i)))
                .collect::<Result<_, _>>()?,
            slot: ports.subscriber::<Slot>(ServiceId::Slot)?,
            measurement: ports.subscriber::<Measurement>(ServiceId::Measurement)?,
            alive: vec![true; n],
            last_attempts: 0,
        })
    }

    /// Hand the belief at the start of leg `header.leg` over to its serving
    /// sensor (radio: once per leg); its replica computes the leg's priors.
    /// No wake-up: the leg's first truth follows at once.
    pub fn hand_over<const N: usize>(
        &mut self,
        sensor: usize,
        header: Header,
        belief: &Belief<N>,
    ) -> Result<(), AgentError> {
        let (mean, cov) = belief_to_wire(belief);
        self.handover[sensor]
            .publish(Handover {
                header,
                dim: N as u32,
                _pad: 0,
                mean,
                cov,
            })
            .map(|_| ())
            .map_err(|e| PortError::send("handover", e).into())
    }

    /// Open slot `header.step` at `sensor`: publish the truth (simulation
    /// plumbing: it stands in for the world the sensor measures), then wake
    /// the sensor.
    pub fn open_slot<const N: usize>(
        &mut self,
        sensor: usize,
        header: Header,
        x: &Vector<N>,
    ) -> Result<(), AgentError> {
        self.truth[sensor]
            .publish(Truth {
                header,
                dim: N as u32,
                _pad: 0,
                x: to_wire_vec(x.as_slice()),
            })
            .map_err(|e| PortError::send("truth", e))?;
        self.wake[sensor]
            .notify()
            .map(|_| ())
            .map_err(|e| PortError::notify("sensor wake", e).into())
    }

    /// The slot of (episode, step, sensor) if it closed: its measurement and
    /// the replica's prior digest. Records of earlier slots are dropped. A
    /// received measurement is acknowledged to its sensor (no wake-up: the
    /// sensor reads the ACK with its next message).
    pub fn take_slot(
        &mut self,
        episode: u64,
        step: u32,
        sensor: u32,
        stamp: &mut Stamper,
    ) -> Result<Option<(Option<WireVec>, u64)>, AgentError> {
        let mut closed = None;
        while let Some(s) = self
            .slot
            .receive()
            .map_err(|e| PortError::receive("slot", e))?
        {
            let h = s.header;
            if h.episode == episode && h.step == step && h.sender == sensor {
                closed = Some((s.delivered == 1, s.prior_digest, h.leg, s.attempts));
            }
        }
        let Some((delivered, digest, leg, attempts)) = closed else {
            return Ok(None);
        };
        self.last_attempts = attempts;
        let m = self.take_measurement(episode, step, sensor)?;
        if delivered && m.is_none() {
            return Err(AgentError::Protocol(format!(
                "sensor {sensor} closed slot {step} of episode {episode} as delivered but no measurement arrived"
            )));
        }
        if let Some((_, sequence)) = m {
            self.ack[sensor as usize]
                .publish(Ack {
                    header: stamp.header(episode, leg, step),
                    sequence,
                    _pad: 0,
                })
                .map_err(|e| PortError::send("ack", e))?;
        }
        Ok(Some((m.map(|(y, _)| y), digest)))
    }

    /// The measurement of (episode, step, sensor), if one arrived: y and its
    /// sequence.
    pub fn take_measurement(
        &mut self,
        episode: u64,
        step: u32,
        sensor: u32,
    ) -> Result<Option<(WireVec, u32)>, AgentError> {
        let mut found = None;
        while let Some(s) = self
            .measurement
            .receive()
            .map_err(|e| PortError::receive("measurement", e))?
        {
            let h = s.header;
            if h.episode == episode && h.step == step && h.sender == sensor {
                found = Some((s.y, s.sequence));
            }
        }
        Ok(found)
    }

    /// Drain every sensor's `threshold`; the OPEN of (episode, leg) if it
    /// came: (δ, sensor).
    pub fn take_open(
        &mut self,
        tag: u64,
        episode: u64,
        leg: u32,
    ) -> Result<Option<(f64, usize)>, AgentError> {
        let mut found = None;
        for sub in &self.threshold {
            while let Some(s) = sub
                .receive()
                .map_err(|e| PortError::receive("threshold", e))?
            {
                let t: Threshold = *s;
                if t.header.run == tag
                    && t.kind == Threshold::OPEN
                    && t.header.episode == episode
                    && t.header.leg == leg
                {
                    found = Some((t.delta, t.sensor as usize));
                }
            }
        }
        Ok(found)
    }
}
