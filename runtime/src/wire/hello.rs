//! Saying hello: how a process announces itself to the coordinator once
//! its ports exist (the processes of a run start in parallel).

use super::messages::to_coordinator::Hello;
use super::{
    Liveness, Notifier, Ports, Pub, RECORDER_NODE, ServiceId, Stamper, WireError, config, liveness,
    open_pubsub,
};
use iceoryx2::prelude::*;

/// How many subscribers a `hello` must reach: the coordinator's, and a
/// recorder's when one runs (it is started before everyone and records the
/// hellos too).
pub fn hello_readers(cfg: &iceoryx2::config::Config) -> usize {
    1 + usize::from(liveness(cfg, RECORDER_NODE) == Liveness::Alive)
}

/// How long a process waits for the coordinator to subscribe to `hello`.
pub const HELLO_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(30);

/// Announce a process to the coordinator: wait (bounded, sleeping) until the
/// coordinator's `hello` subscriber exists, then send `hello` and wake it.
/// Samples sent before a subscriber exists would be lost, and the processes
/// start in parallel. Returns the publisher (keep it alive).
///
/// `coordinator_wake` is the caller's own notifier on `coordinator/wake`: a
/// second, temporary one per process would exceed the service's notifier
/// limit when several processes say hello at once (seen under load:
/// `ExceedsMaxSupportedNotifiers` on a fresh run).
pub fn say_hello(
    ports: &Ports<'_>,
    coordinator_wake: &Notifier,
    stamp: &mut Stamper,
) -> Result<Pub<Hello>, WireError> {
    let hello = Hello {
        header: stamp.header(0, 0, 0),
        pid: std::process::id(),
        _pad: 0,
    };
    let timeout = HELLO_TIMEOUT;
    let factory = open_pubsub::<Hello>(ports.node, ports.run, ServiceId::Hello, ports.sensors)?;
    let publisher = super::ports::publisher_of(&factory, ports.run, ServiceId::Hello)?;
    let needed = hello_readers(&config(ports.run)?);
    let start = std::time::Instant::now();
    while factory.dynamic_config().number_of_subscribers() < needed {
        if start.elapsed() >= timeout {
            return Err(WireError::Port(
                ServiceId::Hello.name(ports.run),
                format!("no coordinator subscribed within {timeout:?}"),
            ));
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    publisher
        .publish(hello)
        .map_err(|e| WireError::Port(ServiceId::Hello.name(ports.run), format!("{e:?}")))?;
    // A subscriber can be counted above before the publisher's connection to
    // it exists; the hello then waits in the history (size 1) until the next
    // connection update, which a process that sends nothing more never does
    // (seen under load: a coordinator missing three sensors' hellos). Update
    // the connections for a moment: a new connection gets the history, an
    // existing one gets nothing twice.
    for _ in 0..30 {
        let _ = publisher.update_connections();
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    coordinator_wake.notify().map_err(|e| {
        WireError::Port(ServiceId::CoordinatorWake.name(ports.run), format!("{e:?}"))
    })?;
    Ok(publisher)
}
