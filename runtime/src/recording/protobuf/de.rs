//! A payload from a `DynamicMessage`: the payload's `Deserialize` reads its
//! fields in order, each from the message field of its name (padding: 0;
//! an enum's number and a flag's bool as the `u32` they stand for), arrays
//! from the flat repeated field in row-major order; with `sized`, the
//! field holds the first `dim` entries per axis and the rest are 0.

use super::{ProtoError, err};
use prost_reflect::{DynamicMessage, ReflectMessage, Value};
use serde::de::{self, DeserializeSeed, IntoDeserializer, SeqAccess, Visitor};

/// Deserializes a struct from a message; `sized`: arrays hold `dim` entries per axis.
pub(super) struct MessageDe<'a> {
    pub(super) msg: &'a DynamicMessage,
    pub(super) sized: bool,
}

macro_rules! only_struct {
    ($($m:ident)*) => {
        $(fn $m<V: Visitor<'de>>(self, _: V) -> Result<V::Value, ProtoError> {
            err(concat!("a payload field is not a struct: ", stringify!($m)))
        })*
    };
}

impl<'de> de::Deserializer<'de> for MessageDe<'_> {
    type Error = ProtoError;

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, ProtoError> {
        visitor.visit_seq(Fields {
            msg: self.msg,
            sized: self.sized,
            fields,
            at: 0,
        })
    }

    only_struct! {
        deserialize_any deserialize_bool deserialize_i8 deserialize_i16 deserialize_i32
        deserialize_i64 deserialize_u8 deserialize_u16 deserialize_u32 deserialize_u64
        deserialize_f32 deserialize_f64 deserialize_char deserialize_str deserialize_string
        deserialize_bytes deserialize_byte_buf deserialize_option deserialize_unit deserialize_seq
        deserialize_map deserialize_identifier deserialize_ignored_any
    }

    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("a unit struct")
    }
    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("a newtype struct")
    }
    fn deserialize_tuple<V: Visitor<'de>>(self, _: usize, _: V) -> Result<V::Value, ProtoError> {
        err("a tuple")
    }
    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: usize,
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("a tuple struct")
    }
    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("an enum")
    }
}

/// The fields of a struct in order, each from the message field of its name
/// (padding: 0).
struct Fields<'a> {
    msg: &'a DynamicMessage,
    sized: bool,
    fields: &'static [&'static str],
    at: usize,
}

impl<'de> SeqAccess<'de> for Fields<'_> {
    type Error = ProtoError;

    fn next_element_seed<S: DeserializeSeed<'de>>(
        &mut self,
        seed: S,
    ) -> Result<Option<S::Value>, ProtoError> {
        let Some(&name) = self.fields.get(self.at) else {
            return Ok(None);
        };
        self.at += 1;
        if name.starts_with('_') {
            return seed.deserialize(0u32.into_deserializer()).map(Some);
        }
        let Some(field) = self.msg.descriptor().get_field_by_name(name) else {
            return err(format!("no field `{name}` in the schema"));
        };
        let value = self.msg.get_field(&field);
        let v = match value.as_ref() {
            Value::Message(m) => seed.deserialize(MessageDe {
                msg: m,
                sized: self.sized,
            }),
            Value::List(items) => {
                let used = match self.sized {
                    true => Some(self.dim()?),
                    false => None,
                };
                let mut flat = Flat {
                    items,
                    at: 0,
                    used,
                    unused: false,
                };
                let v = seed.deserialize(&mut flat)?;
                if flat.at != items.len() {
                    return err(format!(
                        "field `{name}` holds {} values, the payload {}",
                        items.len(),
                        flat.at
                    ));
                }
                Ok(v)
            }
            scalar => seed.deserialize(&mut Flat {
                items: std::slice::from_ref(scalar),
                at: 0,
                used: None,
                unused: false,
            }),
        };
        v.map_err(|e| ProtoError(format!("field `{name}`: {e}")))
            .map(Some)
    }
}

impl Fields<'_> {
    /// The message's `dim`: how many entries per axis its arrays hold.
    fn dim(&self) -> Result<usize, ProtoError> {
        let dim = crate::wire::proto::DIM_FIELD;
        match self.msg.get_field_by_name(dim).as_deref() {
            Some(Value::U32(d)) => usize::try_from(*d).map_err(|e| ProtoError(e.to_string())),
            _ => err(format!("an array in a message without `{dim}`")),
        }
    }
}

/// Scalars handed out in order: a scalar field (one value), or an array
/// (nested arrays take their rows in turn from the same flat list); an
/// array entry past `used` (per axis) is not in the list and reads as 0.
struct Flat<'a> {
    items: &'a [Value],
    at: usize,
    used: Option<usize>,
    /// The entry being read is past `used`.
    unused: bool,
}

impl Flat<'_> {
    fn next(&mut self) -> Result<&Value, ProtoError> {
        let v = self
            .items
            .get(self.at)
            .ok_or_else(|| ProtoError(format!("only {} values", self.items.len())))?;
        self.at += 1;
        Ok(v)
    }
}

macro_rules! scalar_de {
    ($($m:ident => $visit:ident($zero:expr): $($pat:pat => $e:expr),+;)*) => {
        $(fn $m<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ProtoError> {
            if self.unused {
                return visitor.$visit($zero);
            }
            match self.next()? {
                $($pat => visitor.$visit($e),)+
                other => err(format!("{other:?} where {} was expected", stringify!($visit))),
            }
        })*
    };
}

impl<'de> de::Deserializer<'de> for &mut Flat<'_> {
    type Error = ProtoError;

    scalar_de! {
        deserialize_bool => visit_bool(false): Value::Bool(v) => *v;
        deserialize_u8 => visit_u32(0): Value::U32(v) => *v;
        deserialize_u16 => visit_u32(0): Value::U32(v) => *v;
        deserialize_u32 => visit_u32(0):
            Value::U32(v) => *v,
            Value::EnumNumber(v) => u32::from_ne_bytes(v.to_ne_bytes()),
            Value::Bool(v) => u32::from(*v);
        deserialize_u64 => visit_u64(0): Value::U64(v) => *v;
        deserialize_i32 => visit_i32(0): Value::I32(v) => *v;
        deserialize_i64 => visit_i64(0): Value::I64(v) => *v;
        deserialize_f32 => visit_f32(0.0): Value::F32(v) => *v;
        deserialize_f64 => visit_f64(0.0): Value::F64(v) => *v;
    }

    fn deserialize_tuple<V: Visitor<'de>>(
        self,
        len: usize,
        visitor: V,
    ) -> Result<V::Value, ProtoError> {
        let outer_unused = self.unused;
        visitor.visit_seq(Elements {
            flat: self,
            len,
            seen: 0,
            outer_unused,
        })
    }

    only_struct! {
        deserialize_any deserialize_i8 deserialize_i16 deserialize_char deserialize_str
        deserialize_string deserialize_bytes deserialize_byte_buf deserialize_option
        deserialize_unit deserialize_seq deserialize_map deserialize_identifier
        deserialize_ignored_any
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("a struct where the schema has a scalar")
    }
    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("a unit struct")
    }
    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("a newtype struct")
    }
    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: usize,
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("a tuple struct")
    }
    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, ProtoError> {
        err("an enum")
    }
}

/// `len` elements of an array, from the shared flat list (those past
/// `used`, or inside an unused row, read as 0).
struct Elements<'a, 'b> {
    flat: &'a mut Flat<'b>,
    len: usize,
    seen: usize,
    /// This whole array is an unused row.
    outer_unused: bool,
}

impl<'de> SeqAccess<'de> for Elements<'_, '_> {
    type Error = ProtoError;
    fn next_element_seed<S: DeserializeSeed<'de>>(
        &mut self,
        seed: S,
    ) -> Result<Option<S::Value>, ProtoError> {
        if self.len == 0 {
            return Ok(None);
        }
        self.len -= 1;
        self.flat.unused = self.outer_unused || self.flat.used.is_some_and(|d| self.seen >= d);
        self.seen += 1;
        let v = seed.deserialize(&mut *self.flat);
        self.flat.unused = self.outer_unused;
        v.map(Some)
    }
    fn size_hint(&self) -> Option<usize> {
        Some(self.len)
    }
}
