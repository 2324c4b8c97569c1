//! A leg's OPEN that reaches its sensor after the leg's first truth.
//!
//! The coordinator's `threshold` service has two readers, the sensor and
//! the agent, and iceoryx2 hands a sample to them one after the other. The
//! agent can therefore read the OPEN, hand over and send the leg's first
//! truth (waking the sensor) while the OPEN is not yet in the sensor's
//! queue: the sensor keeps the truth until its leg opens, and looks again
//! only when woken. This test plays the coordinator and the agent at the
//! wire against the real `etp-sensor-node` and shows both halves: without a
//! wake-up after the OPEN the slot never comes (the run hung, the agent in
//! its slot wait and every sensor idle), with it the slot is served. The
//! coordinator wakes the sensor after every `threshold` it sends
//! (`coordinator::core::Opening::sends`, tested there).

use etp_runtime::wire::agent_to_sensor::{Handover, Truth};
use etp_runtime::wire::coordinator_to_sensor::Threshold;
use etp_runtime::wire::sensor_to_agent::Slot;
use etp_runtime::wire::to_coordinator::Hello;
use etp_runtime::wire::{
    self, COORDINATOR_NODE, Ports, RunId, SENDER_AGENT, SENDER_COORDINATOR, ServiceId, Stamper,
    to_wire_mat, to_wire_vec,
};
use etp_shared::scenario::Scenario;
use etp_tests::{EtpRun, no_leftovers, unique_run_id};
use std::time::{Duration, Instant};

/// Longer than several of the sensor's idle checks (250 ms): a sensor that
/// served on its idle checks would have answered by then.
const QUIET: Duration = Duration::from_millis(1500);

/// `sub`'s slots until `wait` passes; the first of (episode, step) of s0.
fn slot_within(sub: &wire::Sub<Slot>, episode: u64, step: u32, wait: Duration) -> Option<Slot> {
    let start = Instant::now();
    loop {
        while let Some(s) = sub.receive().expect("receive slot") {
            let s: Slot = *s;
            if s.header.episode == episode && s.header.step == step && s.header.sender == 0 {
                return Some(s);
            }
        }
        if start.elapsed() >= wait {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn a_sensor_serves_a_truth_that_came_before_its_legs_open_at_the_wake_up_after_the_open() {
    let run_id = unique_run_id("late-open");
    let run = RunId::new(&run_id).expect("run id");
    let scenario = Scenario::builtin("winding-2d").expect("built-in");
    let sensors = scenario.sensors.len();
    let leg = scenario
        .legs
        .iter()
        .position(|l| l.sensor == 0)
        .expect("a leg served by s0") as u32;
    let node = wire::create_node(&run, COORDINATOR_NODE).expect("node");
    let ports = Ports {
        node: &node,
        run: &run,
        sensors,
    };
    // The coordinator's side.
    let hello = ports.subscriber::<Hello>(ServiceId::Hello).expect("hello");
    let threshold = ports
        .publisher::<Threshold>(ServiceId::Threshold(0))
        .expect("threshold");
    // The agent's side.
    let handover = ports
        .publisher::<Handover>(ServiceId::Handover(0))
        .expect("handover");
    let truth = ports
        .publisher::<Truth>(ServiceId::Truth(0))
        .expect("truth");
    let slot = ports.subscriber::<Slot>(ServiceId::Slot).expect("slot");
    let wake = ports
        .notifier(ServiceId::SensorWake(0))
        .expect("sensor wake");

    let sensor = EtpRun::spawn_binary(
        &run_id,
        "etp-sensor-node",
        &[
            "--run-id",
            &run_id,
            "--scenario",
            "winding-2d",
            "--sensor",
            "s0",
            "--seed",
            "1",
        ],
    );
    let start = Instant::now();
    let mut ready = false;
    while !ready {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "s0 said no hello"
        );
        while let Some(h) = hello.receive().expect("receive hello") {
            ready |= h.header.sender == 0;
        }
        std::thread::sleep(Duration::from_millis(5));
    }

    let mut coordinator = Stamper::new(&run, SENDER_COORDINATOR);
    let mut agent = Stamper::new(&run, SENDER_AGENT);
    let n = scenario.dim;
    let p = &scenario.plant;
    // The agent read the OPEN first: it hands over and opens the slot.
    handover
        .publish(Handover {
            header: agent.header(0, leg, 0),
            dim: n as u32,
            _pad: 0,
            mean: to_wire_vec(p.x0.as_slice()),
            cov: to_wire_mat(n, |r, c| p.p0[(r, c)]),
        })
        .expect("handover");
    truth
        .publish(Truth {
            header: agent.header(0, leg, 1),
            dim: n as u32,
            _pad: 0,
            x: to_wire_vec(p.x0.as_slice()),
        })
        .expect("truth");
    wake.notify().expect("wake");
    assert!(
        slot_within(&slot, 0, 1, QUIET).is_none(),
        "s0 served a slot of a leg it was not told to open"
    );

    // The OPEN reaches the sensor's queue now, without a wake-up.
    threshold
        .publish(Threshold {
            header: coordinator.header(0, leg, 0),
            kind: Threshold::OPEN,
            sensor: 0,
            delta_index: 0,
            _pad: 0,
            delta: scenario.deltas[0],
        })
        .expect("open");
    assert!(
        slot_within(&slot, 0, 1, QUIET).is_none(),
        "s0 served without a wake-up: the hang's mechanism is gone, and so is this test's point"
    );

    // The wake-up after the OPEN: the slot is served.
    wake.notify().expect("wake");
    let served = slot_within(&slot, 0, 1, Duration::from_secs(60));
    assert!(
        served.is_some(),
        "s0 did not serve the slot after the wake-up that followed its OPEN"
    );

    threshold
        .publish(Threshold {
            header: coordinator.header(0, leg, 0),
            kind: Threshold::STOP,
            sensor: 0,
            delta_index: 0,
            _pad: 0,
            delta: 0.0,
        })
        .expect("stop");
    wake.notify().expect("wake");
    let (code, _, stderr) = sensor.finish_code();
    assert_eq!(code, Some(0), "s0: {stderr}");
    drop((hello, threshold, handover, truth, slot, wake));
    drop(node);
    etp_runtime::cleanup::remove_run(&run);
    no_leftovers(&run_id).expect("no leftovers");
}
