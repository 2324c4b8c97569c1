//! `etp-runtime`: the I/O layer of the multi-process runtime, kept out of the
//! maths crate (`etp-shared`) so that synthesis and the pure algorithms never
//! link iceoryx2 or mcap.
//!
//! A short tour:
//!
//! * [`wire::catalogue`] — every message declared once (payload type, topic,
//!   kind, owner); service ids, topics, recorded kinds and schema texts are
//!   derived from it.
//! * [`wire::messages`] — the `#[repr(C)]` + `ZeroCopySend` payloads, by
//!   direction (`agent_to_sensor`, `sensor_to_agent`, …), and their code enums.
//! * [`wire::services`] — per-run iceoryx2 configuration and the one builder
//!   that sets every service's limits; [`wire::Ports`] and [`wire::PortError`].
//! * [`wire::waiter`] — the one wait point of every process loop
//!   ([`wire::waiter::Waiter`]), the liveness [`wire::waiter::Watchdog`] and
//!   the header [`wire::waiter::Stamper`].
//! * [`recording`] — the versioned MCAP recording: a sans-io reader
//!   ([`recording::read_lenient`]), integrity checks (CRCs, scenario hash) and the
//!   bit-for-bit re-simulation behind `replay --verify` ([`recording::verify`]),
//!   which runs the same episode stepper as simulation and the agent.

pub mod recording;
pub mod wire;
