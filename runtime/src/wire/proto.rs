//! The protobuf schema of every payload, derived from the payload types
//! themselves: each message's descriptor is built from the type's serde
//! implementation (the same trace as [`super::schema`]), so there is no
//! `.proto` file to drift from the structs.
//!
//! The mapping (recording format 5, `crate::recording`):
//! * one protobuf message per kind, `etp.<Kind>` (proto3), in a file of its
//!   own, `etp/<Kind>.proto`; a nested struct (the header) is a nested
//!   message type (`etp.<Kind>.Header`), so each kind's file is
//!   self-contained: a channel's schema is one `FileDescriptorSet` of one file;
//! * fields numbered 1, 2, … in the struct's order; padding fields
//!   (`_pad`) have no field (they are always 0);
//! * `u8`/`u16`/`u32` → `uint32`, `u64` → `uint64`, `i32` → `int32`, `i64` →
//!   `int64`, `f32` → `float`, `f64` → `double`, `bool` → `bool`;
//! * a fixed array (also nested: a matrix) → a packed `repeated` field of its
//!   scalars in row-major order, every entry written (a vector of 6 has 6
//!   values, a 6 × 6 matrix 36).
//!
//! Field numbers follow the struct's order: a change of a payload struct
//! changes its schema, which is why the recording's format version moves
//! with it (each file carries its own schemas, so other readers never
//! misread an older file).

use super::catalogue::{Kind, KindVisitor, Message};
use prost::Message as _;
use prost_reflect::{DescriptorPool, MessageDescriptor};
use prost_types::field_descriptor_proto::{Label, Type};
use prost_types::{DescriptorProto, FieldDescriptorProto, FileDescriptorProto, FileDescriptorSet};
use serde_reflection::{ContainerFormat, Format, Registry};
use std::collections::BTreeMap;
use std::sync::OnceLock;

/// The protobuf package of every payload.
pub const PACKAGE: &str = "etp";

/// The descriptors of every kind, built once.
struct Schemas {
    /// Kind → (its message descriptor, its `FileDescriptorSet` bytes).
    by_kind: BTreeMap<Kind, (MessageDescriptor, Vec<u8>)>,
}

fn schemas() -> Result<&'static Schemas, String> {
    static SCHEMAS: OnceLock<Result<Schemas, String>> = OnceLock::new();
    SCHEMAS
        .get_or_init(|| {
            let mut by_kind = BTreeMap::new();
            for &kind in Kind::ALL {
                let file = kind.visit(FileOf)?;
                let set = FileDescriptorSet { file: vec![file] };
                let bytes = set.encode_to_vec();
                // One pool per kind: every file defines its own `Header`.
                let pool = DescriptorPool::decode(bytes.as_slice())
                    .map_err(|e| format!("{kind:?}: {e}"))?;
                let desc = pool
                    .get_message_by_name(&kind.proto_name())
                    .ok_or_else(|| format!("{kind:?}: no message {}", kind.proto_name()))?;
                by_kind.insert(kind, (desc, bytes));
            }
            Ok(Schemas { by_kind })
        })
        .as_ref()
        .map_err(Clone::clone)
}

impl Kind {
    /// The protobuf message name, `etp.<Kind>` (the schema name of a
    /// format-5 recording's channel).
    pub fn proto_name(self) -> String {
        format!(
            "{PACKAGE}.{}",
            self.schema_name().trim_start_matches("etp::")
        )
    }

    /// The message descriptor of this kind's payload.
    pub fn proto_descriptor(self) -> Result<MessageDescriptor, String> {
        let s = schemas()?;
        s.by_kind
            .get(&self)
            .map(|(d, _)| d.clone())
            .ok_or_else(|| format!("{self:?}: no descriptor"))
    }

    /// The schema data of a format-5 channel: a serialized
    /// `google.protobuf.FileDescriptorSet` holding this kind's one file.
    pub fn proto_schema(self) -> Result<&'static [u8], String> {
        let s = schemas()?;
        s.by_kind
            .get(&self)
            .map(|(_, b)| b.as_slice())
            .ok_or_else(|| format!("{self:?}: no descriptor"))
    }
}

struct FileOf;

impl KindVisitor for FileOf {
    type Out = Result<FileDescriptorProto, String>;
    fn visit<T: Message>(self) -> Self::Out {
        let (registry, name) = super::schema::traced::<T>()?;
        let full = format!(".{PACKAGE}.{name}");
        let message = message(&registry, &name, &full)?;
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

/// The descriptor of struct `name` of `registry`, whose full protobuf name
/// is `full`; nested structs become nested message types.
fn message(registry: &Registry, name: &str, full: &str) -> Result<DescriptorProto, String> {
    let Some(ContainerFormat::Struct(fields)) = registry.get(name) else {
        return Err(format!("`{name}` is not a struct"));
    };
    let mut out = DescriptorProto {
        name: Some(name.to_string()),
        ..Default::default()
    };
    let mut number = 0;
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
        match &f.value {
            Format::TypeName(inner) => {
                let nested_full = format!("{full}.{inner}");
                if !out.nested_type.iter().any(|n| n.name() == inner) {
                    out.nested_type
                        .push(message(registry, inner, &nested_full)?);
                }
                field.set_type(Type::Message);
                field.set_label(Label::Optional);
                field.type_name = Some(nested_full);
            }
            v => {
                let (ty, repeated) = scalar(v)?;
                field.set_type(ty);
                field.set_label(if repeated {
                    Label::Repeated
                } else {
                    Label::Optional
                });
            }
        }
        out.field.push(field);
    }
    Ok(out)
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
}
