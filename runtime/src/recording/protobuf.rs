//! The protobuf encoding of a payload (recording formats 5 and 6, one
//! [`ProtoMapping`] each): the payload's serde implementation fills a
//! `prost_reflect::DynamicMessage` of the kind's descriptor (`wire::proto`),
//! which prost encodes; decoding is the reverse, then the payload is encoded
//! again and must give the same bytes.
//!
//! The descriptor decides each field's form: a `u32` whose field is an enum
//! is written as that enum's number (the same 32 bits), one whose field is a
//! `bool` as `false`/`true` (a flag other than 0 or 1 is refused); in
//! [`ProtoMapping::Typed`] an array holds only its first `dim` entries per
//! axis, the rest must be 0 (else refused) and are put back as 0 on reading.
//!
//! That last check makes the decoder exactly as strict as the old
//! fixed-size one: protobuf itself accepts anything that parses (missing
//! fields are 0, unknown fields are kept, fields may come in any order or
//! twice), but a recording holds only what [`encode`] writes, so any other
//! bytes — garbage, a forged field, a vector of the wrong length — are
//! refused, and what is accepted round-trips bit for bit.

use crate::wire::Message;
pub use crate::wire::proto::ProtoMapping;
use prost::Message as _;
use prost_reflect::{DynamicMessage, Kind as PKind, MessageDescriptor, ReflectMessage, Value};
use serde::ser::{self, Impossible, Serialize};

mod de;
use de::MessageDe;

/// Why a payload does not map onto its protobuf message.
#[derive(Debug)]
pub struct ProtoError(pub String);

impl std::fmt::Display for ProtoError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ProtoError {}

impl ser::Error for ProtoError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        Self(msg.to_string())
    }
}

impl serde::de::Error for ProtoError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        Self(msg.to_string())
    }
}

fn err<T>(m: impl Into<String>) -> Result<T, ProtoError> {
    Err(ProtoError(m.into()))
}

/// Encode a payload as its kind's protobuf message in `mapping`.
pub fn encode<T: Message>(payload: &T, mapping: ProtoMapping) -> Result<Vec<u8>, ProtoError> {
    let desc = T::KIND.proto_descriptor_in(mapping).map_err(ProtoError)?;
    let msg = payload.serialize(MessageSer {
        desc,
        sized: mapping.sized_arrays(),
    })?;
    Ok(msg.encode_to_vec())
}

/// Decode a payload written by [`encode`] in `mapping`; anything else is refused.
pub fn decode<T: Message>(data: &[u8], mapping: ProtoMapping) -> Result<T, ProtoError> {
    let desc = T::KIND.proto_descriptor_in(mapping).map_err(ProtoError)?;
    let msg = DynamicMessage::decode(desc, data).map_err(|e| ProtoError(e.to_string()))?;
    let v = T::deserialize(MessageDe {
        msg: &msg,
        sized: mapping.sized_arrays(),
    })?;
    if encode(&v, mapping)? != data {
        return err(
            "not the canonical encoding of its message (unknown, repeated or misordered \
             fields, or an array of the wrong length)",
        );
    }
    Ok(v)
}

// ---- payload → DynamicMessage -------------------------------------------

/// Serializes a struct into a message of `desc`; `sized`: arrays cut to `dim`.
struct MessageSer {
    desc: MessageDescriptor,
    sized: bool,
}

/// Serializes one field's value (a scalar, an array, or a nested struct
/// when `nested` is its message type) into a `Value`; an array keeps its
/// first `used` entries per axis (all of them when `None`).
struct ValueSer {
    nested: Option<MessageDescriptor>,
    used: Option<usize>,
    sized: bool,
}

struct StructSer {
    msg: DynamicMessage,
    sized: bool,
    /// The struct's `dim`, once serialized (it precedes every array).
    dim: Option<usize>,
}

/// A fixed array's entries, nested arrays flattened (row-major), the first
/// `used` per axis kept.
struct ListSer {
    items: Vec<Value>,
    used: Option<usize>,
    /// Entries (rows, for a matrix) seen so far.
    seen: usize,
}

/// +0 of any scalar (what an unused array entry must be).
fn is_plus_zero(v: &Value) -> bool {
    match v {
        Value::F64(x) => x.to_bits() == 0,
        Value::F32(x) => x.to_bits() == 0,
        Value::U32(x) => *x == 0,
        Value::U64(x) => *x == 0,
        Value::I32(x) => *x == 0,
        Value::I64(x) => *x == 0,
        Value::Bool(b) => !b,
        _ => false,
    }
}

/// The generic `Serializer` methods no payload uses: refused.
macro_rules! unsupported_generic_ser {
    ($ok:ty) => {
        fn serialize_some<V: ?Sized + Serialize>(self, _: &V) -> Result<$ok, ProtoError> {
            err("unsupported in a payload: Option")
        }
        fn serialize_newtype_struct<V: ?Sized + Serialize>(
            self,
            _: &'static str,
            _: &V,
        ) -> Result<$ok, ProtoError> {
            err("unsupported in a payload: newtype struct")
        }
        fn serialize_newtype_variant<V: ?Sized + Serialize>(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
            _: &V,
        ) -> Result<$ok, ProtoError> {
            err("unsupported in a payload: enum")
        }
    };
}

macro_rules! unsupported_ser {
    ($($m:ident($($t:ty),*) -> $ok:ty;)*) => {
        $(fn $m(self, $(_: $t),*) -> Result<$ok, ProtoError> {
            err(concat!("unsupported in a payload: ", stringify!($m)))
        })*
    };
}

impl ser::Serializer for MessageSer {
    type Ok = DynamicMessage;
    type Error = ProtoError;
    type SerializeSeq = Impossible<DynamicMessage, ProtoError>;
    type SerializeTuple = Impossible<DynamicMessage, ProtoError>;
    type SerializeTupleStruct = Impossible<DynamicMessage, ProtoError>;
    type SerializeTupleVariant = Impossible<DynamicMessage, ProtoError>;
    type SerializeMap = Impossible<DynamicMessage, ProtoError>;
    type SerializeStruct = StructSer;
    type SerializeStructVariant = Impossible<DynamicMessage, ProtoError>;

    fn serialize_struct(self, _: &'static str, _: usize) -> Result<StructSer, ProtoError> {
        Ok(StructSer {
            msg: DynamicMessage::new(self.desc),
            sized: self.sized,
            dim: None,
        })
    }

    unsupported_ser! {
        serialize_bool(bool) -> DynamicMessage;
        serialize_i8(i8) -> DynamicMessage;
        serialize_i16(i16) -> DynamicMessage;
        serialize_i32(i32) -> DynamicMessage;
        serialize_i64(i64) -> DynamicMessage;
        serialize_u8(u8) -> DynamicMessage;
        serialize_u16(u16) -> DynamicMessage;
        serialize_u32(u32) -> DynamicMessage;
        serialize_u64(u64) -> DynamicMessage;
        serialize_f32(f32) -> DynamicMessage;
        serialize_f64(f64) -> DynamicMessage;
        serialize_char(char) -> DynamicMessage;
        serialize_str(&str) -> DynamicMessage;
        serialize_bytes(&[u8]) -> DynamicMessage;
        serialize_none() -> DynamicMessage;
        serialize_unit() -> DynamicMessage;
        serialize_unit_struct(&'static str) -> DynamicMessage;
        serialize_unit_variant(&'static str, u32, &'static str) -> DynamicMessage;
        serialize_seq(Option<usize>) -> Self::SerializeSeq;
        serialize_tuple(usize) -> Self::SerializeTuple;
        serialize_tuple_struct(&'static str, usize) -> Self::SerializeTupleStruct;
        serialize_tuple_variant(&'static str, u32, &'static str, usize) -> Self::SerializeTupleVariant;
        serialize_map(Option<usize>) -> Self::SerializeMap;
        serialize_struct_variant(&'static str, u32, &'static str, usize) -> Self::SerializeStructVariant;
    }

    unsupported_generic_ser!(DynamicMessage);
}

impl ser::SerializeStruct for StructSer {
    type Ok = DynamicMessage;
    type Error = ProtoError;

    fn serialize_field<V: ?Sized + Serialize>(
        &mut self,
        key: &'static str,
        value: &V,
    ) -> Result<(), ProtoError> {
        if key.starts_with('_') {
            // Padding has no field; a non-zero one could not be read back.
            let v = value.serialize(ValueSer {
                nested: None,
                used: None,
                sized: self.sized,
            })?;
            return match v {
                Value::U32(0) | Value::U64(0) => Ok(()),
                other => err(format!("padding field `{key}` is {other:?}, not 0")),
            };
        }
        let Some(field) = self.msg.descriptor().get_field_by_name(key) else {
            return err(format!("no field `{key}` in the schema"));
        };
        let nested = match field.kind() {
            PKind::Message(m) => Some(m),
            _ => None,
        };
        let used = match (self.sized, field.is_list()) {
            (true, true) => Some(self.dim.ok_or_else(|| {
                ProtoError(format!(
                    "array `{key}` before `{}`",
                    crate::wire::proto::DIM_FIELD
                ))
            })?),
            _ => None,
        };
        let v = value.serialize(ValueSer {
            nested,
            used,
            sized: self.sized,
        })?;
        if key == crate::wire::proto::DIM_FIELD
            && let Value::U32(d) = v
        {
            self.dim = usize::try_from(d).ok();
        }
        // The descriptor's form of a u32: an enum's number (the same 32
        // bits) or a flag's bool.
        let v = match (field.kind(), v) {
            (PKind::Enum(_), Value::U32(x)) => {
                Value::EnumNumber(i32::from_ne_bytes(x.to_ne_bytes()))
            }
            (PKind::Bool, Value::U32(0)) => Value::Bool(false),
            (PKind::Bool, Value::U32(1)) => Value::Bool(true),
            (PKind::Bool, Value::U32(x)) => {
                return err(format!("flag `{key}` is {x}, neither 0 nor 1"));
            }
            (_, v) => v,
        };
        // proto3 leaves a zero scalar out, and −0 == 0: it would come back
        // as +0. Refused rather than changed (no payload holds one).
        if matches!(v, Value::F64(x) if x == 0.0 && x.is_sign_negative())
            || matches!(v, Value::F32(x) if x == 0.0 && x.is_sign_negative())
        {
            return err(format!("field `{key}` is −0, which proto3 cannot keep"));
        }
        self.msg
            .try_set_field(&field, v)
            .map_err(|e| ProtoError(format!("field `{key}`: {e}")))
    }

    fn end(self) -> Result<DynamicMessage, ProtoError> {
        Ok(self.msg)
    }
}

impl ser::Serializer for ValueSer {
    type Ok = Value;
    type Error = ProtoError;
    type SerializeSeq = Impossible<Value, ProtoError>;
    type SerializeTuple = ListSer;
    type SerializeTupleStruct = Impossible<Value, ProtoError>;
    type SerializeTupleVariant = Impossible<Value, ProtoError>;
    type SerializeMap = Impossible<Value, ProtoError>;
    type SerializeStruct = NestedSer;
    type SerializeStructVariant = Impossible<Value, ProtoError>;

    fn serialize_bool(self, v: bool) -> Result<Value, ProtoError> {
        Ok(Value::Bool(v))
    }
    fn serialize_u8(self, v: u8) -> Result<Value, ProtoError> {
        Ok(Value::U32(v.into()))
    }
    fn serialize_u16(self, v: u16) -> Result<Value, ProtoError> {
        Ok(Value::U32(v.into()))
    }
    fn serialize_u32(self, v: u32) -> Result<Value, ProtoError> {
        Ok(Value::U32(v))
    }
    fn serialize_u64(self, v: u64) -> Result<Value, ProtoError> {
        Ok(Value::U64(v))
    }
    fn serialize_i32(self, v: i32) -> Result<Value, ProtoError> {
        Ok(Value::I32(v))
    }
    fn serialize_i64(self, v: i64) -> Result<Value, ProtoError> {
        Ok(Value::I64(v))
    }
    fn serialize_f32(self, v: f32) -> Result<Value, ProtoError> {
        Ok(Value::F32(v))
    }
    fn serialize_f64(self, v: f64) -> Result<Value, ProtoError> {
        Ok(Value::F64(v))
    }
    fn serialize_tuple(self, len: usize) -> Result<ListSer, ProtoError> {
        Ok(ListSer {
            items: Vec::with_capacity(len),
            used: self.used,
            seen: 0,
        })
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<NestedSer, ProtoError> {
        match self.nested {
            Some(desc) => Ok(NestedSer(StructSer {
                msg: DynamicMessage::new(desc),
                sized: self.sized,
                dim: None,
            })),
            None => err("a nested struct where the schema has no message"),
        }
    }

    unsupported_ser! {
        serialize_i8(i8) -> Value;
        serialize_i16(i16) -> Value;
        serialize_char(char) -> Value;
        serialize_str(&str) -> Value;
        serialize_bytes(&[u8]) -> Value;
        serialize_none() -> Value;
        serialize_unit() -> Value;
        serialize_unit_struct(&'static str) -> Value;
        serialize_unit_variant(&'static str, u32, &'static str) -> Value;
        serialize_seq(Option<usize>) -> Self::SerializeSeq;
        serialize_tuple_struct(&'static str, usize) -> Self::SerializeTupleStruct;
        serialize_tuple_variant(&'static str, u32, &'static str, usize) -> Self::SerializeTupleVariant;
        serialize_map(Option<usize>) -> Self::SerializeMap;
        serialize_struct_variant(&'static str, u32, &'static str, usize) -> Self::SerializeStructVariant;
    }

    unsupported_generic_ser!(Value);
}

/// A nested struct (the header) as a message value.
struct NestedSer(StructSer);

impl ser::SerializeStruct for NestedSer {
    type Ok = Value;
    type Error = ProtoError;
    fn serialize_field<V: ?Sized + Serialize>(
        &mut self,
        key: &'static str,
        value: &V,
    ) -> Result<(), ProtoError> {
        ser::SerializeStruct::serialize_field(&mut self.0, key, value)
    }
    fn end(self) -> Result<Value, ProtoError> {
        Ok(Value::Message(self.0.msg))
    }
}

impl ser::SerializeTuple for ListSer {
    type Ok = Value;
    type Error = ProtoError;
    fn serialize_element<V: ?Sized + Serialize>(&mut self, value: &V) -> Result<(), ProtoError> {
        let kept = self.used.is_none_or(|d| self.seen < d);
        self.seen += 1;
        let v = value.serialize(ValueSer {
            nested: None,
            used: self.used,
            sized: false,
        })?;
        // Past `dim` nothing is written, so only +0 reads back the same.
        let unused_ok = |v: &Value| match v {
            Value::List(row) => row.iter().all(is_plus_zero),
            v => is_plus_zero(v),
        };
        if !kept {
            return match unused_ok(&v) {
                true => Ok(()),
                false => err(format!(
                    "an array entry past dim {} is not 0",
                    self.used.unwrap_or_default()
                )),
            };
        }
        match v {
            // A row of a matrix: its entries follow the previous row's.
            Value::List(row) => self.items.extend(row),
            Value::Message(_) => return err("an array of structs"),
            v => self.items.push(v),
        }
        Ok(())
    }
    fn end(self) -> Result<Value, ProtoError> {
        if let Some(d) = self.used
            && d > self.seen
        {
            return err(format!("dim {d} exceeds the array's {} entries", self.seen));
        }
        Ok(Value::List(self.items))
    }
}

#[cfg(test)]
mod tests;
