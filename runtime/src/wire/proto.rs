//! The protobuf schema of every payload, derived from the payload types
//! themselves: each message's descriptor is built from the type's serde
//! implementation (the same trace as [`super::schema`]) and the catalogue's
//! named fields, so there is no `.proto` file to drift from the structs.
//!
//! The mapping ([`ProtoMapping::Typed`], recording format 6, `crate::recording`):
//! * one protobuf message per kind, `etp.<Kind>` (proto3), in a file of its
//!   own, `etp/<Kind>.proto`; a nested struct (the header) is a nested
//!   message type (`etp.<Kind>.Header`), so each kind's file is
//!   self-contained: a channel's schema is one `FileDescriptorSet` of one file;
//! * fields numbered 1, 2, … in the struct's order; padding fields
//!   (`_pad`) have no field (they are always 0);
//! * `u8`/`u16`/`u32` → `uint32`, `u64` → `uint64`, `i32` → `int32`, `i64` →
//!   `int64`, `f32` → `float`, `f64` → `double`, `bool` → `bool`;
//! * a field the catalogue names (`Row::named`, `HEADER_NAMES`) is typed by
//!   what it names: a 0/1 flag is a `bool`; a code (`Control.kind`,
//!   `Threshold.kind`, `Outcome.outcome`) an enum of the code's values with
//!   `<ENUM>_UNSPECIFIED = 0` first (`Outcome.OutcomeCode`: `TARGET = 1`, …);
//!   a sensor index an enum `Sensor` of `SENSOR_0` … `SENSOR_63`; the
//!   header's `sender` an enum `Header.Sender` of the sensors, `COORDINATOR`
//!   and `AGENT`, and `Outcome.dead_sensor` an enum `SensorOrNone` of the
//!   sensors and `NONE`. The ids past the sensors are the `u32` sentinels
//!   read as protobuf's `int32` enum numbers (`COORDINATOR = -65536` is
//!   0xFFFF0000, `AGENT = -65535`, `NONE = -1` is `u32::MAX`), so the value
//!   on the wire is the payload's `u32` bit for bit; protobuf enums are open,
//!   so an index past the named ones is still recorded, shown as its number.
//!   Enums are nested in their message (`etp.Outcome.OutcomeCode`);
//! * a fixed array (also nested: a matrix) → a packed `repeated` field of its
//!   scalars in row-major order, holding only the entries the payload's
//!   `dim` field says are used: `dim` values for a vector, the `dim × dim`
//!   top-left block for a matrix (the entries past `dim` are 0 in every
//!   payload and are put back on reading). Every payload with an array has a
//!   `dim` before it (checked when the descriptors are built).
//!
//! [`ProtoMapping::Plain`] is format 5's: every field a plain integer or
//! float, every array written whole (6 values for a vector, 36 for a 6 × 6
//! matrix). Its descriptors are kept to read format-5 files.
//!
//! Field numbers follow the struct's order: a change of a payload struct
//! changes its schema, which is why the recording's format version moves
//! with it (each file carries its own schemas, so other readers never
//! misread an older file).

use super::catalogue::{HEADER_NAMES, Kind, KindVisitor, Message, Named};
use super::messages::{
    ControlKind, DriftQuantity, NAMED_SENSORS, OutcomeCode, SENDER_AGENT, SENDER_COORDINATOR,
    ThresholdKind,
};
use prost::Message as _;
use prost_reflect::{DescriptorPool, MessageDescriptor};
use prost_types::field_descriptor_proto::{Label, Type};
use prost_types::{
    DescriptorProto, EnumDescriptorProto, EnumValueDescriptorProto, FieldDescriptorProto,
    FileDescriptorProto, FileDescriptorSet,
};
use serde_reflection::{ContainerFormat, Format, Registry};
use std::collections::BTreeMap;
use std::sync::OnceLock;

/// The protobuf package of every payload.
pub const PACKAGE: &str = "etp";

/// The field whose value is the used length of every array of its payload
/// (per axis) in [`ProtoMapping::Typed`].
pub const DIM_FIELD: &str = "dim";

/// How a payload maps onto protobuf.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ProtoMapping {
    /// Recording format 5: plain integers, arrays written whole.
    Plain,
    /// Recording format 6 (what the recorder writes): codes as enums, flags
    /// as `bool`, arrays cut to `dim`.
    Typed,
}

impl ProtoMapping {
    pub const ALL: [Self; 2] = [Self::Plain, Self::Typed];

    /// Whether arrays hold only the `dim` entries in use.
    pub fn sized_arrays(self) -> bool {
        self == Self::Typed
    }
}

/// The descriptors of every kind in every mapping, built once.
struct Schemas {
    /// (mapping, kind) → (its message descriptor, its `FileDescriptorSet` bytes).
    by_kind: BTreeMap<(ProtoMapping, Kind), (MessageDescriptor, Vec<u8>)>,
}

fn schemas() -> Result<&'static Schemas, String> {
    static SCHEMAS: OnceLock<Result<Schemas, String>> = OnceLock::new();
    SCHEMAS
        .get_or_init(|| {
            let mut by_kind = BTreeMap::new();
            for mapping in ProtoMapping::ALL {
                for &kind in Kind::ALL {
                    let file = kind.visit(FileOf(mapping))?;
                    let set = FileDescriptorSet { file: vec![file] };
                    let bytes = set.encode_to_vec();
                    // One pool per kind: every file defines its own `Header`.
                    let pool = DescriptorPool::decode(bytes.as_slice())
                        .map_err(|e| format!("{kind:?}: {e}"))?;
                    let desc = pool
                        .get_message_by_name(&kind.proto_name())
                        .ok_or_else(|| format!("{kind:?}: no message {}", kind.proto_name()))?;
                    by_kind.insert((mapping, kind), (desc, bytes));
                }
            }
            Ok(Schemas { by_kind })
        })
        .as_ref()
        .map_err(Clone::clone)
}

impl Kind {
    /// The protobuf message name, `etp.<Kind>` (the schema name of a
    /// protobuf recording's channel, formats 5 and 6 alike).
    pub fn proto_name(self) -> String {
        format!(
            "{PACKAGE}.{}",
            self.schema_name().trim_start_matches("etp::")
        )
    }

    /// The message descriptor of this kind's payload as the recorder writes it.
    pub fn proto_descriptor(self) -> Result<MessageDescriptor, String> {
        self.proto_descriptor_in(ProtoMapping::Typed)
    }

    /// The message descriptor of this kind's payload in `mapping`.
    pub fn proto_descriptor_in(self, mapping: ProtoMapping) -> Result<MessageDescriptor, String> {
        let s = schemas()?;
        s.by_kind
            .get(&(mapping, self))
            .map(|(d, _)| d.clone())
            .ok_or_else(|| format!("{self:?}: no descriptor"))
    }

    /// The schema data of a channel as the recorder writes it: a serialized
    /// `google.protobuf.FileDescriptorSet` holding this kind's one file.
    pub fn proto_schema(self) -> Result<&'static [u8], String> {
        self.proto_schema_in(ProtoMapping::Typed)
    }

    /// The schema data of a channel of this kind in `mapping`.
    pub fn proto_schema_in(self, mapping: ProtoMapping) -> Result<&'static [u8], String> {
        let s = schemas()?;
        s.by_kind
            .get(&(mapping, self))
            .map(|(_, b)| b.as_slice())
            .ok_or_else(|| format!("{self:?}: no descriptor"))
    }
}

struct FileOf(ProtoMapping);

impl KindVisitor for FileOf {
    type Out = Result<FileDescriptorProto, String>;
    fn visit<T: Message>(self) -> Self::Out {
        let (registry, name) = super::schema::traced::<T>()?;
        let full = format!(".{PACKAGE}.{name}");
        let named: Vec<(&str, Named)> = match self.0 {
            ProtoMapping::Plain => Vec::new(),
            ProtoMapping::Typed => HEADER_NAMES
                .iter()
                .chain(T::KIND.named_fields())
                .copied()
                .collect(),
        };
        let shape = Shape {
            registry: &registry,
            named: &named,
            sized: self.0.sized_arrays(),
        };
        let message = shape.message(&name, "", &full)?;
        Ok(FileDescriptorProto {
            name: Some(format!("{PACKAGE}/{name}.proto")),
            package: Some(PACKAGE.into()),
            message_type: vec![message],
            syntax: Some("proto3".into()),
            ..Default::default()
        })
    }
}

/// The scalar type of a serde format (the innermost one of an array).
fn scalar(f: &Format) -> Result<(Type, bool), String> {
    Ok(match f {
        Format::U8 | Format::U16 | Format::U32 => (Type::Uint32, false),
        Format::U64 => (Type::Uint64, false),
        Format::I32 => (Type::Int32, false),
        Format::I64 => (Type::Int64, false),
        Format::F32 => (Type::Float, false),
        Format::F64 => (Type::Double, false),
        Format::Bool => (Type::Bool, false),
        Format::TupleArray { content, .. } => (scalar(content)?.0, true),
        other => return Err(format!("unsupported field format {other:?}")),
    })
}

/// The protobuf enum a named field is, as (enum name, values); `None` for a
/// flag (a `bool`).
fn enum_of(named: Named) -> Option<(&'static str, Vec<(String, i32)>)> {
    // A u32 code read as protobuf's int32 enum number, bit for bit.
    let number = |code: u32| i32::from_ne_bytes(code.to_ne_bytes());
    fn codes(prefix: &str, all: impl Iterator<Item = (&'static str, u32)>) -> Vec<(String, i32)> {
        let all: Vec<(String, i32)> = all
            .map(|(n, c)| (n.to_uppercase(), i32::from_ne_bytes(c.to_ne_bytes())))
            .collect();
        // proto3: an enum's first value is 0.
        let unspecified =
            (!all.iter().any(|(_, c)| *c == 0)).then(|| (format!("{prefix}_UNSPECIFIED"), 0));
        unspecified.into_iter().chain(all).collect()
    }
    let sensors = || (0..NAMED_SENSORS).map(move |i| (format!("SENSOR_{i}"), number(i)));
    Some(match named {
        Named::Flag => return None,
        Named::ControlKind => (
            "ControlKind",
            codes(
                "CONTROL_KIND",
                ControlKind::ALL
                    .iter()
                    .map(|k| (k.variant_name(), k.code())),
            ),
        ),
        Named::ThresholdKind => (
            "ThresholdKind",
            codes(
                "THRESHOLD_KIND",
                ThresholdKind::ALL
                    .iter()
                    .map(|k| (k.variant_name(), k.code())),
            ),
        ),
        Named::Outcome => (
            "OutcomeCode",
            codes(
                "OUTCOME",
                OutcomeCode::ALL
                    .iter()
                    .map(|k| (k.variant_name(), k.code())),
            ),
        ),
        Named::DriftQuantity => (
            "DriftQuantity",
            codes(
                "DRIFT_QUANTITY",
                DriftQuantity::ALL
                    .iter()
                    .map(|k| (k.variant_name(), k.code())),
            ),
        ),
        Named::Sensor => ("Sensor", sensors().collect()),
        Named::SensorOrNone => (
            "SensorOrNone",
            sensors()
                .chain([("NONE".to_string(), number(u32::MAX))])
                .collect(),
        ),
        Named::Sender => (
            "Sender",
            sensors()
                .chain([
                    ("COORDINATOR".to_string(), number(SENDER_COORDINATOR)),
                    ("AGENT".to_string(), number(SENDER_AGENT)),
                ])
                .collect(),
        ),
    })
}

/// What a kind's descriptor is built from: its serde trace, the named
/// fields of the mapping (by their dotted path) and whether arrays are cut
/// to `dim`.
struct Shape<'a> {
    registry: &'a Registry,
    named: &'a [(&'a str, Named)],
    sized: bool,
}

impl Shape<'_> {
    /// The descriptor of struct `name` at dotted path `prefix` (`""` for the
    /// payload, `"header."` for its header), whose full protobuf name is
    /// `full`; nested structs become nested message types.
    fn message(&self, name: &str, prefix: &str, full: &str) -> Result<DescriptorProto, String> {
        let Some(ContainerFormat::Struct(fields)) = self.registry.get(name) else {
            return Err(format!("`{name}` is not a struct"));
        };
        let mut out = DescriptorProto {
            name: Some(name.to_string()),
            ..Default::default()
        };
        let mut number = 0;
        let mut dim_seen = false;
        for f in fields {
            if f.name.starts_with('_') {
                // Padding: always 0, no information; no field.
                continue;
            }
            number += 1;
            let mut field = FieldDescriptorProto {
                name: Some(f.name.clone()),
                number: Some(number),
                json_name: Some(f.name.clone()),
                ..Default::default()
            };
            let path = format!("{prefix}{}", f.name);
            let named = self.named.iter().find(|(p, _)| *p == path).map(|(_, n)| *n);
            match (&f.value, named) {
                (Format::TypeName(inner), _) => {
                    let nested_full = format!("{full}.{inner}");
                    if !out.nested_type.iter().any(|n| n.name() == inner) {
                        out.nested_type.push(self.message(
                            inner,
                            &format!("{path}."),
                            &nested_full,
                        )?);
                    }
                    field.set_type(Type::Message);
                    field.set_label(Label::Optional);
                    field.type_name = Some(nested_full);
                }
                (Format::U32, Some(named)) => {
                    field.set_label(Label::Optional);
                    match enum_of(named) {
                        None => field.set_type(Type::Bool),
                        Some((enum_name, values)) => {
                            if !out.enum_type.iter().any(|e| e.name() == enum_name) {
                                out.enum_type.push(enum_descriptor(enum_name, values));
                            }
                            field.set_type(Type::Enum);
                            field.type_name = Some(format!("{full}.{enum_name}"));
                        }
                    }
                }
                (_, Some(_)) => return Err(format!("named field `{path}` is not a u32")),
                (v, None) => {
                    let (ty, repeated) = scalar(v)?;
                    if repeated && self.sized && !dim_seen {
                        return Err(format!(
                            "array `{path}` has no `{DIM_FIELD}` before it to size it"
                        ));
                    }
                    field.set_type(ty);
                    field.set_label(if repeated {
                        Label::Repeated
                    } else {
                        Label::Optional
                    });
                }
            }
            dim_seen |= f.name == DIM_FIELD;
            out.field.push(field);
        }
        Ok(out)
    }
}

fn enum_descriptor(name: &str, values: Vec<(String, i32)>) -> EnumDescriptorProto {
    EnumDescriptorProto {
        name: Some(name.to_string()),
        value: values
            .into_iter()
            .map(|(name, number)| EnumValueDescriptorProto {
                name: Some(name),
                number: Some(number),
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost_reflect::Kind as PKind;

    #[test]
    fn every_kind_has_a_self_contained_descriptor_traced_from_its_type() {
        for &k in Kind::ALL {
            let d = k.proto_descriptor().expect("descriptor");
            assert_eq!(d.full_name(), k.proto_name());
            let header = d.get_field_by_name("header").expect("header");
            let PKind::Message(h) = header.kind() else {
                panic!("{k:?}: header is not a message")
            };
            assert_eq!(h.full_name(), format!("{}.Header", k.proto_name()));
            let names: Vec<String> = h.fields().map(|f| f.name().to_string()).collect();
            assert_eq!(names, ["run", "episode", "step", "leg", "sender", "seq"]);
            // The traced field list, padding aside, in the same order.
            let traced: Vec<String> = k
                .fields()
                .expect("fields")
                .iter()
                .filter(|f| !f.is_padding() && f.path.len() == 1)
                .map(|f| f.name())
                .collect();
            let ours: Vec<String> = d
                .fields()
                .filter(|f| f.name() != "header")
                .map(|f| f.name().to_string())
                .collect();
            assert_eq!(ours, traced, "{k:?}");
            // The schema data is a FileDescriptorSet of one file.
            let set = FileDescriptorSet::decode(k.proto_schema().expect("schema")).expect("set");
            assert_eq!(set.file.len(), 1);
        }
        let h = Kind::Handover.proto_descriptor().expect("handover");
        let cov = h.get_field_by_name("cov").expect("cov");
        assert!(cov.is_list() && cov.is_packed());
        assert_eq!(cov.kind(), PKind::Double);
    }

    /// The enum values of field `path` (`header.sender`) of `kind` in `mapping`.
    fn enum_values(kind: Kind, mapping: ProtoMapping, path: &str) -> Option<Vec<(String, i32)>> {
        let mut desc = kind.proto_descriptor_in(mapping).expect("descriptor");
        let mut parts = path.split('.').peekable();
        while let Some(part) = parts.next() {
            let field = desc.get_field_by_name(part)?;
            match (field.kind(), parts.peek()) {
                (PKind::Message(m), Some(_)) => desc = m,
                (PKind::Enum(e), None) => {
                    return Some(e.values().map(|v| (v.name().into(), v.number())).collect());
                }
                _ => return None,
            }
        }
        None
    }

    #[test]
    fn every_named_field_is_an_enum_or_a_bool_in_format_6_and_a_number_in_format_5() {
        let typed = ProtoMapping::Typed;
        let outcome = enum_values(Kind::Outcome, typed, "outcome").expect("enum");
        assert_eq!(
            outcome,
            [
                ("OUTCOME_UNSPECIFIED".into(), 0),
                ("TARGET".into(), 1),
                ("COLLISION".into(), 2),
                ("FREE".into(), 3)
            ]
        );
        let sender = enum_values(Kind::Measurement, typed, "header.sender").expect("enum");
        assert_eq!(sender.len(), NAMED_SENSORS as usize + 2);
        assert!(sender.contains(&("SENSOR_0".into(), 0)));
        assert!(sender.contains(&("SENSOR_63".into(), 63)));
        // The u32 sentinels, as protobuf's int32 enum numbers.
        assert!(sender.contains(&("COORDINATOR".into(), 0xFFFF_0000_u32 as i32)));
        assert!(sender.contains(&("AGENT".into(), 0xFFFF_0001_u32 as i32)));
        let dead = enum_values(Kind::Outcome, typed, "dead_sensor").expect("enum");
        assert!(dead.contains(&("NONE".into(), -1)));
        let control = enum_values(Kind::Control, typed, "kind").expect("enum");
        assert!(control.contains(&("START".into(), 1)) && control.contains(&("STOP".into(), 2)));
        let threshold = enum_values(Kind::Threshold, typed, "kind").expect("enum");
        assert!(threshold.contains(&("CLOSE".into(), 2)));
        assert!(enum_values(Kind::Threshold, typed, "sensor").is_some());
        // Every catalogue-named field of every kind: an enum or a bool.
        for &k in Kind::ALL {
            let d = k.proto_descriptor_in(typed).expect("descriptor");
            for (path, named) in HEADER_NAMES.iter().chain(k.named_fields()) {
                let found = enum_values(k, typed, path);
                match named {
                    Named::Flag => {
                        let f = d.get_field_by_name(path).expect("flag");
                        assert_eq!(f.kind(), PKind::Bool, "{k:?} {path}");
                    }
                    _ => assert!(found.is_some(), "{k:?} {path}"),
                }
            }
            // Format 5: no enum and no bool anywhere.
            let plain = k.proto_descriptor_in(ProtoMapping::Plain).expect("plain");
            let h = plain.get_field_by_name("header").expect("header");
            let PKind::Message(h) = h.kind() else {
                panic!("header")
            };
            for f in plain.fields().chain(h.fields()) {
                assert!(
                    !matches!(f.kind(), PKind::Enum(_) | PKind::Bool),
                    "{k:?} {}",
                    f.name()
                );
            }
        }
        assert_eq!(
            enum_values(Kind::Outcome, ProtoMapping::Plain, "outcome"),
            None
        );
    }
}
