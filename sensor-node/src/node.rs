//! The sensor's iceoryx2 adapter: one wait point ([`Waiter`]), a closed set
//! of wake-ups, and [`SensorCore`] deciding what every message means.

use crate::core::{ControlAction, SensorCore, SensorId, SensorStats, SlotError};
use crate::{Exit, IDLE_CHECK, LIST_EVERY, SensorError};
use etp_runtime::wire::PortError;
use etp_runtime::wire::agent_to_sensor::{Ack, Handover, Truth};
use etp_runtime::wire::coordinator_to_sensor::Threshold;
use etp_runtime::wire::sensor_to_agent::{Measurement, Slot};
use etp_runtime::wire::sensor_to_coordinator::Ledger;
use etp_runtime::wire::{
    self, COORDINATOR_NODE, Notifier, Ports, Pub, ServiceId, Stamper, Sub, Waiter, Wake, Watchdog,
};
use etp_shared::episode::CompiledScenario;
use etp_shared::etkf::EtKalmanFilter;
use etp_shared::scenario::Scenario;
use iceoryx2::prelude::*;

/// The sensor's ports.
struct SensorPorts {
    truth: Sub<Truth>,
    handover: Sub<Handover>,
    ack: Sub<Ack>,
    threshold: Sub<Threshold>,
    measurement: Pub<Measurement>,
    slot: Pub<Slot>,
    ledger: Pub<Ledger>,
    agent_wake: Notifier,
    coordinator_wake: Notifier,
}

fn send<T: std::fmt::Debug + ZeroCopySend + Copy + 'static>(
    p: &Pub<T>,
    what: &'static str,
    v: T,
) -> Result<(), SensorError> {
    p.publish(v)
        .map(|_| ())
        .map_err(|e| PortError::send(what, e).into())
}

fn notify(n: &Notifier, what: &'static str) -> Result<(), SensorError> {
    n.notify()
        .map(|_| ())
        .map_err(|e| PortError::notify(what, e).into())
}

fn receive<T: std::fmt::Debug + ZeroCopySend + Copy>(
    s: &Sub<T>,
    what: &'static str,
) -> Result<Option<T>, SensorError> {
    s.receive()
        .map(|o| o.map(|x| *x))
        .map_err(|e| PortError::receive(what, e).into())
}

pub(crate) fn serve<const N: usize, const M: usize>(
    run: &wire::RunId,
    scenario: &Scenario,
    index: usize,
    seed: u64,
    schedule: etp_shared::radio::schedule::ChannelSchedule,
) -> Result<(Exit, SensorStats), SensorError> {
    let filter = EtKalmanFilter::<N, M>::new(&scenario.plant, &scenario.sensors[index]);
    let node = wire::create_node(run, &wire::sensor_node_name(index))?;
    let cfg = node.config().clone();
    let ports = Ports {
        node: &node,
        run,
        sensors: scenario.sensors.len(),
    };
    let p = SensorPorts {
        truth: ports.subscriber(ServiceId::Truth(index))?,
        handover: ports.subscriber(ServiceId::Handover(index))?,
        ack: ports.subscriber(ServiceId::Ack(index))?,
        threshold: ports.subscriber(ServiceId::Threshold(index))?,
        measurement: ports.publisher(ServiceId::Measurement)?,
        slot: ports.publisher(ServiceId::Slot)?,
        ledger: ports.publisher(ServiceId::Ledger)?,
        agent_wake: ports.notifier(ServiceId::AgentWake)?,
        coordinator_wake: ports.notifier(ServiceId::CoordinatorWake)?,
    };
    let waiter = Waiter::new(ports.listener(ServiceId::SensorWake(index))?)?;
    let mut stamp = Stamper::new(run, index as u32);
    let _hello = wire::say_hello(&ports, &p.coordinator_wake, &mut stamp)?;
    let mut core = SensorCore::new(
        CompiledScenario::<N>::new(scenario),
        filter,
        scenario.sensors[index].cost,
        SensorId {
            index: index as u32,
            seed,
            tag: run.tag(),
        },
    )
    .with_schedule(schedule);
    // `say_hello` waited for the coordinator's subscriber: it was alive.
    let mut watchdog = Watchdog::new(COORDINATOR_NODE, true, LIST_EVERY);
    let mut pending = Pending::default();
    tracing::info!(sensor = %scenario.sensors[index].name, "sensor ready");
    loop {
        match waiter.wait(&node, IDLE_CHECK)? {
            Wake::Terminate => return Ok((Exit::Signal, core.stats)),
            Wake::Silence => {
                if watchdog.gone(&cfg, false) {
                    return Ok((Exit::CoordinatorGone, core.stats));
                }
                continue;
            }
            Wake::Notified { dead_peer } => {
                if dead_peer && watchdog.gone(&cfg, true) {
                    return Ok((Exit::CoordinatorGone, core.stats));
                }
            }
        }
        core.stats.wakeups += 1;
        if let Some(exit) = serve_pending(&p, &mut core, &mut stamp, &mut pending)? {
            return Ok((exit, core.stats));
        }
    }
}

/// Messages that arrived before what they depend on (over a bridge the
/// services of one sensor travel separately: a handover may land before its
/// leg's OPEN, a truth before its handover). They wait here, in order.
#[derive(Default)]
struct Pending {
    handovers: std::collections::VecDeque<Handover>,
    truths: std::collections::VecDeque<Truth>,
}

/// Everything that arrived, in causal order: thresholds (the coordinator
/// opens a leg before the agent hands over), handovers (the agent hands over
/// before the leg's first truth), then each truth: one slot each. A message
/// whose predecessor has not arrived waits in `pending` for the next
/// wake-up; one that can never be served is a protocol error.
fn serve_pending<const N: usize, const M: usize>(
    p: &SensorPorts,
    core: &mut SensorCore<N, M>,
    stamp: &mut Stamper,
    pending: &mut Pending,
) -> Result<Option<Exit>, SensorError> {
    if let Some(exit) = drain_thresholds(p, core, stamp)? {
        return Ok(Some(exit));
    }
    // ACKs of earlier deliveries (the agent sends each before the next
    // truth); one that matches no delivery is a protocol error.
    while let Some(a) = receive(&p.ack, "ack")? {
        core.on_ack(&a)
            .map_err(|e| SensorError::Protocol(e.to_string()))?;
    }
    while let Some(h) = receive(&p.handover, "handover")? {
        pending.handovers.push_back(h);
    }
    while let Some(h) = pending.handovers.front() {
        match core.on_handover(h) {
            Ok(()) => {
                pending.handovers.pop_front();
            }
            Err(SlotError::LegNotOpen { .. }) => break,
            Err(e) => return Err(SensorError::Protocol(e.to_string())),
        }
    }
    while let Some(t) = receive(&p.truth, "truth")? {
        pending.truths.push_back(t);
    }
    while let Some(truth) = pending.truths.front() {
        let decision = match core.on_slot(truth) {
            Ok(d) => d,
            Err(SlotError::LegNotOpen { .. } | SlotError::NoHandover { .. })
                if !core.is_closed(truth.header.episode, truth.header.leg) =>
            {
                break;
            }
            Err(e) => return Err(SensorError::Protocol(e.to_string())),
        };
        pending.truths.pop_front();
        if let Some((y, sequence)) = decision.transmit {
            let header = stamp.header(decision.episode, decision.leg, decision.step);
            send(
                &p.measurement,
                "measurement",
                Measurement {
                    header,
                    dim: M as u32,
                    sequence,
                    y,
                },
            )?;
        }
        let header = stamp.header(decision.episode, decision.leg, decision.step);
        send(
            &p.slot,
            "slot",
            Slot {
                header,
                delivered: u32::from(decision.transmit.is_some()),
                attempts: decision.attempts,
                prior_digest: decision.prior_digest,
            },
        )?;
        notify(&p.agent_wake, "agent wake")?;
    }
    Ok(None)
}

fn drain_thresholds<const N: usize, const M: usize>(
    p: &SensorPorts,
    core: &mut SensorCore<N, M>,
    stamp: &mut Stamper,
) -> Result<Option<Exit>, SensorError> {
    while let Some(t) = receive(&p.threshold, "threshold")? {
        match core.on_threshold(&t) {
            ControlAction::None => {}
            ControlAction::Stop => return Ok(Some(Exit::Stopped)),
            ControlAction::Ledger { ledger, energy } => {
                tracing::debug!(
                    episode = ledger.episode,
                    leg = ledger.leg,
                    transmissions = ledger.transmissions,
                    "ledger"
                );
                let header = stamp.header(ledger.episode, ledger.leg, 0);
                send(
                    &p.ledger,
                    "ledger",
                    Ledger {
                        header,
                        slots: ledger.slots,
                        triggers: ledger.triggers,
                        transmissions: ledger.transmissions,
                        delivered: ledger.delivered,
                        lost: ledger.lost,
                        _pad: 0,
                        energy,
                    },
                )?;
                notify(&p.coordinator_wake, "coordinator wake")?;
            }
        }
    }
    Ok(None)
}
