//! The schema of a payload as a recording shows it: its fields in wire
//! order traced from the type's serde implementation (so the text cannot
//! drift from the struct), their scalar types and shapes, the Python
//! `struct` format, and the schema text of a recording's channel.

use super::catalogue::{
    HEADER_CODES, HEADER_NAMES, Kind, KindVisitor, Message, Named, PAYLOAD_ENCODING,
};

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

/// The serde trace of a payload type: its registry of containers and its
/// own (unqualified) name in it — what the schema text here and the
/// protobuf descriptors of `wire::proto` are both made from.
pub(super) fn traced<T: Message>() -> Result<(serde_reflection::Registry, String), String> {
    let mut tracer = serde_reflection::Tracer::new(serde_reflection::TracerConfig::default());
    tracer.trace_simple_type::<T>().map_err(|e| e.to_string())?;
    let registry = tracer.registry().map_err(|e| e.to_string())?;
    let name = std::any::type_name::<T>()
        .rsplit("::")
        .next()
        .unwrap_or_default()
        .to_string();
    Ok((registry, name))
}

/// The fields of `T` in wire order, nested structs (the header) flattened;
/// traced from the type's serde implementation, so it is the layout bincode
/// writes.
fn fields_of<T: Message>() -> Result<Vec<Field>, String> {
    use serde_reflection::{ContainerFormat, Format};
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
    let (registry, name) = traced::<T>()?;
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
            Self::DriftQuantity => "loss | more_triggers | fewer_triggers",
            Self::Sensor => "the sensor's name",
            Self::SensorOrNone => "the sensor's name, or null for none",
            Self::Sender => "the sensor's name, coordinator or agent",
        }
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
}
