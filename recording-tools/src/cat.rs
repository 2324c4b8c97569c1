//! `etp replay cat`: every message of a recording as one JSON line, in
//! log-time order, in one of two shapes ([`Shape`]).
//!
//! * [`Shape::Rows`] (the default): the message's typed row, as `replay
//!   export --format jsonl` writes it, with `topic` first (codes as names,
//!   sensors by their scenario names, arrays cut to the scenario's
//!   dimension).
//! * [`Shape::Mcap`] (`--json`): the line of `mcap cat --json` (the Go `mcap`
//!   CLI): `{"topic", "sequence", "log_time", "publish_time", "data"}` in
//!   that order, the two times as JSON numbers of seconds with nine
//!   decimals (`1765000000.000000042`), `data` the message in the protobuf
//!   JSON mapping of its schema (`protojson`: fields by their JSON name,
//!   fields at their default value left out, 64-bit integers as strings).
//!   An etp channel's message is its protobuf message as its file's schema
//!   has it (format 6: enums by name, arrays of the used length; format 5:
//!   plain numbers, whole arrays); a format-4 file's bincode payload is
//!   decoded and encoded as its format-6 message first;
//!   another writer's `json` message is its own JSON. A message neither
//!   decodes has `data: null`, and its channel's `message_encoding`,
//!   `schema` and size in `bytes` follow (`mcap cat --json` refuses such a
//!   file).

use crate::error::{Context, Error, Result};
use crate::export::{decoded_row, names, tables};
use etp_runtime::recording::{Contents, Encoding, RawMessage};
use prost_reflect::{DynamicMessage, SerializeOptions};
use serde_json::{Value, json};
use std::io::Write;

/// The shape of `cat`'s lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// The typed rows of `replay export --format jsonl`, `topic` first.
    Rows,
    /// The lines of `mcap cat --json`.
    Mcap,
}

/// Every message of `c` as one JSON line of `shape`, in log-time order
/// (messages of equal log time in file order); the count of lines.
pub fn cat(c: &Contents, out: &mut impl Write, shape: Shape) -> Result<u64> {
    let (names, dim) = names(c);
    let tables = tables(c, dim)?;
    let mut order: Vec<&RawMessage> = c.messages.iter().collect();
    order.sort_by_key(|m| m.log_time);
    let mut n = 0u64;
    for m in order {
        if !c.channels.contains_key(&m.topic) {
            return Err(Error::UndeclaredChannel(m.topic.clone()));
        }
        let line = match (shape, tables.get(&m.topic)) {
            (Shape::Rows, Some(t)) => {
                let row = decoded_row(t, m, &names)?;
                t.json_line(&[("topic", Value::from(m.topic.as_str()))], &row)
            }
            (Shape::Rows, None) => foreign_row(c, m).to_string(),
            (Shape::Mcap, Some(_)) => mcap_line(m, &protobuf_json(m)?, None),
            (Shape::Mcap, None) => match foreign_json(c, m) {
                Some(v) => mcap_line(m, &v.to_string(), None),
                None => mcap_line(m, "null", Some(undecoded(c, m))),
            },
        };
        writeln!(out, "{line}").map_err(Error::Stream)?;
        n += 1;
    }
    out.flush().map_err(Error::Stream)?;
    Ok(n)
}

/// A time of `mcap cat --json` (its `DecimalTime`): ns as seconds with nine
/// decimals, written as a JSON number.
pub fn decimal_time(ns: u64) -> String {
    format!("{}.{:09}", ns / 1_000_000_000, ns % 1_000_000_000)
}

/// One line of `mcap cat --json`; `data` is JSON text. `extra` (the
/// description of a message that does not decode) follows `data`.
fn mcap_line(m: &RawMessage, data: &str, extra: Option<serde_json::Map<String, Value>>) -> String {
    let mut line = format!(
        "{{\"topic\":{},\"sequence\":{},\"log_time\":{},\"publish_time\":{},\"data\":{data}",
        Value::from(m.topic.as_str()),
        m.sequence,
        decimal_time(m.log_time),
        decimal_time(m.publish_time),
    );
    for (k, v) in extra.into_iter().flatten() {
        line.push_str(&format!(",{}:{v}", Value::from(k)));
    }
    line.push('}');
    line
}

/// An etp channel's message as `mcap cat --json`'s `data`: its protobuf
/// message in the protobuf JSON mapping, as JSON text (fields in the order
/// of their numbers, as `protojson` writes them).
fn protobuf_json(m: &RawMessage) -> Result<String> {
    let at = || format!("message at log time {} on `{}`", m.log_time, m.topic);
    let payload = m.decode().at_message(at)?;
    // A protobuf channel's message in its own file's mapping (its schema);
    // a format-4 payload as the recorder writes it now.
    let encoding = match m.encoding {
        Some(Encoding::Protobuf5) => Encoding::Protobuf5,
        _ => Encoding::Protobuf,
    };
    let bytes = encoding.encode_recorded(&payload).at_message(at)?;
    let mapping = encoding
        .proto_mapping()
        .unwrap_or(etp_runtime::recording::ProtoMapping::Typed);
    let desc = payload.kind().proto_descriptor_in(mapping).at_message(at)?;
    let msg = DynamicMessage::decode(desc, bytes.as_slice()).at_message(at)?;
    let mut text = Vec::new();
    msg.serialize_with_options(
        &mut serde_json::Serializer::new(&mut text),
        &SerializeOptions::new(),
    )
    .at_message(at)?;
    String::from_utf8(text).at_message(at)
}

/// A `json` message of a channel etp did not write, parsed.
fn foreign_json(c: &Contents, m: &RawMessage) -> Option<Value> {
    (c.encodings.get(&m.topic).map(String::as_str) == Some("json"))
        .then(|| serde_json::from_slice::<Value>(&m.data).ok())
        .flatten()
}

/// What is known of a message that does not decode: its channel's encoding
/// and schema name, and its size.
fn undecoded(c: &Contents, m: &RawMessage) -> serde_json::Map<String, Value> {
    let mut o = serde_json::Map::new();
    o.insert(
        "message_encoding".into(),
        json!(c.encodings.get(&m.topic).map_or("", String::as_str)),
    );
    o.insert("schema".into(), json!(c.channels.get(&m.topic)));
    o.insert("bytes".into(), json!(m.data.len()));
    o
}

/// A message of a channel etp did not write, as [`Shape::Rows`] shows it:
/// `json` payloads decoded (`message`), any other encoding named with its
/// size.
fn foreign_row(c: &Contents, m: &RawMessage) -> Value {
    let mut o = serde_json::Map::new();
    o.insert("topic".into(), json!(m.topic));
    o.insert("log_time_ns".into(), json!(m.log_time));
    match foreign_json(c, m) {
        Some(v) => {
            o.insert("message".into(), v);
        }
        None => o.extend(undecoded(c, m)),
    }
    Value::Object(o)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_seconds_with_nine_decimals_as_mcap_writes_them() {
        assert_eq!(decimal_time(0), "0.000000000");
        assert_eq!(decimal_time(42), "0.000000042");
        assert_eq!(
            decimal_time(1_765_000_000_123_456_789),
            "1765000000.123456789"
        );
        assert_eq!(decimal_time(u64::MAX), "18446744073.709551615");
    }

    #[test]
    fn a_line_has_mcaps_fields_in_mcaps_order() {
        let m = RawMessage {
            topic: "outcome".into(),
            sequence: 7,
            log_time: 2_000_000_001,
            publish_time: 1_000_000_000,
            data: Vec::new(),
            encoding: None,
        };
        let line = mcap_line(&m, "{\"a\":1}", None);
        assert_eq!(
            line,
            "{\"topic\":\"outcome\",\"sequence\":7,\"log_time\":2.000000001,\
             \"publish_time\":1.000000000,\"data\":{\"a\":1}}"
        );
        let v: Value = serde_json::from_str(&line).expect("JSON");
        assert_eq!(v["data"]["a"], 1);
    }
}
