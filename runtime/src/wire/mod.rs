//! The runtime's wire vocabulary (its processes and services: below).
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
//!   ([`ports`]: [`Ports`], [`PortError`]) in every process; [`stamp`] — the
//!   sender's time every sample carries (its user header), written by the
//!   one publish path [`Pub::publish`], and how the bridge's link carries it.
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
//!
//! # Processes and services
//!
//! `etp run` (etp/src/cmd/run.rs over the `etp-launcher` crate) finds `etp-coordinator`, `etp-agent`,
//! `etp-sensor-node` (and `etp-recorder`) next to its own executable — or, when
//! they are not installed there (`cargo run -p etp` builds only `etp`), starts
//! itself as the hidden `etp process <name>`, which calls the same library entry
//! point (`etp_runtime::shell::main_with::<P>`, with `P` the process's
//! `shell::Process` — its name, arguments and body; argument parsing,
//! logging, exit code and the stdout line for the parent are written once
//! for agent, coordinator, sensor node, recorder and bridge) as the
//! standalone binary, in a process of its own. It
//! spawns one sensor process per sensor, supervises them with tokio (exit codes, ctrl-c, a deadline; SIGTERM to
//! the others when the coordinator ends abnormally) and removes the run's
//! iceoryx2 files at the end. Every run has a `RunId`; its iceoryx2 configuration
//! (`wire::run_id::config`) uses its own shm prefix and root folder, and every
//! service name lives under `etp/<run-id>/…`, so runs and tests never see each other.
//! Stale runs of dead processes are removed at the start.
//!
//! The payloads (`runtime/src/wire/messages.rs`) are `#[repr(C)]` + `ZeroCopySend`,
//! fixed size for n, m ≤ 6, one module per direction, each with a header. Each
//! has one row in the catalogue (`runtime/src/wire/catalogue.rs`), and every
//! service is derived from the rows. The limits of every service come from one
//! function (`wire::limits`, by the row's limits class), used by every process.
//! `threshold`, `truth`, `handover` and `ack` have one service per sensor
//! (`sensor/<i>/…`: only the serving sensor is woken, and an idle sensor's
//! buffer only ever holds the few messages of legs it serves); `control`,
//! `measurement`, `slot`, `waypoint`, `outcome`, `ledger` and `hello` are shared.
//!
//! **Adding a message** is one struct in `wire/messages.rs` (`#[repr(C)]`,
//! `ZeroCopySend`, serde, a `Header` first) and one row in the `catalogue!`
//! invocation, with every column: `Kind(sensor) => type { topic, owner,
//! reader, limits, link, recorded, forward, names, codes }` (`(sensor)` and
//! `{sensor}` in the topic for a per-sensor message). From the row alone come
//! its `Kind` and `ServiceId` variant, topic and `from_topic`, the reader's
//! wake-up event, limits, link class (`traffic::link_class`), the recorder's
//! subscription and channel with its schema text, `replay publish`, and the
//! bridges' forwarding for remote sensors (`ServiceId::forwarded`, in causal
//! rank). A row lacking a column does not compile; `const` checks refuse a
//! sensor reading a shared service and a forwarded message off the sensor
//! link; the test `every_row_has_every_column_and_they_agree` checks the rest,
//! and `a_test_only_row_derives_everything` adds a `#[cfg(test)]` row
//! (`Probe`) and checks all of the above for it. The lossy radio's
//! acknowledgement (docs/MODEL.md §8) was added that way: the struct
//! `agent_to_sensor::Ack` and the row `Ack(sensor) => a2s::Ack { topic:
//! "sensor/{sensor}/ack", owner: Agent, reader: Sensor, limits: OneToOne(16),
//! link: Radio, recorded: true, forward: Down(2), … }` gave it a per-sensor
//! service, the sensor's wake-up, the recording, the traffic table's radio
//! downlink and the bridge's downlink (ranked after the handover and before
//! the truth, which moved to rank 3); its counts are fields of existing
//! payloads (`slot.attempts`, the ledger's `triggers`, `delivered`, `lost`). What processes do with a message
//! (publishing it, reading it) is of course code in those processes.
//!
//! Each process waits in exactly one place, `wire::Waiter::wait` on its own
//! wake-up event (`agent/wake`, `coordinator/wake`, `sensor/<i>/wake`) — the
//! recorder and a bridge's outbound direction on several at once, one
//! `Waiter::over` them —, and gets
//! one of a closed set of `Wake`s (notified, silence, terminate); interrupted
//! waits are resumed inside it. What a silence means is decided by one
//! `wire::Watchdog` (supervisor gone? peer dead in the node list?). Every
//! message carries a header from one `wire::Stamper`, and the time it was
//! published from `Pub::publish`. The sensor's decisions are
//! a pure `SensorCore` (unit-tested) behind a thin adapter, and so are the
//! agent's (`EpisodeCore`, over the one step `episode::AgentCore`) and the
//! coordinator's (`CoordinatorCore`).

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
pub mod stamp;
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
