//! `etp-bridge`: the services of remote sensors, carried between hosts over
//! Zenoh (docs/remote.md).
//!
//! A short tour:
//!
//! * [`session`] — the Zenoh configuration (peer mode, scouting off, only
//!   the given endpoints, a short link lease), the key expressions
//!   `etp/<run-id>/{down,up}/<topic>` and liveliness tokens
//!   `etp/<run-id>/alive/…`, and [`session::SessionInfo`], the run a sensor
//!   host fetches when it joins.
//! * [`forward`] — the two directions: iceoryx2 → Zenoh on the readers'
//!   wake-up events, Zenoh → iceoryx2 with the reader's wake-up; the bytes
//!   on the wire are the recording's encoding; per-sensor traffic counted as
//!   radio or plumbing.
//! * [`admit`] — what may come in from the link: a sample decodes, carries
//!   this run's tag, comes from its kind's owner about a sensor this link
//!   carries and, towards the agent, is its sensor's next message (each
//!   sensor's messages reach the agent in the order it sent them). Anything
//!   else is refused, counted and dropped.
//! * [`agent_host`] — `etp-bridge agent-host` (started by `etp run --listen`):
//!   waits for the remote sensors, then forwards; a remote sensor's
//!   liveliness is mirrored by a proxy iceoryx2 node, so its death is a dead
//!   link to the agent like a local sensor's.
//! * [`sensor_host`] — `etp-bridge sensor-host` (started by
//!   `etp sensor-host`): joins, then forwards; the agent host's liveliness is
//!   mirrored by proxies of the coordinator and agent nodes.
//!
//! The bridge prints one JSON object per line on stdout for its parent
//! (`ready`, `joined`, `lost`, `agent-host-gone`, and `refused`, `stalled`
//! and `traffic` at the end).

pub mod admit;
pub mod agent_host;
pub mod answers;
pub mod forward;
pub mod sensor_host;
pub mod session;
pub mod tls_check;

use std::io::Write;

/// Why the bridge stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    #[error("{0}")]
    Input(String),
    #[error("zenoh: {0}")]
    Zenoh(String),
    #[error("iceoryx2: {0}")]
    Wire(String),
    #[error(transparent)]
    WireSetup(#[from] etp_runtime::wire::WireError),
    #[error(transparent)]
    Recording(#[from] etp_runtime::recording::RecordingError),
    #[error("protocol error: {0}")]
    Protocol(String),
    #[error("{0}")]
    Join(String),
}

/// One line of JSON to the parent. A closed stdout (the parent died) is not
/// an error of the bridge.
pub fn emit(v: &serde_json::Value) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{v}").and_then(|()| out.flush());
}

/// The `refused` line: what this end refused from the link, by reason; per
/// sensor the messages still held for an earlier one that never came; and
/// how many messages overtook an earlier one and were put back in order.
pub fn emit_refused(admission: &admit::Admission, names: &[String]) {
    let name = |i: usize| names.get(i).cloned().unwrap_or_else(|| format!("#{i}"));
    let counts: serde_json::Map<String, serde_json::Value> = admission
        .refused()
        .iter()
        .map(|(r, n)| (r.name().to_string(), serde_json::json!(n)))
        .collect();
    let held: serde_json::Map<String, serde_json::Value> = admission
        .held()
        .into_iter()
        .map(|(i, n)| (name(i), serde_json::json!(n)))
        .collect();
    emit(
        &serde_json::json!({"event": "refused", "counts": counts, "held": held,
        "reordered": admission.reordered(), "dropped_after_cut": admission.after_cut()}),
    );
}

/// The `handshakes` line: connections the TLS accept loop refused before
/// they became links, by reason (`tls_check::Cause`), and the first named.
/// Not a fault of the run's counts (nothing of the run came through them).
pub fn emit_handshakes() {
    let r = tls_check::refusals();
    emit(&serde_json::json!({"event": "handshakes", "refused": r.counts, "named": r.named}));
}

/// The last lines: `stalled` (per sensor name, the puts a peer that stopped
/// reading held up) and `traffic` (per sensor name, what this end carried).
pub fn emit_traffic(counters: &forward::Counters, stalls: &forward::Stalls, names: &[String]) {
    fn by_name<T: serde::Serialize>(
        m: &std::sync::Mutex<std::collections::BTreeMap<usize, T>>,
        names: &[String],
    ) -> serde_json::Map<String, serde_json::Value> {
        m.lock()
            .map(|c| {
                c.iter()
                    .map(|(i, t)| {
                        (
                            names.get(*i).cloned().unwrap_or_else(|| format!("#{i}")),
                            serde_json::to_value(t).unwrap_or_default(),
                        )
                    })
                    .collect()
            })
            .unwrap_or_default()
    }
    emit(&serde_json::json!({"event": "stalled", "sensors": by_name(stalls, names)}));
    emit(&serde_json::json!({"event": "traffic", "sensors": by_name(counters, names)}));
}

/// The command line of `etp-bridge`.
#[derive(Debug, clap::Parser)]
#[command(
    name = "etp-bridge",
    version,
    about = "Carry remote sensors' services over Zenoh"
)]
pub enum Cli {
    /// The agent host's end (started by `etp run --listen`).
    AgentHost(agent_host::Args),
    /// A sensor host's end (started by `etp sensor-host`).
    SensorHost(sensor_host::Args),
}

/// The bridge process, as the process shell runs it.
pub struct BridgeProcess;

impl etp_runtime::shell::Process for BridgeProcess {
    const NAME: &'static str = "etp-bridge";
    type Args = Cli;
    fn parse(argv: Vec<std::ffi::OsString>) -> Self::Args {
        clap::Parser::parse_from(argv)
    }
    type Error = anyhow::Error;
    fn body(cli: &Cli) -> anyhow::Result<etp_runtime::shell::Done> {
        match cli {
            Cli::AgentHost(a) => agent_host::run(a),
            Cli::SensorHost(a) => sensor_host::run(a),
        }?;
        Ok(etp_runtime::shell::Done::Quiet)
    }
}
