//! A recording's messages as flat, typed rows: the tables of `etp replay
//! --export` (CSV, JSON Lines) and the lines of `etp replay … cat`.
//!
//! Everything is derived from the catalogue: the columns are the traced
//! fields of each kind in wire order ([`Kind::fields`]), the header's fields
//! unprefixed (`episode`, `step`, …), padding dropped, arrays spread over one
//! column per entry (`y_0` … `y_5`, `cov_0_0` … `cov_5_5`), and the fields
//! the catalogue declares as codes shown by name ([`Kind::named_fields`]:
//! `outcome` = `target`, `sender` = a sensor's name, `coordinator` or
//! `agent`, flags as booleans). The first column is `log_time_ns`.

use super::{Kind, Recorded};
use crate::wire::catalogue::{HEADER_NAMES, Named};
use crate::wire::schema::{Field, Scalar};
use crate::wire::{
    ControlKind, DriftQuantity, MAX_DIM, OutcomeCode, SENDER_AGENT, SENDER_COORDINATOR,
    ThresholdKind,
};
use serde_json::Value;

/// The type of a column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ColumnType {
    /// Unsigned integer (u8 … u64).
    Uint,
    /// Signed integer.
    Int,
    /// Floating point (f64; NaN is written as an empty cell / null).
    Float,
    Bool,
    /// A name (string).
    Text,
}

/// One column of a table.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Column {
    pub name: String,
    #[serde(rename = "type")]
    pub ty: ColumnType,
}

/// One cell.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell {
    Uint(u64),
    Int(i64),
    Float(f64),
    Bool(bool),
    Text(String),
    Null,
}

impl Cell {
    /// The cell as JSON (a non-finite float as null).
    pub fn to_json(&self) -> Value {
        match self {
            Cell::Uint(x) => Value::from(*x),
            Cell::Int(x) => Value::from(*x),
            Cell::Float(x) if x.is_finite() => Value::from(*x),
            Cell::Bool(b) => Value::Bool(*b),
            Cell::Text(t) => Value::String(t.clone()),
            Cell::Float(_) | Cell::Null => Value::Null,
        }
    }

    /// The cell as CSV text (RFC 4180 quoting; null and NaN empty).
    pub fn to_csv(&self) -> String {
        match self {
            Cell::Uint(x) => x.to_string(),
            Cell::Int(x) => x.to_string(),
            Cell::Float(x) if x.is_finite() => format!("{x:?}"),
            Cell::Bool(b) => b.to_string(),
            Cell::Text(t) => csv_quote(t),
            Cell::Float(_) | Cell::Null => String::new(),
        }
    }
}

/// Quote a CSV field when it needs it.
pub fn csv_quote(t: &str) -> String {
    if t.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", t.replace('"', "\"\""))
    } else {
        t.to_string()
    }
}

/// How one column is read from a decoded payload.
#[derive(Debug, Clone)]
struct Source {
    /// Path in the payload's JSON (`header`, `episode`), then array indexes.
    path: Vec<String>,
    index: Vec<usize>,
    scalar: Scalar,
    named: Option<Named>,
    /// The run hash (`header.run`), written as decimal text.
    hash: bool,
}

/// The table layout of one kind.
#[derive(Debug, Clone)]
pub struct Table {
    pub kind: Kind,
    pub columns: Vec<Column>,
    sources: Vec<Source>,
}

/// Sensor names, for the named codes.
#[derive(Debug, Clone, Default)]
pub struct Names {
    pub sensors: Vec<String>,
}

impl Names {
    fn sensor(&self, i: u64) -> String {
        self.sensors
            .get(i as usize)
            .cloned()
            .unwrap_or_else(|| format!("sensor-{i}"))
    }
}

fn all_indexes(shape: &[usize]) -> Vec<Vec<usize>> {
    shape.iter().fold(vec![Vec::new()], |acc, &n| {
        acc.iter()
            .flat_map(|p| {
                (0..n).map(move |i| {
                    let mut q = p.clone();
                    q.push(i);
                    q
                })
            })
            .collect()
    })
}

fn column_type(scalar: Scalar, named: Option<Named>) -> ColumnType {
    match named {
        Some(Named::Flag) => ColumnType::Bool,
        Some(_) => ColumnType::Text,
        None => match scalar {
            Scalar::U8 | Scalar::U16 | Scalar::U32 | Scalar::U64 => ColumnType::Uint,
            Scalar::I32 | Scalar::I64 => ColumnType::Int,
            Scalar::F32 | Scalar::F64 => ColumnType::Float,
            Scalar::Bool => ColumnType::Bool,
        },
    }
}

impl Table {
    /// The layout of `kind`'s table. With `dim = Some(n)` (the scenario's
    /// state dimension), arrays keep their first n entries per axis (the
    /// entries past the dimension are always 0): `y_0 … y_{n-1}`,
    /// `cov_0_0 … cov_{n-1}_{n-1}`.
    pub fn of(kind: Kind, dim: Option<usize>) -> Result<Self, String> {
        let fields: Vec<Field> = kind.fields()?;
        let mut columns = vec![Column {
            name: "log_time_ns".into(),
            ty: ColumnType::Uint,
        }];
        let mut sources = Vec::new();
        for f in fields.iter().filter(|f| !f.is_padding()) {
            let full = f.name();
            let named = HEADER_NAMES
                .iter()
                .chain(kind.named_fields())
                .find(|(n, _)| *n == full)
                .map(|(_, n)| *n);
            // The header's fields are common to every table: unprefixed.
            let base = match f.path.first().map(String::as_str) {
                Some("header") => f.path[1..].join("_"),
                _ => f.path.join("_"),
            };
            let shape: Vec<usize> = f
                .shape
                .iter()
                .map(|&n| match dim {
                    Some(d) if n == MAX_DIM => d.min(n),
                    _ => n,
                })
                .collect();
            for index in all_indexes(&shape) {
                let mut name = base.clone();
                for i in &index {
                    name.push_str(&format!("_{i}"));
                }
                // The run's 64-bit hash as text: a JSON number past 2^53
                // loses digits in jq and JavaScript.
                let hash = full == "header.run";
                columns.push(Column {
                    name,
                    ty: if hash {
                        ColumnType::Text
                    } else {
                        column_type(f.scalar, named)
                    },
                });
                sources.push(Source {
                    path: f.path.clone(),
                    index,
                    scalar: f.scalar,
                    named,
                    hash,
                });
            }
        }
        Ok(Self {
            kind,
            columns,
            sources,
        })
    }

    /// The row of one decoded payload (same order as [`Table::columns`]).
    pub fn row(&self, log_time: u64, rec: &Recorded, names: &Names) -> Vec<Cell> {
        let v = rec.to_json();
        let mut out = Vec::with_capacity(self.columns.len());
        out.push(Cell::Uint(log_time));
        for s in &self.sources {
            let mut at = &v;
            for p in &s.path {
                at = at.get(p).unwrap_or(&Value::Null);
            }
            for i in &s.index {
                at = at.get(i).unwrap_or(&Value::Null);
            }
            out.push(cell(at, s, names));
        }
        out
    }

    /// A row as one JSON object text, keys in column order.
    pub fn json_line(&self, prefix: &[(&str, Value)], row: &[Cell]) -> String {
        let mut t = String::from("{");
        let quoted = |k: &str| Value::String(k.to_string()).to_string();
        let mut first = true;
        for (k, v) in prefix {
            if !first {
                t.push(',');
            }
            first = false;
            t.push_str(&format!("{}:{v}", quoted(k)));
        }
        for (c, x) in self.columns.iter().zip(row) {
            if !first {
                t.push(',');
            }
            first = false;
            t.push_str(&format!("{}:{}", quoted(&c.name), x.to_json()));
        }
        t.push('}');
        t
    }
}

fn cell(v: &Value, s: &Source, names: &Names) -> Cell {
    let code = v.as_u64();
    if s.hash {
        return code.map_or(Cell::Null, |x| Cell::Text(x.to_string()));
    }
    match (s.named, code) {
        (Some(Named::Flag), Some(c)) => Cell::Bool(c != 0),
        (Some(Named::ControlKind), Some(c)) => named_code(c, |c| {
            ControlKind::try_from(c).ok().map(|k| match k {
                ControlKind::Start => "start",
                ControlKind::Stop => "stop",
            })
        }),
        (Some(Named::ThresholdKind), Some(c)) => named_code(c, |c| {
            ThresholdKind::try_from(c).ok().map(|k| match k {
                ThresholdKind::Open => "open",
                ThresholdKind::Close => "close",
                ThresholdKind::Stop => "stop",
            })
        }),
        (Some(Named::Outcome), Some(c)) => {
            named_code(c, |c| OutcomeCode::try_from(c).ok().map(OutcomeCode::name))
        }
        (Some(Named::DriftQuantity), Some(c)) => named_code(c, |c| {
            DriftQuantity::try_from(c).ok().map(DriftQuantity::name)
        }),
        (Some(Named::Sensor), Some(c)) => Cell::Text(names.sensor(c)),
        (Some(Named::SensorOrNone), Some(c)) if c == u64::from(u32::MAX) => Cell::Null,
        (Some(Named::SensorOrNone), Some(c)) => Cell::Text(names.sensor(c)),
        (Some(Named::Sender), Some(c)) if c == u64::from(SENDER_COORDINATOR) => {
            Cell::Text("coordinator".into())
        }
        (Some(Named::Sender), Some(c)) if c == u64::from(SENDER_AGENT) => {
            Cell::Text("agent".into())
        }
        (Some(Named::Sender), Some(c)) => Cell::Text(names.sensor(c)),
        (Some(_), None) => Cell::Null,
        (None, _) => match s.scalar {
            Scalar::F32 | Scalar::F64 => v.as_f64().map_or(Cell::Null, Cell::Float),
            Scalar::I32 | Scalar::I64 => v.as_i64().map_or(Cell::Null, Cell::Int),
            Scalar::Bool => v.as_bool().map_or(Cell::Null, Cell::Bool),
            _ => v.as_u64().map_or(Cell::Null, Cell::Uint),
        },
    }
}

/// A code by name; an unknown code as `code <n>` (never dropped).
fn named_code(c: u64, name: impl Fn(u32) -> Option<&'static str>) -> Cell {
    let n = u32::try_from(c).ok().and_then(name);
    Cell::Text(n.map_or_else(|| format!("code {c}"), str::to_string))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::agent_to_coordinator::Outcome;
    use crate::wire::{Header, Message};

    #[test]
    fn every_kind_has_a_table_and_codes_become_names() {
        for k in Kind::ALL {
            let t = Table::of(*k, None).expect("traced");
            assert_eq!(t.columns[0].name, "log_time_ns");
            assert!(t.columns.iter().any(|c| c.name == "episode"), "{k:?}");
            assert!(!t.columns.iter().any(|c| c.name.contains("pad")), "{k:?}");
        }
        let t = Table::of(Kind::Outcome, None).expect("outcome");
        let o = Outcome {
            header: Header {
                episode: 3,
                sender: SENDER_AGENT,
                ..Header::default()
            },
            outcome: Outcome::COLLISION,
            degraded: 1,
            dead_sensor: u32::MAX,
            ..Outcome::default()
        };
        let names = Names {
            sensors: vec!["s0".into()],
        };
        let row = t.row(42, &o.into_recorded(), &names);
        let get = |n: &str| {
            let i = t.columns.iter().position(|c| c.name == n).expect(n);
            row[i].clone()
        };
        assert_eq!(get("log_time_ns"), Cell::Uint(42));
        assert_eq!(get("episode"), Cell::Uint(3));
        assert_eq!(get("sender"), Cell::Text("agent".into()));
        assert_eq!(get("outcome"), Cell::Text("collision".into()));
        assert_eq!(get("degraded"), Cell::Bool(true));
        assert_eq!(get("dead_sensor"), Cell::Null);
        let line = t.json_line(&[("topic", Value::from("outcome"))], &row);
        assert!(
            line.starts_with("{\"topic\":\"outcome\",\"log_time_ns\":42,"),
            "{line}"
        );
        let p = Table::of(Kind::Handover, None).expect("handover");
        assert!(p.columns.iter().any(|c| c.name == "cov_5_5"));
        let p2 = Table::of(Kind::Handover, Some(2)).expect("handover");
        let names: Vec<&str> = p2.columns.iter().skip(8).map(|c| c.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "mean_0", "mean_1", "cov_0_0", "cov_0_1", "cov_1_0", "cov_1_1"
            ]
        );
        assert_eq!(csv_quote("a,b"), "\"a,b\"");
    }
}
