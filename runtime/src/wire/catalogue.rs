//! THE message catalogue: one row per payload of the runtime, and
//! everything about a message derived from its row.
//!
//! A row holds every column of a message: its kind and Rust type, its topic
//! pattern (`{sensor}` in it makes the service per-sensor: one service per
//! sensor, so idle sensors are never woken), the process that publishes it
//! (`owner`) and the one that reads it (`reader`, whose wake-up event a
//! publication notifies), its limits class, its link class (radio, plumbing
//! or local), whether it is recorded, whether and in which causal rank it is
//! forwarded for a remote sensor (down: agent host → sensor host; up: the
//! reverse), and the codes and named fields of its schema.
//!
//! Derived from the rows: the [`Kind`] enum, the decoded [`Recorded`] union,
//! typed dispatch over kinds ([`KindVisitor`]), the [`ServiceId`] enum (one
//! variant per row, `(usize)` for a per-sensor one, plus the three wake-up
//! events) with its topic, reader wake-up, kind, limits, link class and
//! forwarding (`super::services`, `super::limits`, `super::traffic`), the
//! recorder's subscriptions ([`ServiceId::recorded`]), the bridge's
//! forwarding lists ([`ServiceId::forwarded`]) and the schema text of a
//! recording (`super::schema`).
//!
//! **Adding a message is one struct in [`super::messages`] and one row
//! below.** A row lacking a column does not compile (the macro requires
//! every column, in order); a per-sensor reader of a shared message, or a
//! forwarded message that is not on the sensor link, fails a `const` check.

use super::messages::{
    Header, agent_to_coordinator as a2c, agent_to_sensor as a2s, coordinator_to_agent as c2a,
    coordinator_to_sensor as c2s, sensor_to_agent as s2a, sensor_to_coordinator as s2c,
    to_coordinator as tc,
};
use iceoryx2::prelude::ZeroCopySend;
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::fmt::Debug;

/// A payload of the runtime.
pub trait Message:
    Debug + Copy + Default + ZeroCopySend + Serialize + DeserializeOwned + 'static
{
    const KIND: Kind;
    /// This payload as the decoded union.
    fn into_recorded(self) -> Recorded;
    /// The payload, if `r` is of this kind.
    fn from_recorded(r: Recorded) -> Option<Self>;
    /// Its header.
    fn header(&self) -> &Header;
}

/// Something done with the type of a kind (e.g. open a typed port).
pub trait KindVisitor {
    type Out;
    fn visit<T: Message>(self) -> Self::Out;
}

/// A process of a run (a message's owner or reader).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Process {
    Coordinator,
    Agent,
    Sensor,
    /// Every process (only as an owner: `hello`).
    Any,
}

impl Process {
    /// `coordinator`, `agent`, `sensor`, `any` (the schema text's "published by").
    pub const fn name(self) -> &'static str {
        match self {
            Self::Coordinator => "coordinator",
            Self::Agent => "agent",
            Self::Sensor => "sensor",
            Self::Any => "any",
        }
    }
}

/// How many ports, nodes and buffered samples a message's service allows
/// (`super::limits` turns a class into numbers for a run's sensor count).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitsClass {
    /// One publisher, one reader (plus observers); the reader's buffer.
    OneToOne(usize),
    /// One publisher, read by its sensor and by the agent; the buffer.
    OneToTwo(usize),
    /// Published by every sensor, one reader; the buffer.
    FromSensors(usize),
    /// Published once by every process; late readers get the history.
    Announce,
}

/// What a message is on the sensor link (a deployment's view).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// Transmitted by a real sensor network.
    Radio,
    /// Stands in for the physical world or drives the simulation.
    Plumbing,
}

/// Direction relative to the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Agent host → sensor.
    Down,
    /// Sensor → agent host.
    Up,
}

/// The link class column: radio, plumbing, or never on a sensor link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Link {
    Radio,
    Plumbing,
    /// Between the agent and the coordinator: never crosses hosts.
    Local,
}

impl Link {
    pub const fn class(self) -> Option<Class> {
        match self {
            Self::Radio => Some(Class::Radio),
            Self::Plumbing => Some(Class::Plumbing),
            Self::Local => None,
        }
    }
}

/// The forwarding column: which way a bridge carries the message for a
/// remote sensor, and its causal rank in that direction (a bridge drains
/// lower ranks first: a message is put after those it may depend on).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Forward {
    Down(u8),
    Up(u8),
    /// Not forwarded.
    Local,
}

impl Forward {
    /// The direction and the rank.
    pub const fn direction(self) -> Option<(Direction, u8)> {
        match self {
            Self::Down(r) => Some((Direction::Down, r)),
            Self::Up(r) => Some((Direction::Up, r)),
            Self::Local => None,
        }
    }
}

/// One row of the catalogue: every column of one message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Row {
    pub kind: Kind,
    /// The topic within the run (`etp/<run-id>/<topic>`, also the
    /// recording's channel topic); `{sensor}` stands for the sensor's index.
    pub topic: &'static str,
    /// One service per sensor (`ServiceId::Kind(i)`), or one for the run.
    pub per_sensor: bool,
    /// The process that publishes it.
    pub owner: Process,
    /// The process that reads it: its wake-up event is notified after a
    /// publication (a sensor's own, for a per-sensor message).
    pub reader: Process,
    pub limits: LimitsClass,
    pub link: Link,
    /// The recorder subscribes to it.
    pub recorded: bool,
    pub forward: Forward,
    /// Fields whose numbers stand for names (`replay export`, `cat`).
    pub named: &'static [(&'static str, Named)],
    /// What the numeric codes of its fields mean (schema text).
    pub codes: &'static str,
}

/// `(usize)` of a per-sensor [`ServiceId`] variant.
macro_rules! sensor_index {
    ($sensor:ident) => {
        usize
    };
}

/// A wildcard pattern for a per-sensor variant's index.
macro_rules! any_index {
    ($sensor:ident) => {
        _
    };
}

/// Whether a row is per-sensor.
macro_rules! is_per_sensor {
    () => {
        false
    };
    ($sensor:ident) => {
        true
    };
}

/// `Some(index)` of a per-sensor variant, `None` of a shared one.
macro_rules! index_of {
    () => {
        None
    };
    ($sensor:ident) => {
        Some($sensor)
    };
}

/// The service of a row for an optional sensor index (`None` on a mismatch).
macro_rules! service_of {
    ($variant:path, $index:ident) => {
        match $index {
            None => Some($variant),
            Some(_) => None,
        }
    };
    ($variant:path, $index:ident, $sensor:ident) => {
        $index.map($variant)
    };
}

macro_rules! catalogue {
    ($(
        $(#[cfg($cfg:meta)])?
        $kind:ident $( ($sensor:ident) )? => $ty:ty {
            topic: $topic:literal,
            owner: $owner:ident,
            reader: $reader:ident,
            limits: $limits:ident $( ($buffer:expr) )?,
            link: $link:ident,
            recorded: $recorded:literal,
            forward: $forward:ident $( ($rank:literal) )?,
            names: [ $( $field:literal : $named:ident ),* ],
            codes: $codes:literal $(,)?
        }
    )*) => {
        /// The kind of a payload (one per message type).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum Kind { $( $(#[cfg($cfg)])? $kind, )* }

        impl Kind {
            /// Every kind, in catalogue order.
            pub const ALL: &'static [Kind] = &[ $( $(#[cfg($cfg)])? Kind::$kind, )* ];

            /// The schema name (the iceoryx2 type name `etp::<Kind>`).
            pub fn schema_name(self) -> &'static str {
                match self { $( $(#[cfg($cfg)])? Kind::$kind => concat!("etp::", stringify!($kind)), )* }
            }

            /// Its row of the catalogue.
            pub const fn row(self) -> &'static Row {
                match self {
                    $( $(#[cfg($cfg)])? Kind::$kind => {
                        const ROW: Row = Row {
                        kind: Kind::$kind,
                        topic: $topic,
                        per_sensor: is_per_sensor!($($sensor)?),
                        owner: Process::$owner,
                        reader: Process::$reader,
                        limits: LimitsClass::$limits $( ($buffer) )?,
                        link: Link::$link,
                        recorded: $recorded,
                        forward: Forward::$forward $( ($rank) )?,
                        named: &[ $( ($field, Named::$named), )* ],
                        codes: $codes,
                        };
                        &ROW
                    } )*
                }
            }

            /// Run `v` with the Rust type of this kind.
            pub fn visit<V: KindVisitor>(self, v: V) -> V::Out {
                match self { $( $(#[cfg($cfg)])? Kind::$kind => v.visit::<$ty>(), )* }
            }
        }

        /// One decoded payload of any kind.
        #[derive(Debug, Clone, PartialEq)]
        pub enum Recorded { $( $(#[cfg($cfg)])? $kind($ty), )* }

        impl Recorded {
            pub fn kind(&self) -> Kind {
                match self { $( $(#[cfg($cfg)])? Recorded::$kind(_) => Kind::$kind, )* }
            }

            pub fn header(&self) -> &Header {
                match self { $( $(#[cfg($cfg)])? Recorded::$kind(m) => &m.header, )* }
            }

            /// The payload as a JSON value (serde's view of the struct:
            /// nested `header`, arrays as arrays).
            pub fn to_json(&self) -> serde_json::Value {
                let v = match self { $( $(#[cfg($cfg)])? Recorded::$kind(m) => serde_json::to_value(m), )* };
                // Plain structs of numbers always serialize.
                v.unwrap_or(serde_json::Value::Null)
            }
        }

        $(
            $(#[cfg($cfg)])?
            impl Message for $ty {
                const KIND: Kind = Kind::$kind;
                fn into_recorded(self) -> Recorded { Recorded::$kind(self) }
                fn from_recorded(r: Recorded) -> Option<Self> {
                    #[allow(unreachable_patterns)]
                    match r { Recorded::$kind(m) => Some(m), _ => None }
                }
                fn header(&self) -> &Header { &self.header }
            }
        )*

        /// Every service of a run: one per shared message, one per sensor
        /// and per-sensor message, and the three wake-up events (one per
        /// process: peers publish, then notify the reader's event).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum ServiceId {
            $(
                $(#[cfg($cfg)])?
                #[doc = concat!("`", $topic, "`: ", stringify!($owner), " → ", stringify!($reader), " (", stringify!($kind), ").")]
                $kind $( (sensor_index!($sensor)) )?,
            )*
            /// event: wakes the agent.
            AgentWake,
            /// event: wakes the coordinator.
            CoordinatorWake,
            /// event: wakes sensor i.
            SensorWake(usize),
        }

        impl ServiceId {
            /// The kind of payload a publish-subscribe service carries;
            /// `None` for the wake-up events (no payload).
            pub const fn kind(self) -> Option<Kind> {
                match self {
                    $( $(#[cfg($cfg)])? Self::$kind $( (any_index!($sensor)) )? => Some(Kind::$kind), )*
                    Self::AgentWake | Self::CoordinatorWake | Self::SensorWake(_) => None,
                }
            }

            /// The sensor a per-sensor service (or wake-up event) belongs to.
            pub const fn sensor(self) -> Option<usize> {
                match self {
                    $( $(#[cfg($cfg)])? Self::$kind $( ($sensor) )? => index_of!($($sensor)?), )*
                    Self::SensorWake(i) => Some(i),
                    Self::AgentWake | Self::CoordinatorWake => None,
                }
            }

            /// The service of `kind` (of sensor `sensor` for a per-sensor
            /// kind; `None` for a shared one). `None` on a mismatch.
            pub fn of(kind: Kind, sensor: Option<usize>) -> Option<Self> {
                match kind {
                    $( $(#[cfg($cfg)])? Kind::$kind => service_of!(Self::$kind, sensor $(, $sensor)?), )*
                }
            }
        }

        // The columns' consistency, checked when the crate compiles.
        $(
            $(#[cfg($cfg)])?
            const _: () = {
                let row = Kind::$kind.row();
                // A sensor reads only its own per-sensor services; the reader
                // is one process.
                assert!(!matches!(row.reader, Process::Sensor) || row.per_sensor, concat!(stringify!($kind), ": a sensor reads only per-sensor services"));
                assert!(!matches!(row.reader, Process::Any), concat!(stringify!($kind), ": the reader is one process"));
                // Forwarded exactly when on the sensor link.
                assert!(row.link.class().is_some() == row.forward.direction().is_some(), concat!(stringify!($kind), ": forwarded iff on the sensor link"));
            };
        )*
    };
}

catalogue! {
    Control => c2a::Control {
        topic: "control",
        owner: Coordinator, reader: Agent,
        limits: OneToOne(8), link: Local, recorded: true, forward: Local,
        names: ["kind": ControlKind],
        codes: "kind: 1 = START (an episode), 2 = STOP (the agent exits)",
    }
    Threshold(sensor) => c2s::Threshold {
        topic: "sensor/{sensor}/threshold",
        owner: Coordinator, reader: Sensor,
        // Read by its sensor and by the agent; at most an OPEN and a CLOSE
        // per leg the sensor serves are ever outstanding.
        limits: OneToTwo(16), link: Plumbing, recorded: true, forward: Down(0),
        names: ["kind": ThresholdKind, "sensor": Sensor],
        codes: "kind: 1 = OPEN (leg header.leg at `sensor` with delta), 2 = CLOSE (the sensor answers with its ledger), 3 = STOP (the sensor exits); delta_index: index of delta in the strategy's thresholds",
    }
    Truth(sensor) => a2s::Truth {
        topic: "sensor/{sensor}/truth",
        owner: Agent, reader: Sensor,
        limits: OneToOne(8), link: Plumbing, recorded: true, forward: Down(3),
        names: [],
        codes: "x: the true state (simulation only: stands in for the physical world); entries past dim are 0",
    }
    Handover(sensor) => a2s::Handover {
        topic: "sensor/{sensor}/handover",
        owner: Agent, reader: Sensor,
        limits: OneToOne(8), link: Radio, recorded: true, forward: Down(1),
        names: [],
        codes: "radio, once per leg served: mean, cov = the agent's belief at the start of leg header.leg after header.step steps (row-major; entries past dim are 0); the sensor's replica computes the leg's priors from it",
    }
    Ack(sensor) => a2s::Ack {
        topic: "sensor/{sensor}/ack",
        owner: Agent, reader: Sensor,
        // At most one per slot, drained at the sensor's next wake-up.
        limits: OneToOne(16), link: Radio, recorded: true, forward: Down(2),
        names: [],
        codes: "radio, towards the sensor: the agent received the measurement of step header.step (sequence = its sequence); never lost (docs/MODEL.md §8)",
    }
    Measurement => s2a::Measurement {
        topic: "measurement",
        owner: Sensor, reader: Agent,
        limits: FromSensors(16), link: Radio, recorded: true, forward: Up(1),
        names: [],
        codes: "costed: one delivered transmission attempt; sequence: attempts of this sensor in this episode, this one included (a gap = attempts lost on the radio); y: entries past dim are 0",
    }
    Slot => s2a::Slot {
        topic: "slot",
        owner: Sensor, reader: Agent,
        limits: FromSensors(16), link: Plumbing, recorded: true, forward: Up(2),
        names: ["delivered": Flag],
        codes: "delivered: 1 if a measurement reached the agent in this slot, 0 if not (silent, or every attempt lost); attempts: transmission attempts in this slot (0 = no trigger; each costs c_m; lost = attempts - delivered); prior_digest: FNV-1a of the bits of the replica's prior (mean, then cov row by row)",
    }
    Waypoint => a2c::Waypoint {
        topic: "waypoint",
        owner: Agent, reader: Coordinator,
        limits: OneToOne(16), link: Local, recorded: true, forward: Local,
        names: ["prev_degraded": Flag],
        codes: "decision point header.leg reached; prev_*: counts of the leg that just ended; prev_degraded: 1 if it had a dead link",
    }
    Outcome => a2c::Outcome {
        topic: "outcome",
        owner: Agent, reader: Coordinator,
        limits: OneToOne(16), link: Local, recorded: true, forward: Local,
        names: ["outcome": Outcome, "degraded": Flag, "dead_sensor": SensorOrNone],
        codes: "outcome: 1 = TARGET, 2 = COLLISION, 3 = FREE; degraded: 1 if a slot had a dead link; dead_sensor: 4294967295 = none",
    }
    Ledger => s2c::Ledger {
        topic: "ledger",
        owner: Sensor, reader: Coordinator,
        // Drained at leg boundaries: a generous buffer per sensor.
        limits: FromSensors(256), link: Plumbing, recorded: true, forward: Up(3),
        names: [],
        codes: "what the sensor spent on leg header.leg: slots served, triggers, transmissions (attempts) = delivered + lost, energy = transmissions x cost",
    }
    Hello => tc::Hello {
        topic: "hello",
        owner: Any, reader: Coordinator,
        limits: Announce, link: Plumbing, recorded: true, forward: Up(0),
        names: [],
        codes: "a process is ready (pid)",
    }
    // Last of the recorded rows: a recording's channels keep the order
    // they had before it.
    Drift => a2c::Drift {
        topic: "drift",
        owner: Agent, reader: Coordinator,
        // At most three flags per sensor in a run.
        limits: OneToOne(64), link: Local, recorded: true, forward: Local,
        names: ["sensor": Sensor, "quantity": DriftQuantity],
        codes: "a flag of the agent's channel monitor (docs/MODEL.md 11) at header.step: quantity 1 = LOSS (attempts lost beyond the link's model), 2 = MORE_TRIGGERS, 3 = FEWER_TRIGGERS (than the family's rate at the slot's delta); alternative: the CUSUM's alternative (loss per attempt, trigger probability); statistic >= threshold (inf: an observation the model cannot produce); since_onset: observations from the estimated onset; estimate: lost/attempts since the onset, -1 = none",
    }
    // A message that exists only in this crate's tests: it shows that one
    // row derives everything (see `tests::a_test_only_row_derives_everything`).
    #[cfg(test)]
    Probe(sensor) => super::messages::test_only::Probe {
        topic: "sensor/{sensor}/probe",
        owner: Agent, reader: Sensor,
        limits: OneToOne(8), link: Radio, recorded: true, forward: Down(4),
        names: ["flag": Flag],
        codes: "flag: test only",
    }
}

/// How payloads are encoded on the bridge's link and in recordings of
/// format 4 and older: bincode 2.0.1 through serde with `config::legacy()`
/// (fixed-width little-endian integers, fields in the order of the
/// `#[repr(C)]` struct, padding fields included). Recordings are protobuf
/// since format 5 (`super::proto`, `crate::recording`).
pub const PAYLOAD_ENCODING: &str = "bincode2-serde-legacy";

/// Codes of the header, common to every kind.
pub const HEADER_CODES: &str = "header.run: hash of the run id; header.sender: the sensor's index, 4294901760 = coordinator, 4294901761 = agent; header.seq: per-sender sequence number";

impl Kind {
    /// The process that publishes this kind (`any`: every process).
    pub fn owner(self) -> &'static str {
        self.row().owner.name()
    }

    /// What the numeric codes of this kind's fields mean.
    pub fn codes(self) -> &'static str {
        self.row().codes
    }

    /// The fields of this kind whose numbers stand for names (the
    /// header's `sender` aside: see [`HEADER_NAMES`]).
    pub fn named_fields(self) -> &'static [(&'static str, Named)] {
        self.row().named
    }
}

/// What the number of a code field stands for, in exports and `replay cat`
/// (declared per kind in the catalogue; see [`Kind::named_fields`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Named {
    /// 0 / 1 → false / true.
    Flag,
    /// [`super::ControlKind`]: `start`, `stop`.
    ControlKind,
    /// [`super::ThresholdKind`]: `open`, `close`, `stop`.
    ThresholdKind,
    /// [`super::OutcomeCode`]: `target`, `collision`, `free`.
    Outcome,
    /// [`super::DriftQuantity`]: `loss`, `more_triggers`, `fewer_triggers`.
    DriftQuantity,
    /// A sensor index → the sensor's name.
    Sensor,
    /// A sensor index → its name; `u32::MAX` → none (null).
    SensorOrNone,
    /// `header.sender` → a sensor's name, `coordinator` or `agent`.
    Sender,
}

/// Named fields of the header, common to every kind.
pub const HEADER_NAMES: &[(&str, Named)] = &[("header.sender", Named::Sender)];
