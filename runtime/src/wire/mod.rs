//! The runtime's wire vocabulary (ARCHITECTURE.md "Runtime processes and services").
//!
//! * [`messages`] — the fixed-size `#[repr(C)]` + `ZeroCopySend` payloads, one
//!   module per direction (`coordinator_to_agent`, `coordinator_to_sensor`,
//!   `agent_to_sensor`, `sensor_to_agent`, `agent_to_coordinator`,
//!   `sensor_to_coordinator`, `to_coordinator`), each starting with a [`Header`].
//! * [`catalogue`] — THE list of messages, one row each (type, topic,
//!   owner and reader, limits class, link class, recorded, forwarded), and
//!   [`ServiceId`], generated from it; [`services`] derives each service's
//!   topic, reader wake-up, the recorder's and the bridge's lists;
//!   [`schema`] the schema text of a recording's channel.
//! * [`run_id`] — [`RunId`] and the per-run iceoryx2 [`config`] (own shm
//!   prefix and root folder).
//! * [`limits`](mod@limits) — THE limits table used by [`open_pubsub`] / [`open_event`]
//!   ([`ports`]: [`Ports`], [`PortError`]) in every process.
//! * [`liveness`](mod@liveness) — node names, [`create_node`] and what the node list says
//!   about a node; [`hello`] — how a process announces itself.
//! * [`waiter`] — the one wait point of a process ([`Waiter`]), the
//!   [`Watchdog`] and the header [`Stamper`]; [`traffic`] — the sensor
//!   link's radio and plumbing counts.
//!
//! One step of an episode (one blocking round trip): the agent publishes
//! `truth` to the serving sensor and wakes it; the sensor computes the prior
//! with its replica of the agent's estimator (handed over once per leg on
//! `handover`), measures,
//! whitens, triggers, publishes `measurement` if it triggers, then `slot`, and
//! wakes the agent. One decision point (one more round trip per leg): the
//! agent publishes `waypoint`; the coordinator answers on `threshold` (open
//! the leg at the serving sensor, close the previous one, whose sensor answers
//! on `ledger`). The episode ends with `outcome`.

pub mod catalogue;
pub mod hello;
pub mod limits;
pub mod liveness;
pub mod messages;
pub mod ports;
pub mod proto;
pub mod run_id;
pub mod schema;
pub mod services;
pub mod traffic;
pub mod waiter;

pub use catalogue::{Kind, KindVisitor, Message, Recorded, ServiceId};
pub use hello::{HELLO_TIMEOUT, hello_readers, say_hello};
pub use limits::{Limits, limits};
pub use liveness::{
    AGENT_NODE, COORDINATOR_NODE, Liveness, RECORDER_NODE, alive_nodes, create_node, liveness,
    peek_liveness, remove_dead_nodes, sensor_node_name,
};
pub use messages::*;
pub use ports::{
    DEAD_NOTIFIER_EVENT, Event, Listener, Notifier, PortError, Ports, Pub, PubSub, Sub, open_event,
    open_pubsub,
};
pub use run_id::{IPC_DOMAIN_ENV, ROOT_FOLDER, RunId, config};
pub use waiter::{Stamper, Waiter, Wake, Watchdog, note_termination, termination_requested};

use etp_shared::etkf::{Belief, Matrix, Vector};

/// Why a runtime service could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum WireError {
    #[error("invalid run id `{0}`: use 1–40 characters of a–z, 0–9 and -")]
    RunId(String),
    #[error("iceoryx2 configuration: {0}")]
    Config(String),
    #[error("iceoryx2 node: {0}")]
    Node(String),
    #[error("iceoryx2 service `{0}`: {1}")]
    Service(String, String),
    #[error("iceoryx2 port on `{0}`: {1}")]
    Port(String, String),
    #[error("waiting for a wake-up: {0}")]
    Wait(String),
}

/// A belief as wire arrays (mean, covariance).
pub fn belief_to_wire<const N: usize>(b: &Belief<N>) -> (WireVec, WireMat) {
    (
        to_wire_vec(b.mean.as_slice()),
        to_wire_mat(N, |r, c| b.cov[(r, c)]),
    )
}

/// A belief from wire arrays.
pub fn belief_from_wire<const N: usize>(mean: &WireVec, cov: &WireMat) -> Belief<N> {
    Belief {
        mean: Vector::<N>::from_fn(|i, _| mean[i]),
        cov: Matrix::<N, N>::from_fn(|r, c| cov[r][c]),
    }
}

/// A fixed-size vector from a wire vector.
pub fn vec_from_wire<const D: usize>(v: &WireVec) -> Vector<D> {
    Vector::<D>::from_fn(|i, _| v[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beliefs_round_trip() {
        let b = Belief::<3> {
            mean: Vector::<3>::new(1.0, 2.0, 3.0),
            cov: Matrix::<3, 3>::from_fn(|r, c| (r * 3 + c) as f64),
        };
        let (m, p) = belief_to_wire(&b);
        assert_eq!(belief_from_wire::<3>(&m, &p), b);
        assert_eq!(m[3..], [0.0; 3]);
    }
}
