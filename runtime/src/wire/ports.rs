//! Opening a run's services and ports: every process goes through
//! [`Ports`], which takes every service's limits from [`super::limits`](mod@super::limits), so
//! whichever process creates a service first, it has the same QoS. And the
//! one port error of every runtime process ([`PortError`]).

use super::limits::limits;
use super::{RunId, ServiceId, WireError};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{event, publish_subscribe};
use std::fmt::Debug;

/// Event id the iceoryx2 cleanup emits when a notifier's process died.
pub const DEAD_NOTIFIER_EVENT: usize = 200;

/// A publish-subscribe service's factory.
pub type PubSub<T> = publish_subscribe::PortFactory<ipc::Service, T, ()>;
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

/// A publisher on a run's service.
pub type Pub<T> = iceoryx2::port::publisher::Publisher<ipc::Service, T, ()>;
/// A subscriber on a run's service.
pub type Sub<T> = iceoryx2::port::subscriber::Subscriber<ipc::Service, T, ()>;
/// A listener (wake-ups) on a run's event service.
pub type Listener = iceoryx2::port::listener::Listener<ipc::Service>;
/// A notifier on a run's event service.
pub type Notifier = iceoryx2::port::notifier::Notifier<ipc::Service>;

/// The run's ports are opened through these, all with the limits of [`limits`].
pub struct Ports<'a> {
    pub node: &'a Node<ipc::Service>,
    pub run: &'a RunId,
    pub sensors: usize,
}

impl Ports<'_> {
    pub fn publisher<T: Debug + ZeroCopySend>(&self, s: ServiceId) -> Result<Pub<T>, WireError> {
        open_pubsub::<T>(self.node, self.run, s, self.sensors)?
            .publisher_builder()
            .create()
            .map_err(|e| WireError::Port(s.name(self.run), format!("{e:?}")))
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
