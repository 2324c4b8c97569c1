//! THE message catalogue: every payload of the runtime declared once — its
//! kind, its Rust type, the process that publishes it — and everything else
//! derived from that one list: the [`Kind`] enum, the decoded [`Recorded`]
//! union, typed dispatch over kinds ([`KindVisitor`]), the schema text of a
//! recording (field names and types traced from the type itself, so it cannot
//! drift from the struct), and which kind each service carries
//! ([`ServiceId::kind`], topics in [`ServiceId::topic`] /
//! [`ServiceId::from_topic`]).
//!
//! Adding a message is one line in the `catalogue!` invocation below (plus
//! its struct in [`super::messages`] and, if it gets a service of its own, a
//! [`ServiceId`] variant).

use super::messages::{
    Header, agent_to_coordinator as a2c, agent_to_sensor as a2s, coordinator_to_agent as c2a,
    coordinator_to_all as c2all, sensor_to_agent as s2a, sensor_to_coordinator as s2c,
    to_coordinator as tc,
};
use super::services::ServiceId;
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

macro_rules! catalogue {
    ($( $kind:ident => $ty:ty, owner $owner:literal, codes $codes:literal; )*) => {
        /// The kind of a payload (one per message type).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum Kind { $( $kind, )* }

        impl Kind {
            /// Every kind, in catalogue order.
            pub const ALL: &'static [Kind] = &[ $( Kind::$kind, )* ];

            /// The schema name (the iceoryx2 type name `etp::<Kind>`).
            pub fn schema_name(self) -> &'static str {
                match self { $( Kind::$kind => concat!("etp::", stringify!($kind)), )* }
            }

            /// The process that publishes this kind.
            pub fn owner(self) -> &'static str {
                match self { $( Kind::$kind => $owner, )* }
            }

            /// What the numeric codes of this kind's fields mean.
            pub fn codes(self) -> &'static str {
                match self { $( Kind::$kind => $codes, )* }
            }

            /// Run `v` with the Rust type of this kind.
            pub fn visit<V: KindVisitor>(self, v: V) -> V::Out {
                match self { $( Kind::$kind => v.visit::<$ty>(), )* }
            }
        }

        /// One decoded payload of any kind.
        #[derive(Debug, Clone, PartialEq)]
        pub enum Recorded { $( $kind($ty), )* }

        impl Recorded {
            pub fn kind(&self) -> Kind {
                match self { $( Recorded::$kind(_) => Kind::$kind, )* }
            }

            pub fn header(&self) -> &Header {
                match self { $( Recorded::$kind(m) => &m.header, )* }
            }
        }

        $(
            impl Message for $ty {
                const KIND: Kind = Kind::$kind;
                fn into_recorded(self) -> Recorded { Recorded::$kind(self) }
                fn from_recorded(r: Recorded) -> Option<Self> {
                    match r { Recorded::$kind(m) => Some(m), _ => None }
                }
                fn header(&self) -> &Header { &self.header }
            }
        )*
    };
}

catalogue! {
    Control => c2a::Control, owner "coordinator",
        codes "kind: 1 = START (an episode), 2 = STOP (the agent exits)";
    Threshold => c2all::Threshold, owner "coordinator",
        codes "kind: 1 = OPEN (leg header.leg at `sensor` with delta), 2 = CLOSE (the sensor answers with its ledger), 3 = STOP (the sensor exits); delta_index: index of delta in the strategy's thresholds";
    Truth => a2s::Truth, owner "agent",
        codes "x: the true state (simulation only: stands in for the physical world); entries past dim are 0";
    Handover => a2s::Handover, owner "agent",
        codes "radio, once per leg served: mean, cov = the agent's belief at the start of leg header.leg after header.step steps (row-major; entries past dim are 0); the sensor's replica computes the leg's priors from it";
    Measurement => s2a::Measurement, owner "sensor",
        codes "costed: one transmission; sequence: transmissions of this sensor in this episode, this one included; y: entries past dim are 0";
    Slot => s2a::Slot, owner "sensor",
        codes "transmitted: 1 if a measurement was sent for this slot, 0 if silent; prior_digest: FNV-1a of the bits of the replica's prior (mean, then cov row by row)";
    Waypoint => a2c::Waypoint, owner "agent",
        codes "decision point header.leg reached; prev_*: counts of the leg that just ended; prev_degraded: 1 if it had a dead link";
    Outcome => a2c::Outcome, owner "agent",
        codes "outcome: 1 = TARGET, 2 = COLLISION, 3 = FREE; degraded: 1 if a slot had a dead link; dead_sensor: 4294967295 = none";
    Ledger => s2c::Ledger, owner "sensor",
        codes "what the sensor spent on leg header.leg: slots served, transmissions, energy = transmissions x cost";
    Hello => tc::Hello, owner "any",
        codes "a process is ready (pid)";
}

/// How payloads are encoded in a recording: bincode 2.0.1 through serde with
/// `config::legacy()` (fixed-width little-endian integers, fields in the
/// order of the `#[repr(C)]` struct, padding fields included).
pub const PAYLOAD_ENCODING: &str = "bincode2-serde-legacy";

/// Codes of the header, common to every kind.
pub const HEADER_CODES: &str = "header.run: hash of the run id; header.sender: the sensor's index, 4294901760 = coordinator, 4294901761 = agent; header.seq: per-sender sequence number";

fn format_name(f: &serde_reflection::Format) -> String {
    use serde_reflection::Format as F;
    match f {
        F::U8 => "u8".into(),
        F::U16 => "u16".into(),
        F::U32 => "u32".into(),
        F::U64 => "u64".into(),
        F::I32 => "i32".into(),
        F::I64 => "i64".into(),
        F::F32 => "f32".into(),
        F::F64 => "f64".into(),
        F::Bool => "bool".into(),
        F::TupleArray { content, size } => format!("[{}; {size}]", format_name(content)),
        F::TypeName(n) => n.clone(),
        other => format!("{other:?}"),
    }
}

/// The fields of `T` in wire order, `name: type` per line, nested structs
/// (the header) flattened as `header.field`; traced from the type's serde
/// implementation, so it is the layout bincode writes.
fn fields_of<T: Message>() -> Result<String, String> {
    use serde_reflection::{ContainerFormat, Format, Tracer, TracerConfig};
    let mut tracer = Tracer::new(TracerConfig::default());
    tracer.trace_simple_type::<T>().map_err(|e| e.to_string())?;
    let registry = tracer.registry().map_err(|e| e.to_string())?;
    fn walk(
        registry: &serde_reflection::Registry,
        name: &str,
        prefix: &str,
        out: &mut String,
    ) -> Result<(), String> {
        let Some(ContainerFormat::Struct(fields)) = registry.get(name) else {
            return Err(format!("`{name}` is not a struct"));
        };
        for f in fields {
            match &f.value {
                Format::TypeName(inner) => {
                    walk(registry, inner, &format!("{prefix}{}.", f.name), out)?;
                }
                v => {
                    out.push_str(&format!("{prefix}{}: {}\n", f.name, format_name(v)));
                }
            }
        }
        Ok(())
    }
    let name = std::any::type_name::<T>()
        .rsplit("::")
        .next()
        .unwrap_or_default()
        .to_string();
    let mut out = String::new();
    walk(&registry, &name, "", &mut out)?;
    Ok(out)
}

struct SchemaText;

impl KindVisitor for SchemaText {
    type Out = Result<String, String>;
    fn visit<T: Message>(self) -> Self::Out {
        fields_of::<T>()
    }
}

impl Kind {
    /// The schema text of a recording's channel of this kind: a header line,
    /// the fields in wire order (traced from the type), the codes.
    pub fn schema_text(self) -> String {
        let encoding = PAYLOAD_ENCODING;
        let fields = self
            .visit(SchemaText)
            .unwrap_or_else(|e| format!("# fields could not be traced: {e}\n"));
        format!(
            "# {} ({encoding}), published by the {}\n{fields}# codes: {HEADER_CODES}\n# codes: {}\n",
            self.schema_name(),
            self.owner(),
            self.codes()
        )
    }
}

impl ServiceId {
    /// The kind of payload a publish-subscribe service carries; `None` for
    /// the wake-up events (no payload).
    pub fn kind(self) -> Option<Kind> {
        Some(match self {
            Self::Control => Kind::Control,
            Self::Threshold(_) => Kind::Threshold,
            Self::Truth(_) => Kind::Truth,
            Self::Handover(_) => Kind::Handover,
            Self::Measurement => Kind::Measurement,
            Self::Slot => Kind::Slot,
            Self::Waypoint => Kind::Waypoint,
            Self::Outcome => Kind::Outcome,
            Self::Ledger => Kind::Ledger,
            Self::Hello => Kind::Hello,
            Self::AgentWake | Self::CoordinatorWake | Self::SensorWake(_) => return None,
        })
    }

    /// The inverse of [`ServiceId::topic`] for publish-subscribe services.
    pub fn from_topic(topic: &str) -> Option<Self> {
        let per_sensor = |tail: &str| -> Option<usize> {
            topic
                .strip_prefix("sensor/")?
                .strip_suffix(tail)?
                .parse()
                .ok()
        };
        let s = match topic {
            "control" => Self::Control,
            "measurement" => Self::Measurement,
            "slot" => Self::Slot,
            "waypoint" => Self::Waypoint,
            "outcome" => Self::Outcome,
            "ledger" => Self::Ledger,
            "hello" => Self::Hello,
            _ => {
                if let Some(i) = per_sensor("/truth") {
                    Self::Truth(i)
                } else if let Some(i) = per_sensor("/handover") {
                    Self::Handover(i)
                } else {
                    Self::Threshold(per_sensor("/threshold")?)
                }
            }
        };
        // Canonical spelling only ("sensor/01/truth" is not a topic).
        (s.topic() == topic).then_some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_text_is_traced_from_the_types() {
        let t = Kind::Measurement.schema_text();
        assert!(
            t.starts_with("# etp::Measurement (bincode2-serde-legacy), published by the sensor\n"),
            "{t}"
        );
        assert!(t.contains("header.run: u64\nheader.episode: u64\nheader.step: u32\nheader.leg: u32\nheader.sender: u32\nheader.seq: u32\ndim: u32\nsequence: u32\ny: [f64; 6]\n"), "{t}");
        assert!(
            Kind::Handover
                .schema_text()
                .contains("cov: [[f64; 6]; 6]\n")
        );
        assert!(Kind::Outcome.schema_text().contains("1 = TARGET"));
        for k in Kind::ALL {
            let t = k.schema_text();
            assert!(!t.contains("could not be traced"), "{t}");
            assert!(t.contains("header.seq: u32"), "{t}");
        }
    }

    #[test]
    fn every_service_has_one_topic_and_kind() {
        for s in ServiceId::all_pubsub(12) {
            assert_eq!(ServiceId::from_topic(&s.topic()), Some(s));
            assert!(s.kind().is_some(), "{s:?}");
        }
        for bad in [
            "",
            "sensor/x/truth",
            "sensor/1/wake",
            "sensor//handover",
            "sensor/01/truth",
            "nope",
        ] {
            assert_eq!(ServiceId::from_topic(bad), None, "{bad}");
        }
        assert_eq!(Kind::ALL.len(), 10);
    }

    #[test]
    fn the_union_round_trips_every_kind() {
        let m = s2a::Slot::default();
        let r = m.into_recorded();
        assert_eq!(r.kind(), Kind::Slot);
        assert_eq!(s2a::Slot::from_recorded(r.clone()), Some(m));
        assert_eq!(s2a::Measurement::from_recorded(r), None);
    }
}
