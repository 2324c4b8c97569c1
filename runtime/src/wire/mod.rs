//! The runtime's wire vocabulary (DESIGN.md "Runtime: processes and services").
//!
//! * [`messages`] — the fixed-size `#[repr(C)]` + `ZeroCopySend` payloads, one
//!   module per direction (`coordinator_to_agent`, `coordinator_to_all`,
//!   `agent_to_sensor`, `sensor_to_agent`, `agent_to_coordinator`,
//!   `sensor_to_coordinator`, `to_coordinator`), each starting with a [`Header`].
//! * [`services`] — [`RunId`], the per-run iceoryx2 [`config`] (own shm prefix
//!   and root folder), [`ServiceId`] with its `etp/<run-id>/…` name, THE
//!   [`limits`] table used by [`open_pubsub`] / [`open_event`] in every
//!   process, and node [`liveness`].
//! * [`cleanup`] — removing what a run (or dead runs) left in /dev/shm and
//!   under [`root_base`] (only folders this user owns, never through a symlink).
//! * [`private`] — the per-user, mode-0700 folder every run path lives under.
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
pub mod cleanup;
pub mod messages;
pub mod port;
pub mod private;
pub mod report;
pub mod services;
pub mod traffic;
pub mod waiter;

pub use catalogue::{Kind, KindVisitor, Message, Recorded};
pub use messages::*;
pub use port::PortError;
pub use services::*;
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
    #[error("private run folder: {0}")]
    Private(String),
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

/// Resolve a runtime process's `--scenario` argument: a built-in name or a
/// TOML path (the supervisor passes the same argument to every process).
pub fn load_scenario(arg: &str) -> Result<etp_shared::scenario::Scenario, String> {
    if let Some(text) = etp_shared::scenario::builtin_text(arg) {
        return etp_shared::scenario::Scenario::from_toml(text).map_err(|e| e.to_string());
    }
    let text =
        std::fs::read_to_string(arg).map_err(|e| format!("reading scenario `{arg}`: {e}"))?;
    etp_shared::scenario::Scenario::from_toml(&text).map_err(|e| format!("scenario `{arg}`: {e}"))
}

/// iceoryx2 reports errors only: its warnings (no config file, the global
/// config used while cleaning a dead node whose details are gone) are noise
/// here, where every configuration is built in code.
pub fn quiet_iceoryx2() {
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
}

/// Logging setup for the runtime processes: a `tracing` subscriber on
/// stderr filtered by `RUST_LOG` (default `warn`); the caller enters a span
/// named after the process so every line says who wrote it. iceoryx2 only reports errors (its "no config file"
/// warning is noise: the config is built in code).
pub fn init_process_logging(process: &str) {
    quiet_iceoryx2();
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        // Zenoh's own warnings (e.g. that gossip, which we turn off, cannot
        // de-duplicate across region gateways) are noise by default.
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,zenoh=error"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .try_init();
    tracing::debug!(process, pid = std::process::id(), "logging ready");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_ids_are_checked_and_prefixes_do_not_nest() {
        assert!(RunId::new("t-1").is_ok());
        assert!(RunId::new("").is_err());
        assert!(RunId::new("A").is_err());
        assert!(RunId::new("a_b").is_err());
        let a = RunId::new("a").expect("valid");
        let ab = RunId::new("a-b").expect("valid");
        assert!(!ab.shm_prefix().starts_with(&a.shm_prefix()));
        assert_ne!(a.tag(), ab.tag());
        assert_eq!(ServiceId::Truth(3).name(&a), "etp/a/sensor/3/truth");
        assert!(RunId::new(RunId::generate().as_str()).is_ok());
    }

    #[test]
    fn limits_admit_32_sensors_and_a_recorder() {
        for s in ServiceId::all_pubsub(32) {
            let l = limits(s, 32);
            assert!(l.max_nodes > 32 + 2);
            assert!(l.max_subscribers >= 2);
        }
        assert!(limits(ServiceId::Measurement, 32).max_publishers >= 33);
        assert!(limits(ServiceId::Threshold(31), 32).max_subscribers > 2);
        // Nothing that carries data or accounting may overwrite an unread sample.
        for s in ServiceId::all_pubsub(32) {
            assert!(!limits(s, 32).safe_overflow, "{s:?}");
        }
        assert!(limits(ServiceId::AgentWake, 32).max_publishers >= 34);
    }

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
