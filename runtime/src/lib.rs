//! `etp-runtime`: the I/O layer of the multi-process runtime, kept out of the
//! maths crate (`etp-shared`) so that synthesis and the pure algorithms never
//! link iceoryx2 or mcap.
//!
//! A short tour:
//!
//! * [`wire::catalogue`] — every message declared once, one row each (type,
//!   topic, owner and reader, limits, link class, recorded, forwarded); the
//!   [`wire::ServiceId`]s, topics, limits, recorded kinds, the bridge's
//!   lists and schema texts are derived from it.
//! * [`wire::messages`] — the `#[repr(C)]` + `ZeroCopySend` payloads, by
//!   direction (`agent_to_sensor`, `sensor_to_agent`, …), and their code enums.
//! * [`wire::run_id`], [`wire::limits`](mod@wire::limits), [`wire::ports`], [`wire::liveness`](mod@wire::liveness),
//!   [`wire::hello`] — a run's id and iceoryx2 configuration, THE limits
//!   table, the one way to open ports ([`wire::Ports`], [`wire::PortError`]),
//!   nodes and their liveness, and saying hello.
//! * [`wire::waiter`] — the one wait point of every process loop
//!   ([`wire::Waiter`], over one wake-up event or several), the liveness
//!   [`wire::Watchdog`] and the header [`wire::Stamper`].
//! * [`progress`] — the progress of long work on stderr: a bar on a
//!   terminal, a plain line every few seconds otherwise, nothing with `--json`.
//! * [`shell`] — the one process shell: argument parsing, logging, exit
//!   codes ([`shell::main_with`]).
//! * [`scenario_arg`] — a `SCENARIO` argument (built-in name or TOML path);
//!   [`strategy_arg`] — a `STRATEGY` argument (sealed file and its scenario).
//! * [`report`] — the coordinator's run report and a run's session info;
//!   [`cleanup`] — removing what a run left in /dev/shm and its folder (in
//!   the user's private folders of `etp_files::folders`).
//! * [`link_keys`] — the key folder of an authenticated link (`--tls DIR`):
//!   file names and the checks made before Zenoh reads it.
//! * [`recording`] — the versioned MCAP recording: a sans-io reader
//!   ([`recording::read_lenient`]), integrity checks (CRCs, scenario hash) and the
//!   bit-for-bit re-simulation behind `replay verify` ([`recording::verify`]),
//!   which runs the same episode stepper as simulation and the agent.

pub mod cleanup;
pub mod link_keys;
pub mod live;
pub mod progress;
pub mod recording;
pub mod report;
pub mod scenario_arg;
pub mod shell;
pub mod strategy_arg;
pub mod wire;

pub use scenario_arg::load_scenario;
