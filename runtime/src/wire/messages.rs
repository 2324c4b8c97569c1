//! The payloads, one module per direction (the catalogue, `catalogue.rs`, lists who sends what to whom).
//!
//! Every payload is a fixed-size `#[repr(C)]` struct of plain numbers (no heap,
//! no pointers), sized for n ≤ 6 and m ≤ 6, and starts with a [`Header`]. The
//! derive `ZeroCopySend` lets iceoryx2 place them directly in shared memory.
//!
//! The derive expands to an `unsafe impl ZeroCopySend` (the trait is unsafe
//! because iceoryx2 cannot check that a type holds no pointers); the structs
//! below hold only integers, floats and arrays of them, which is exactly the
//! contract. That is the only reason this module allows `unsafe_code`.
#![allow(unsafe_code)]

use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Largest state or measurement dimension a payload carries.
pub const MAX_DIM: usize = 6;

/// A state-sized vector on the wire (unused entries are 0).
pub type WireVec = [f64; MAX_DIM];
/// A state-sized matrix on the wire, `[row][col]` (unused entries 0). Nested
/// arrays of 6 keep serde's derives usable (serde stops at arrays of 32).
pub type WireMat = [[f64; MAX_DIM]; MAX_DIM];

/// How many sensor indices a recording's protobuf enums name (`SENSOR_0` …
/// `SENSOR_63`): every sensor a run can have (`etp_launcher`'s
/// `MAX_SENSORS`, checked there); a larger index would still be recorded,
/// shown as its number.
pub const NAMED_SENSORS: u32 = 64;

/// Sender id of the coordinator.
pub const SENDER_COORDINATOR: u32 = 0xFFFF_0000;
/// Sender id of the agent.
pub const SENDER_AGENT: u32 = 0xFFFF_0001;
// Sensors send with their index in the scenario (0, 1, …).

/// Common first field of every payload.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ZeroCopySend, Serialize, Deserialize)]
pub struct Header {
    /// Hash of the run id ([`super::RunId::tag`]): a message from another run is refused.
    pub run: u64,
    /// Episode index (0-based).
    pub episode: u64,
    /// Step k inside the episode (1-based for plant steps; 0 before the first step).
    pub step: u32,
    /// Leg (decision point) index.
    pub leg: u32,
    /// Who sent it: a sensor index, [`SENDER_AGENT`] or [`SENDER_COORDINATOR`].
    pub sender: u32,
    /// Per-sender sequence number (for recording and gap detection).
    pub seq: u32,
}

/// Coordinator → agent.
pub mod coordinator_to_agent {
    use super::*;

    /// `control`: start an episode or stop the agent.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Control")]
    pub struct Control {
        pub header: Header,
        /// [`Control::START`] or [`Control::STOP`].
        pub kind: u32,
        /// State dimension of `initial_mean` / `initial_cov`.
        pub dim: u32,
        /// Run seed (the agent derives its per-episode stream from it).
        pub seed: u64,
        /// Initial belief x̂₀ (for the record: the agent takes it from the scenario).
        pub initial_mean: WireVec,
        /// Initial covariance P₀, row-major.
        pub initial_cov: WireMat,
    }

    impl Control {
        pub const START: u32 = 1;
        pub const STOP: u32 = 2;
    }
}

/// Coordinator → one sensor, with the agent listening (one service per
/// sensor, `threshold/<i>`, so a sensor is woken only for its own legs).
pub mod coordinator_to_sensor {
    use super::*;

    /// `threshold`: open leg i with δ at the serving sensor, close a leg (the
    /// sensor answers with its ledger), or stop.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Threshold")]
    pub struct Threshold {
        pub header: Header,
        /// [`Threshold::OPEN`], [`Threshold::CLOSE`] or [`Threshold::STOP`].
        pub kind: u32,
        /// The serving sensor of `header.leg` (index).
        pub sensor: u32,
        /// Index of δ in the strategy's Δ.
        pub delta_index: u32,
        pub _pad: u32,
        /// The threshold δ.
        pub delta: f64,
    }

    impl Threshold {
        pub const OPEN: u32 = 1;
        pub const CLOSE: u32 = 2;
        pub const STOP: u32 = 3;
    }
}

/// Agent → one sensor (one service per sensor, so idle sensors are never woken).
pub mod agent_to_sensor {
    use super::*;

    /// `truth`: the true state x_k (simulation only: stands in for the world).
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Truth")]
    pub struct Truth {
        pub header: Header,
        pub dim: u32,
        pub _pad: u32,
        pub x: WireVec,
    }

    /// `handover` (radio: once per leg served): the agent's belief x̂, P at
    /// the start of leg `header.leg` (after `header.step` steps). From it the
    /// sensor's replica computes every prior of the leg itself
    /// (`episode::LegReplica`), so no estimate is sent per step.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Handover")]
    pub struct Handover {
        pub header: Header,
        pub dim: u32,
        pub _pad: u32,
        pub mean: WireVec,
        pub cov: WireMat,
    }

    /// `ack` (radio, towards the sensor): the agent received the sensor's
    /// measurement of step `header.step` (docs/MODEL.md §8: the link is
    /// acknowledged, and ACKs are never lost). The sensor checks every ACK
    /// against a delivery it made.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Ack")]
    pub struct Ack {
        pub header: Header,
        /// The acknowledged measurement's `sequence`.
        pub sequence: u32,
        pub _pad: u32,
    }
}

/// Sensor → agent.
pub mod sensor_to_agent {
    use super::*;

    /// `measurement` (costed: c_m each): a transmitted y_k.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Measurement")]
    pub struct Measurement {
        pub header: Header,
        /// Measurement dimension m.
        pub dim: u32,
        /// Transmission attempts of this sensor in this episode, this one
        /// included (a gap in the sequence = attempts lost on the radio).
        pub sequence: u32,
        pub y: WireVec,
    }

    /// `slot`: "slot k closed" (sent after the measurement, if any;
    /// simulation plumbing: the slot clock, and the record of the slot's
    /// attempts on the radio, delivered or lost).
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Slot")]
    pub struct Slot {
        pub header: Header,
        /// 1 if a measurement was delivered to the agent in this slot (the
        /// agent must find it).
        pub delivered: u32,
        /// Transmission attempts in this slot, each costing c_m: 0 (no
        /// trigger), else 1 + retries after lost ones; lost = attempts −
        /// delivered.
        pub attempts: u32,
        /// `episode::belief_digest` of the prior the sensor's replica
        /// triggered on: the agent checks it against its own prior.
        pub prior_digest: u64,
    }
}

/// Agent → coordinator.
pub mod agent_to_coordinator {
    use super::*;

    /// `waypoint`: decision point `header.leg` reached (leg 0: episode start),
    /// with the belief there and the counts of the leg that just ended.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Waypoint")]
    pub struct Waypoint {
        pub header: Header,
        pub dim: u32,
        /// Plant steps of the previous leg (0 at leg 0).
        pub prev_steps: u32,
        /// Measurements received in the previous leg.
        pub prev_received: u32,
        /// 1 if the previous leg had a dead link.
        pub prev_degraded: u32,
        pub mean: WireVec,
        pub cov: WireMat,
    }

    /// `outcome`: the episode ended.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Outcome")]
    pub struct Outcome {
        pub header: Header,
        /// [`Outcome::TARGET`], [`Outcome::COLLISION`] or [`Outcome::FREE`].
        pub outcome: u32,
        /// 1 if any slot of the episode had a dead link (prediction only).
        pub degraded: u32,
        pub steps: u32,
        pub slots: u32,
        /// Measurements received in the episode.
        pub received: u32,
        /// Steps of the last leg and measurements received in it.
        pub last_steps: u32,
        pub last_received: u32,
        /// Slots in which the agent did prediction only (dead link).
        pub dead_slots: u32,
        /// Longest wait for a slot before a dead link was declared, µs (0: none).
        pub detect_us: u64,
        /// Wall clock (ns since the Unix epoch) when the dead link was declared (0: none).
        pub detected_unix_ns: u64,
        /// Wall clock when the agent started waiting on the dead link.
        pub wait_started_unix_ns: u64,
        /// Index of the sensor found dead (u32::MAX: none).
        pub dead_sensor: u32,
        pub _pad: u32,
    }

    impl Outcome {
        pub const TARGET: u32 = 1;
        pub const COLLISION: u32 = 2;
        pub const FREE: u32 = 3;
    }

    /// `drift`: the agent's monitor raised a flag (docs/MODEL.md §11): what
    /// sensor `sensor` carried is not the channel or trigger the strategy
    /// was synthesized for. `header.step` is the slot that raised it.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Drift")]
    pub struct Drift {
        pub header: Header,
        pub sensor: u32,
        /// [`Drift::LOSS`], [`Drift::MORE_TRIGGERS`] or [`Drift::FEWER_TRIGGERS`].
        pub quantity: u32,
        /// The alternative whose CUSUM reached the threshold: a loss per
        /// attempt, or a trigger probability per slot.
        pub alternative: f64,
        /// The CUSUM statistic (+∞: an observation the model cannot produce).
        pub statistic: f64,
        pub threshold: f64,
        /// Observations from the estimated onset to the flag.
        pub since_onset: u64,
        /// Observations of this test so far in the run.
        pub observations: u64,
        /// A loss flag's lost / attempts since the onset; -1 for none.
        pub estimate: f64,
    }

    impl Drift {
        pub const LOSS: u32 = 1;
        pub const MORE_TRIGGERS: u32 = 2;
        pub const FEWER_TRIGGERS: u32 = 3;

        /// The message of the monitor's flag `f` (the agent publishes it,
        /// `replay verify` compares the recorded one with it).
        pub fn of_flag(header: Header, f: &etp_shared::drift::Flag) -> Self {
            Self {
                header,
                sensor: f.sensor as u32,
                quantity: f.quantity.code(),
                alternative: f.alternative,
                statistic: f.statistic,
                threshold: f.threshold,
                since_onset: f.since_onset,
                observations: f.observations,
                estimate: f.estimate.unwrap_or(-1.0),
            }
        }

        /// The same flag, every field bit for bit, the header's episode and
        /// step included (its sender, run and sequence aside).
        pub fn same_flag(&self, other: &Self) -> bool {
            let bits = |a: f64, b: f64| a.to_bits() == b.to_bits();
            self.sensor == other.sensor
                && self.quantity == other.quantity
                && self.header.episode == other.header.episode
                && self.header.step == other.header.step
                && bits(self.alternative, other.alternative)
                && bits(self.statistic, other.statistic)
                && bits(self.threshold, other.threshold)
                && self.since_onset == other.since_onset
                && self.observations == other.observations
                && bits(self.estimate, other.estimate)
        }
    }
}

/// Sensor → coordinator.
pub mod sensor_to_coordinator {
    use super::*;

    /// `ledger`: what the sensor spent on leg `header.leg` of `header.episode`.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Ledger")]
    pub struct Ledger {
        pub header: Header,
        pub slots: u32,
        /// Slots in which the trigger fired.
        pub triggers: u32,
        /// Transmission attempts (each costs c_m) = delivered + lost.
        pub transmissions: u32,
        /// Attempts that reached the agent (= what it received).
        pub delivered: u32,
        /// Attempts lost on the radio.
        pub lost: u32,
        pub _pad: u32,
        /// transmissions × c_m.
        pub energy: f64,
    }
}

/// Any process → coordinator.
pub mod to_coordinator {
    use super::*;

    /// `hello`: a process has created all its ports and is ready.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Hello")]
    pub struct Hello {
        pub header: Header,
        pub pid: u32,
        pub _pad: u32,
    }
}

/// Messages of this crate's tests only (the catalogue's test-only row).
#[cfg(test)]
pub mod test_only {
    use super::*;

    /// `sensor/<i>/probe`: exists only to show that one row derives everything.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
    #[type_name("etp::Probe")]
    pub struct Probe {
        pub header: Header,
        pub flag: u32,
        pub _pad: u32,
    }
}

/// Copy a slice into a wire vector (entries beyond `MAX_DIM` are ignored).
pub fn to_wire_vec(v: &[f64]) -> WireVec {
    let mut out = [0.0; MAX_DIM];
    for (o, x) in out.iter_mut().zip(v) {
        *o = *x;
    }
    out
}

/// Copy an `n × n` matrix given by `get(row, col)` into a wire matrix.
pub fn to_wire_mat(n: usize, get: impl Fn(usize, usize) -> f64) -> WireMat {
    let mut out = [[0.0; MAX_DIM]; MAX_DIM];
    for (r, row) in out.iter_mut().enumerate().take(n) {
        for (c, x) in row.iter_mut().enumerate().take(n) {
            *x = get(r, c);
        }
    }
    out
}

/// A `u32` code field of a payload as a closed enum: `TryFrom<u32>` refuses
/// unknown codes, `code()` gives the wire value.
macro_rules! code_enum {
    ($(#[$m:meta])* $name:ident { $( $variant:ident = $value:expr ),* $(,)? }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $name { $( $variant, )* }

        impl $name {
            /// Every variant, in declaration order.
            pub const ALL: &'static [Self] = &[ $( Self::$variant, )* ];

            /// The value on the wire.
            pub const fn code(self) -> u32 {
                match self { $( Self::$variant => $value, )* }
            }

            /// The variant's name as declared (`Start`, `Open`, `Target`):
            /// a recording's protobuf enum value is this name upper-cased.
            pub const fn variant_name(self) -> &'static str {
                match self { $( Self::$variant => stringify!($variant), )* }
            }
        }

        impl TryFrom<u32> for $name {
            /// The unknown code.
            type Error = u32;
            fn try_from(v: u32) -> Result<Self, u32> {
                match v { $( x if x == $value => Ok(Self::$variant), )* other => Err(other) }
            }
        }
    };
}

code_enum! {
    /// `Control::kind`.
    ControlKind { Start = coordinator_to_agent::Control::START, Stop = coordinator_to_agent::Control::STOP }
}

code_enum! {
    /// `Threshold::kind`.
    ThresholdKind {
        Open = coordinator_to_sensor::Threshold::OPEN,
        Close = coordinator_to_sensor::Threshold::CLOSE,
        Stop = coordinator_to_sensor::Threshold::STOP,
    }
}

code_enum! {
    /// `Outcome::outcome`.
    OutcomeCode {
        Target = agent_to_coordinator::Outcome::TARGET,
        Collision = agent_to_coordinator::Outcome::COLLISION,
        Free = agent_to_coordinator::Outcome::FREE,
    }
}

impl OutcomeCode {
    /// The name used in reports ("target", "collision", "free").
    pub fn name(self) -> &'static str {
        match self {
            Self::Target => "target",
            Self::Collision => "collision",
            Self::Free => "free",
        }
    }
}

code_enum! {
    /// `Drift::quantity` (the codes of `etp_shared::drift::Quantity`).
    DriftQuantity {
        Loss = agent_to_coordinator::Drift::LOSS,
        MoreTriggers = agent_to_coordinator::Drift::MORE_TRIGGERS,
        FewerTriggers = agent_to_coordinator::Drift::FEWER_TRIGGERS,
    }
}

impl DriftQuantity {
    /// The name used in reports (`loss`, `more_triggers`, `fewer_triggers`).
    pub fn name(self) -> &'static str {
        self.quantity().name()
    }

    /// The monitor's quantity of this code.
    pub fn quantity(self) -> etp_shared::drift::Quantity {
        use etp_shared::drift::Quantity;
        match self {
            Self::Loss => Quantity::Loss,
            Self::MoreTriggers => Quantity::MoreTriggers,
            Self::FewerTriggers => Quantity::FewerTriggers,
        }
    }
}

#[cfg(test)]
mod code_tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_unknown_ones_are_refused() {
        for k in [
            ThresholdKind::Open,
            ThresholdKind::Close,
            ThresholdKind::Stop,
        ] {
            assert_eq!(ThresholdKind::try_from(k.code()), Ok(k));
        }
        assert_eq!(ThresholdKind::try_from(0), Err(0));
        assert_eq!(ControlKind::try_from(2), Ok(ControlKind::Stop));
        assert_eq!(OutcomeCode::try_from(3).map(OutcomeCode::name), Ok("free"));
        assert_eq!(OutcomeCode::try_from(9), Err(9));
        for q in DriftQuantity::ALL {
            assert_eq!(q.code(), q.quantity().code(), "{q:?}");
        }
    }
}
