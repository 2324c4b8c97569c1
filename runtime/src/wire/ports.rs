//! Opening a run's services and ports: every process goes through
//! [`Ports`], which takes every service's limits from [`super::limits`](mod@super::limits), so
//! whichever process creates a service first, it has the same QoS; every
//! publish-subscribe service carries the sender's time as its user header
//! ([`PublishTime`]), written by the one publish path ([`Pub::publish`]).
//! And the one port error of every runtime process ([`PortError`]).

use super::limits::limits;
use super::stamp::{PublishTime, now_ns};
use super::{RunId, ServiceId, WireError};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{event, publish_subscribe};
use std::fmt::Debug;

/// Event id the iceoryx2 cleanup emits when a notifier's process died.
pub const DEAD_NOTIFIER_EVENT: usize = 200;

/// A publish-subscribe service's factory.
pub type PubSub<T> = publish_subscribe::PortFactory<ipc::Service, T, PublishTime>;
/// An event service's factory.
pub type Event = event::PortFactory<ipc::Service>;

/// Open (or create) a publish-subscribe service with the limits of [`limits`].
pub fn open_pubsub<T: Debug + ZeroCopySend>(
    node: &Node<ipc::Service>,
    run: &RunId,
    service: ServiceId,
    sensors: usize,
) -> Result<PubSub<T>, WireError> {
    let l = limits(service, sensors);
    let name = service.name(run);
    let sname =
        ServiceName::new(&name).map_err(|e| WireError::Service(name.clone(), format!("{e:?}")))?;
    node.service_builder(&sname)
        .publish_subscribe::<T>()
        .user_header::<PublishTime>()
        .max_publishers(l.max_publishers)
        .max_subscribers(l.max_subscribers)
        .max_nodes(l.max_nodes)
        .subscriber_max_buffer_size(l.buffer.max(l.observer_buffer))
        .history_size(l.history)
        .enable_safe_overflow(l.safe_overflow)
        .open_or_create()
        .map_err(|e| WireError::Service(name, format!("{e:?}")))
}

/// Open (or create) an event service with the limits of [`limits`].
pub fn open_event(
    node: &Node<ipc::Service>,
    run: &RunId,
    service: ServiceId,
    sensors: usize,
) -> Result<Event, WireError> {
    let l = limits(service, sensors);
    let name = service.name(run);
    let sname =
        ServiceName::new(&name).map_err(|e| WireError::Service(name.clone(), format!("{e:?}")))?;
    node.service_builder(&sname)
        .event()
        .max_notifiers(l.max_publishers)
        .max_listeners(l.max_subscribers)
        .max_nodes(l.max_nodes)
        .notifier_dead_event(EventId::new(DEAD_NOTIFIER_EVENT))
        .open_or_create()
        .map_err(|e| WireError::Service(name, format!("{e:?}")))
}

/// A publisher on a run's service. It sends only through [`Pub::publish`]
/// (or [`Pub::publish_at`]), so every sample carries its sender's time.
pub struct Pub<T: Debug + ZeroCopySend + 'static>(
    iceoryx2::port::publisher::Publisher<ipc::Service, T, PublishTime>,
);

impl<T: Debug + ZeroCopySend + 'static> Pub<T> {
    /// Send `v` stamped with the time now (THE publish path of every
    /// process); the number of subscribers it reached.
    pub fn publish(&self, v: T) -> Result<usize, iceoryx2::port::SendError> {
        self.publish_at(v, now_ns())
    }

    /// Send `v` stamped with `time`: a sample another host's sender
    /// published at `time` (the Zenoh bridge delivering it here).
    pub fn publish_at(&self, v: T, time: PublishTime) -> Result<usize, iceoryx2::port::SendError> {
        let mut sample = self.0.loan_uninit()?;
        *sample.user_header_mut() = time;
        sample.write_payload(v).send()
    }

    /// Connect to the subscribers that appeared since the last send (see
    /// `super::hello`).
    pub fn update_connections(
        &self,
    ) -> Result<(), iceoryx2::port::update_connections::ConnectionFailure> {
        use iceoryx2::port::update_connections::UpdateConnections;
        self.0.update_connections()
    }
}

/// A subscriber on a run's service (a sample's user header is its
/// sender's [`PublishTime`]).
pub type Sub<T> = iceoryx2::port::subscriber::Subscriber<ipc::Service, T, PublishTime>;
/// A listener (wake-ups) on a run's event service.
pub type Listener = iceoryx2::port::listener::Listener<ipc::Service>;
/// A notifier on a run's event service.
pub type Notifier = iceoryx2::port::notifier::Notifier<ipc::Service>;

/// A publisher of the service `factory` opened (service `s` of `run`).
pub fn publisher_of<T: Debug + ZeroCopySend + 'static>(
    factory: &PubSub<T>,
    run: &RunId,
    s: ServiceId,
) -> Result<Pub<T>, WireError> {
    factory
        .publisher_builder()
        .create()
        .map(Pub)
        .map_err(|e| WireError::Port(s.name(run), format!("{e:?}")))
}

/// The run's ports are opened through these, all with the limits of [`limits`].
pub struct Ports<'a> {
    pub node: &'a Node<ipc::Service>,
    pub run: &'a RunId,
    pub sensors: usize,
}

impl Ports<'_> {
    pub fn publisher<T: Debug + ZeroCopySend + 'static>(
        &self,
        s: ServiceId,
    ) -> Result<Pub<T>, WireError> {
        publisher_of(
            &open_pubsub::<T>(self.node, self.run, s, self.sensors)?,
            self.run,
            s,
        )
    }

    pub fn subscriber<T: Debug + ZeroCopySend>(&self, s: ServiceId) -> Result<Sub<T>, WireError> {
        self.subscriber_with_buffer(s, limits(s, self.sensors).buffer)
    }

    /// A subscriber with the observer's (recorder's) buffer.
    pub fn observer<T: Debug + ZeroCopySend>(&self, s: ServiceId) -> Result<Sub<T>, WireError> {
        self.subscriber_with_buffer(s, limits(s, self.sensors).observer_buffer)
    }

    fn subscriber_with_buffer<T: Debug + ZeroCopySend>(
        &self,
        s: ServiceId,
        buffer: usize,
    ) -> Result<Sub<T>, WireError> {
        open_pubsub::<T>(self.node, self.run, s, self.sensors)?
            .subscriber_builder()
            .buffer_size(buffer)
            .create()
            .map_err(|e| WireError::Port(s.name(self.run), format!("{e:?}")))
    }

    pub fn listener(&self, s: ServiceId) -> Result<Listener, WireError> {
        open_event(self.node, self.run, s, self.sensors)?
            .listener_builder()
            .create()
            .map_err(|e| WireError::Port(s.name(self.run), format!("{e:?}")))
    }

    pub fn notifier(&self, s: ServiceId) -> Result<Notifier, WireError> {
        open_event(self.node, self.run, s, self.sensors)?
            .notifier_builder()
            .create()
            .map_err(|e| WireError::Port(s.name(self.run), format!("{e:?}")))
    }
}

/// A send, notification or receive on a run's port failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PortError {
    #[error("sending on `{service}` failed: {detail}")]
    Send {
        service: &'static str,
        detail: String,
    },
    #[error("notifying `{service}` failed: {detail}")]
    Notify {
        service: &'static str,
        detail: String,
    },
    #[error("receiving on `{service}` failed: {detail}")]
    Receive {
        service: &'static str,
        detail: String,
    },
}

impl PortError {
    pub fn send(service: &'static str, e: impl Debug) -> Self {
        Self::Send {
            service,
            detail: format!("{e:?}"),
        }
    }

    pub fn notify(service: &'static str, e: impl Debug) -> Self {
        Self::Notify {
            service,
            detail: format!("{e:?}"),
        }
    }

    pub fn receive(service: &'static str, e: impl Debug) -> Self {
        Self::Receive {
            service,
            detail: format!("{e:?}"),
        }
    }
}

#[cfg(test)]
mod publish_tests {
    use super::*;
    use crate::wire::messages::sensor_to_agent::Slot;

    #[test]
    fn every_sample_carries_its_senders_time() {
        let run = RunId::new(&format!("unit-stamp-{}", std::process::id())).expect("id");
        let node = crate::wire::create_node(&run, "unit-stamp").expect("node");
        let ports = Ports {
            node: &node,
            run: &run,
            sensors: 1,
        };
        let sub = ports
            .subscriber::<Slot>(ServiceId::Slot)
            .expect("subscriber");
        let publisher = ports.publisher::<Slot>(ServiceId::Slot).expect("publisher");
        let before = now_ns();
        publisher.publish(Slot::default()).expect("publish");
        let after = now_ns();
        // Another host's time, a forged one too: carried as it is.
        publisher
            .publish_at(Slot::default(), u64::MAX)
            .expect("publish_at");
        let mut times = Vec::new();
        while let Some(s) = sub.receive().expect("receive") {
            times.push(*s.user_header());
        }
        assert_eq!(times.len(), 2, "{times:?}");
        assert!((before..=after).contains(&times[0]), "{times:?}");
        assert_eq!(times[1], u64::MAX);
    }
}

#[cfg(test)]
mod port_error_tests {
    use super::*;

    #[test]
    fn the_message_names_the_operation_and_the_service() {
        let e = PortError::send("ledger", "ExceedsMaxLoans");
        assert_eq!(
            e.to_string(),
            "sending on `ledger` failed: \"ExceedsMaxLoans\""
        );
        assert!(
            PortError::receive("slot", 3)
                .to_string()
                .starts_with("receiving on `slot`")
        );
        assert!(
            PortError::notify("agent wake", 3)
                .to_string()
                .starts_with("notifying `agent wake`")
        );
    }
}
