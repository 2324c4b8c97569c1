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
    ($( $kind:ident => $ty:ty, owner $owner:literal,
        names [ $( $field:literal : $named:ident ),* ], codes $codes:literal; )*) => {
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

            /// The fields of this kind whose numbers stand for names (the
            /// header's `sender` aside: see [`HEADER_NAMES`]).
            pub fn named_fields(self) -> &'static [(&'static str, Named)] {
                match self { $( Kind::$kind => &[ $( ($field, Named::$named), )* ], )* }
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

            /// The payload as a JSON value (serde's view of the struct:
            /// nested `header`, arrays as arrays).
            pub fn to_json(&self) -> serde_json::Value {
                let v = match self { $( Recorded::$kind(m) => serde_json::to_value(m), )* };
                // Plain structs of numbers always serialize.
                v.unwrap_or(serde_json::Value::Null)
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
    Control => c2a::Control, owner "coordinator", names ["kind": ControlKind],
        codes "kind: 1 = START (an episode), 2 = STOP (the agent exits)";
    Threshold => c2all::Threshold, owner "coordinator", names ["kind": ThresholdKind, "sensor": Sensor],
        codes "kind: 1 = OPEN (leg header.leg at `sensor` with delta), 2 = CLOSE (the sensor answers with its ledger), 3 = STOP (the sensor exits); delta_index: index of delta in the strategy's thresholds";
    Truth => a2s::Truth, owner "agent", names [],
        codes "x: the true state (simulation only: stands in for the physical world); entries past dim are 0";
    Handover => a2s::Handover, owner "agent", names [],
        codes "radio, once per leg served: mean, cov = the agent's belief at the start of leg header.leg after header.step steps (row-major; entries past dim are 0); the sensor's replica computes the leg's priors from it";
    Measurement => s2a::Measurement, owner "sensor", names [],
        codes "costed: one transmission; sequence: transmissions of this sensor in this episode, this one included; y: entries past dim are 0";
    Slot => s2a::Slot, owner "sensor", names ["transmitted": Flag],
        codes "transmitted: 1 if a measurement was sent for this slot, 0 if silent; prior_digest: FNV-1a of the bits of the replica's prior (mean, then cov row by row)";
    Waypoint => a2c::Waypoint, owner "agent", names ["prev_degraded": Flag],
        codes "decision point header.leg reached; prev_*: counts of the leg that just ended; prev_degraded: 1 if it had a dead link";
    Outcome => a2c::Outcome, owner "agent",
        names ["outcome": Outcome, "degraded": Flag, "dead_sensor": SensorOrNone],
        codes "outcome: 1 = TARGET, 2 = COLLISION, 3 = FREE; degraded: 1 if a slot had a dead link; dead_sensor: 4294967295 = none";
    Ledger => s2c::Ledger, owner "sensor", names [],
        codes "what the sensor spent on leg header.leg: slots served, transmissions, energy = transmissions x cost";
    Hello => tc::Hello, owner "any", names [],
        codes "a process is ready (pid)";
}

/// How payloads are encoded in a recording: bincode 2.0.1 through serde with
/// `config::legacy()` (fixed-width little-endian integers, fields in the
/// order of the `#[repr(C)]` struct, padding fields included).
pub const PAYLOAD_ENCODING: &str = "bincode2-serde-legacy";

/// Codes of the header, common to every kind.
pub const HEADER_CODES: &str = "header.run: hash of the run id; header.sender: the sensor's index, 4294901760 = coordinator, 4294901761 = agent; header.seq: per-sender sequence number";

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
    /// A sensor index → the sensor's name.
    Sensor,
    /// A sensor index → its name; `u32::MAX` → none (null).
    SensorOrNone,
    /// `header.sender` → a sensor's name, `coordinator` or `agent`.
    Sender,
}

/// Named fields of the header, common to every kind.
pub const HEADER_NAMES: &[(&str, Named)] = &[("header.sender", Named::Sender)];

/// The scalar type of a payload field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    U8,
    U16,
    U32,
    U64,
    I32,
    I64,
    F32,
    F64,
    Bool,
}

impl Scalar {
    /// The Rust spelling (`u32`, `f64`, …).
    pub fn name(self) -> &'static str {
        match self {
            Self::U8 => "u8",
            Self::U16 => "u16",
            Self::U32 => "u32",
            Self::U64 => "u64",
            Self::I32 => "i32",
            Self::I64 => "i64",
            Self::F32 => "f32",
            Self::F64 => "f64",
            Self::Bool => "bool",
        }
    }

    /// The Python `struct` format character (little-endian, standard sizes).
    pub fn struct_char(self) -> char {
        match self {
            Self::U8 => 'B',
            Self::U16 => 'H',
            Self::U32 => 'I',
            Self::U64 => 'Q',
            Self::I32 => 'i',
            Self::I64 => 'q',
            Self::F32 => 'f',
            Self::F64 => 'd',
            Self::Bool => '?',
        }
    }

    /// Bytes on the wire.
    pub fn size(self) -> usize {
        match self {
            Self::U8 | Self::Bool => 1,
            Self::U16 => 2,
            Self::U32 | Self::I32 | Self::F32 => 4,
            Self::U64 | Self::I64 | Self::F64 => 8,
        }
    }
}

/// One field of a payload in wire order: its path (`header.seq`, `y`), its
/// scalar type and array shape (`[]` scalar, `[6]` vector, `[6, 6]` matrix).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub path: Vec<String>,
    pub scalar: Scalar,
    pub shape: Vec<usize>,
}

impl Field {
    /// `header.seq`, `y`.
    pub fn name(&self) -> String {
        self.path.join(".")
    }

    /// A padding field (`_pad`): no information.
    pub fn is_padding(&self) -> bool {
        self.path.last().is_some_and(|p| p.starts_with('_'))
    }

    /// `u32`, `[f64; 6]`, `[[f64; 6]; 6]`.
    pub fn type_name(&self) -> String {
        self.shape
            .iter()
            .rev()
            .fold(self.scalar.name().to_string(), |t, n| format!("[{t}; {n}]"))
    }

    /// Number of scalars.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    /// True for a zero-sized array (none in the catalogue).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The fields of `T` in wire order, nested structs (the header) flattened;
/// traced from the type's serde implementation, so it is the layout bincode
/// writes.
fn fields_of<T: Message>() -> Result<Vec<Field>, String> {
    use serde_reflection::{ContainerFormat, Format, Tracer, TracerConfig};
    fn scalar(f: &Format, shape: &mut Vec<usize>) -> Result<Scalar, String> {
        Ok(match f {
            Format::U8 => Scalar::U8,
            Format::U16 => Scalar::U16,
            Format::U32 => Scalar::U32,
            Format::U64 => Scalar::U64,
            Format::I32 => Scalar::I32,
            Format::I64 => Scalar::I64,
            Format::F32 => Scalar::F32,
            Format::F64 => Scalar::F64,
            Format::Bool => Scalar::Bool,
            Format::TupleArray { content, size } => {
                shape.push(*size);
                scalar(content, shape)?
            }
            other => return Err(format!("unsupported field format {other:?}")),
        })
    }
    fn walk(
        registry: &serde_reflection::Registry,
        name: &str,
        prefix: &[String],
        out: &mut Vec<Field>,
    ) -> Result<(), String> {
        let Some(ContainerFormat::Struct(fields)) = registry.get(name) else {
            return Err(format!("`{name}` is not a struct"));
        };
        for f in fields {
            let mut path = prefix.to_vec();
            path.push(f.name.clone());
            match &f.value {
                Format::TypeName(inner) => walk(registry, inner, &path, out)?,
                v => {
                    let mut shape = Vec::new();
                    let scalar = scalar(v, &mut shape)?;
                    out.push(Field {
                        path,
                        scalar,
                        shape,
                    });
                }
            }
        }
        Ok(())
    }
    let mut tracer = Tracer::new(TracerConfig::default());
    tracer.trace_simple_type::<T>().map_err(|e| e.to_string())?;
    let registry = tracer.registry().map_err(|e| e.to_string())?;
    let name = std::any::type_name::<T>()
        .rsplit("::")
        .next()
        .unwrap_or_default()
        .to_string();
    let mut out = Vec::new();
    walk(&registry, &name, &[], &mut out)?;
    Ok(out)
}

struct Fields;

impl KindVisitor for Fields {
    type Out = Result<Vec<Field>, String>;
    fn visit<T: Message>(self) -> Self::Out {
        fields_of::<T>()
    }
}

impl Kind {
    /// The payload's fields in wire order (traced from the type).
    pub fn fields(self) -> Result<Vec<Field>, String> {
        self.visit(Fields)
    }

    /// The Python `struct` format of a payload (`<` little-endian, standard
    /// sizes, padding fields included), e.g. `<QQIIIIII6d`.
    pub fn struct_format(self) -> Result<String, String> {
        let mut f = String::from("<");
        for x in self.fields()? {
            match x.len() {
                1 => f.push(x.scalar.struct_char()),
                n => f.push_str(&format!("{n}{}", x.scalar.struct_char())),
            }
        }
        Ok(f)
    }

    /// The schema text of a recording's channel of this kind: a header line,
    /// the fields in wire order (traced from the type), the payload's size
    /// and Python `struct` format, the codes and named fields.
    pub fn schema_text(self) -> String {
        let encoding = PAYLOAD_ENCODING;
        let (fields, layout) = match (self.fields(), self.struct_format()) {
            (Ok(f), Ok(s)) => {
                let size: usize = f.iter().map(|x| x.len() * x.scalar.size()).sum();
                (
                    f.iter()
                        .map(|x| format!("{}: {}\n", x.name(), x.type_name()))
                        .collect::<String>(),
                    format!("# size: {size} bytes; python: struct.unpack(\"{s}\", data)\n"),
                )
            }
            (Err(e), _) | (_, Err(e)) => (
                format!("# fields could not be traced: {e}\n"),
                String::new(),
            ),
        };
        let named: Vec<String> = HEADER_NAMES
            .iter()
            .chain(self.named_fields())
            .map(|(f, n)| format!("{f} ({})", n.describe()))
            .collect();
        format!(
            "# {} ({encoding}), published by {}\n{fields}{layout}# codes: {HEADER_CODES}\n# codes: {}\n# names in `etp replay export` and `cat`: {}\n",
            self.schema_name(),
            match self.owner() {
                "any" => "any process".to_string(),
                owner => format!("the {owner}"),
            },
            self.codes(),
            named.join("; ")
        )
    }
}

impl Named {
    /// How an export shows the field.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Flag => "bool",
            Self::ControlKind => "start | stop",
            Self::ThresholdKind => "open | close | stop",
            Self::Outcome => "target | collision | free",
            Self::Sensor => "the sensor's name",
            Self::SensorOrNone => "the sensor's name, or null for none",
            Self::Sender => "the sensor's name, coordinator or agent",
        }
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
        assert!(
            t.contains("# size: 88 bytes; python: struct.unpack(\"<QQIIIIII6d\", data)\n"),
            "{t}"
        );
        assert!(
            Kind::Outcome
                .schema_text()
                .contains("dead_sensor (the sensor's name, or null for none)")
        );
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
