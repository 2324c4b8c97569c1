//! The sensor's event loop and per-slot work.

use crate::{Exit, IDLE_CHECK, SensorError};
use etp_shared::etkf::{EtKalmanFilter, Vector};
use etp_shared::rng::{stream_rng, streams};
use etp_shared::scenario::Scenario;
use etp_shared::wire::agent_to_sensor::{Prior, Truth};
use etp_shared::wire::coordinator_to_all::Threshold;
use etp_shared::wire::sensor_to_agent::{Measurement, Slot};
use etp_shared::wire::sensor_to_coordinator::Ledger;
use etp_shared::wire::to_coordinator::Hello;
use etp_shared::wire::{
    self, COORDINATOR_NODE, Header, Liveness, Ports, ServiceId, belief_from_wire, to_wire_vec,
    vec_from_wire,
};
use iceoryx2::prelude::EventId;

/// What the sensor spent on one leg.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LegLedger {
    pub episode: u64,
    pub leg: u32,
    pub slots: u32,
    pub transmissions: u32,
}

/// Totals of a sensor process (logged at exit).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SensorStats {
    pub slots: u64,
    pub transmissions: u64,
    pub wakeups: u64,
}

/// The open leg: its threshold and its ledger so far.
#[derive(Debug, Clone, Copy)]
struct OpenLeg {
    delta: f64,
    ledger: LegLedger,
}

pub(crate) fn serve<const N: usize, const M: usize>(
    run: &wire::RunId,
    scenario: &Scenario,
    index: usize,
    seed: u64,
) -> Result<(Exit, SensorStats), SensorError> {
    let filter = EtKalmanFilter::<N, M>::new(&scenario.plant, &scenario.sensors[index]);
    let cost = scenario.sensors[index].cost;
    let node = wire::create_node(run, &wire::sensor_node_name(index))?;
    let cfg = node.config().clone();
    let ports = Ports {
        node: &node,
        run,
        sensors: scenario.sensors.len(),
    };
    let truth_sub = ports.subscriber::<Truth>(ServiceId::Truth(index))?;
    let prior_sub = ports.subscriber::<Prior>(ServiceId::Prior(index))?;
    let threshold_sub = ports.subscriber::<Threshold>(ServiceId::Threshold)?;
    let measurement_pub = ports.publisher::<Measurement>(ServiceId::Measurement)?;
    let slot_pub = ports.publisher::<Slot>(ServiceId::Slot)?;
    let ledger_pub = ports.publisher::<Ledger>(ServiceId::Ledger)?;
    let wake = ports.listener(ServiceId::SensorWake(index))?;
    let agent_wake = ports.notifier(ServiceId::AgentWake)?;
    let coordinator_wake = ports.notifier(ServiceId::CoordinatorWake)?;

    let tag = run.tag();
    let sender = index as u32;
    let mut seq = 0u32;
    let mut header = |episode: u64, leg: u32, step: u32| {
        seq = seq.wrapping_add(1);
        Header {
            run: tag,
            episode,
            step,
            leg,
            sender,
            seq,
        }
    };
    let _hello = wire::say_hello(
        &ports,
        Hello {
            header: header(0, 0, 0),
            pid: std::process::id(),
            _pad: 0,
        },
        wire::HELLO_TIMEOUT,
    )?;

    let parent = std::os::unix::process::parent_id();
    // `say_hello` waited for the coordinator's subscriber: it was alive.
    let mut seen_coordinator = true;
    let mut open: Option<OpenLeg> = None;
    let mut truth: Option<Truth> = None;
    let mut stats = SensorStats::default();
    let mut episode_transmissions = 0u32;
    let mut episode_of_count = u64::MAX;

    // A prior whose leg was not open yet: the coordinator's OPEN was
    // published before the agent could send it, so draining the thresholds
    // once more finds it.
    let mut pending: Option<Prior> = None;
    let mut idle_checks = 0u32;
    'wake: loop {
        let mut peer_died = false;
        let woke = if pending.is_some() {
            1
        } else {
            let dead = EventId::new(wire::DEAD_NOTIFIER_EVENT);
            match wake.timed_wait(|ev| peer_died |= ev.id == dead, IDLE_CHECK) {
                Ok(n) => n,
                // A signal interrupts the wait: it is a termination request.
                Err(_) if wire::termination_requested(&node) => return Ok((Exit::Signal, stats)),
                Err(e) => return Err(SensorError::Protocol(format!("wait: {e:?}"))),
            }
        };
        if woke == 0 || peer_died {
            if wire::termination_requested(&node) {
                return Ok((Exit::Signal, stats));
            }
            if std::os::unix::process::parent_id() != parent {
                return Ok((Exit::CoordinatorGone, stats));
            }
            // The node list costs milliseconds: only when a peer's death was
            // signalled (iceoryx2's dead-notifier event, emitted when someone
            // cleans a dead node up) or every LIST_EVERY idle periods.
            idle_checks = idle_checks.wrapping_add(u32::from(woke == 0));
            if peer_died || idle_checks.is_multiple_of(crate::LIST_EVERY) {
                match wire::liveness(&cfg, COORDINATOR_NODE) {
                    Liveness::Alive => seen_coordinator = true,
                    Liveness::Dead => return Ok((Exit::CoordinatorGone, stats)),
                    Liveness::Missing if seen_coordinator => {
                        return Ok((Exit::CoordinatorGone, stats));
                    }
                    Liveness::Missing => {}
                }
            }
            if woke == 0 {
                continue;
            }
        }
        stats.wakeups += 1;

        // 1. Thresholds first: the coordinator publishes a leg's threshold
        //    before the agent can publish that leg's first prior.
        while let Some(s) = threshold_sub
            .receive()
            .map_err(|e| SensorError::Protocol(format!("threshold: {e:?}")))?
        {
            let t: Threshold = *s;
            if t.header.run != tag {
                continue;
            }
            match t.kind {
                Threshold::STOP => return Ok((Exit::Stopped, stats)),
                Threshold::OPEN if t.sensor == sender => {
                    open = Some(OpenLeg {
                        delta: t.delta,
                        ledger: LegLedger {
                            episode: t.header.episode,
                            leg: t.header.leg,
                            slots: 0,
                            transmissions: 0,
                        },
                    });
                }
                Threshold::CLOSE if t.sensor == sender => {
                    let l = match open {
                        Some(o)
                            if o.ledger.episode == t.header.episode
                                && o.ledger.leg == t.header.leg =>
                        {
                            o.ledger
                        }
                        // A leg that never reached this sensor (e.g. ended by a
                        // collision on its first step) spent nothing.
                        _ => LegLedger {
                            episode: t.header.episode,
                            leg: t.header.leg,
                            ..LegLedger::default()
                        },
                    };
                    open = None;
                    ledger_pub
                        .send_copy(Ledger {
                            header: header(l.episode, l.leg, 0),
                            slots: l.slots,
                            transmissions: l.transmissions,
                            energy: f64::from(l.transmissions) * cost,
                        })
                        .map_err(|e| SensorError::Send("ledger", format!("{e:?}")))?;
                    coordinator_wake
                        .notify()
                        .map_err(|e| SensorError::Send("coordinator wake", format!("{e:?}")))?;
                }
                _ => {}
            }
        }

        // 2. A prior, then the truth of the same step (published before the
        //    prior, so it is there once the prior is): one slot.
        loop {
            let retried = pending.is_some();
            let p: Prior = match pending.take() {
                Some(p) => p,
                None => match prior_sub
                    .receive()
                    .map_err(|e| SensorError::Protocol(format!("prior: {e:?}")))?
                {
                    Some(s) => *s,
                    None => break,
                },
            };
            while let Some(s) = truth_sub
                .receive()
                .map_err(|e| SensorError::Protocol(format!("truth: {e:?}")))?
            {
                truth = Some(*s);
            }
            let Some(t) = truth
                .filter(|t| t.header.episode == p.header.episode && t.header.step == p.header.step)
            else {
                return Err(SensorError::Protocol(format!(
                    "prior of episode {} step {} without its truth",
                    p.header.episode, p.header.step
                )));
            };
            let is_open =
                |o: &OpenLeg| o.ledger.episode == p.header.episode && o.ledger.leg == p.header.leg;
            if !open.as_ref().is_some_and(is_open) {
                if retried {
                    return Err(SensorError::Protocol(format!(
                        "prior for episode {} leg {} but the open leg is {:?}",
                        p.header.episode,
                        p.header.leg,
                        open.map(|o| (o.ledger.episode, o.ledger.leg))
                    )));
                }
                pending = Some(p);
                continue 'wake;
            }
            let Some(leg) = open.as_mut() else { continue };
            // Measurement noise: keyed by (episode, step), independent of timing.
            let mut rng = stream_rng(
                seed,
                streams::SENSOR,
                (p.header.episode << 32) | u64::from(p.header.step),
            );
            let x: Vector<N> = vec_from_wire(&t.x);
            let y = filter.sensor.measure(&x, &mut rng);
            let prior = belief_from_wire::<N>(&p.mean, &p.cov);
            let inn = filter.innovation(&prior);
            let transmit = inn.triggers(&y, leg.delta);
            leg.ledger.slots += 1;
            stats.slots += 1;
            if episode_of_count != p.header.episode {
                episode_of_count = p.header.episode;
                episode_transmissions = 0;
            }
            if transmit {
                leg.ledger.transmissions += 1;
                stats.transmissions += 1;
                episode_transmissions += 1;
                measurement_pub
                    .send_copy(Measurement {
                        header: header(p.header.episode, p.header.leg, p.header.step),
                        dim: M as u32,
                        sequence: episode_transmissions,
                        y: to_wire_vec(y.as_slice()),
                    })
                    .map_err(|e| SensorError::Send("measurement", format!("{e:?}")))?;
            }
            slot_pub
                .send_copy(Slot {
                    header: header(p.header.episode, p.header.leg, p.header.step),
                    transmitted: u32::from(transmit),
                    _pad: 0,
                })
                .map_err(|e| SensorError::Send("slot", format!("{e:?}")))?;
            agent_wake
                .notify()
                .map_err(|e| SensorError::Send("agent wake", format!("{e:?}")))?;
        }
    }
}
