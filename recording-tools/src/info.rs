//! `--info`: what `ros2 bag info` / `mcap info` show, for an etp recording:
//! size, profile and writer, whether it is finished, start, end and duration
//! of the messages, chunk compression, schemas, per channel its messages,
//! their rate and payload bytes, the time from publish to record (`log_time`
//! − `publish_time`, format 7), the metadata records and the run they
//! describe.

use etp_runtime::recording::{self, Contents, Layout};
use serde_json::{Value, json};
use std::fmt::Write;
use std::path::Path;

/// `ns` since the Unix epoch as RFC 3339 UTC (`2026-11-27T02:26:03.123456789Z`).
pub fn rfc3339(ns: u64) -> String {
    // A u64 of nanoseconds ends in 2554: always inside RFC 3339's years.
    let t = std::time::UNIX_EPOCH + std::time::Duration::from_nanos(ns);
    humantime::format_rfc3339_nanos(t).to_string()
}

/// The info object.
pub fn info(file: &Path, bytes: u64, c: &Contents, layout: &Layout) -> Value {
    let start = c.messages.iter().map(|m| m.log_time).min();
    let end = c.messages.iter().map(|m| m.log_time).max();
    let counts = c.counts();
    let mut bytes_of = std::collections::BTreeMap::<&str, u64>::new();
    let mut delays = std::collections::BTreeMap::<&str, Vec<i128>>::new();
    for m in &c.messages {
        *bytes_of.entry(m.topic.as_str()).or_default() += m.data.len() as u64;
        delays
            .entry(m.topic.as_str())
            .or_default()
            .push(i128::from(m.log_time) - i128::from(m.publish_time));
    }
    // As `mcap info`: a channel's messages over the file's span (null for
    // a span of zero, one message or none).
    let span_s = match (start, end) {
        (Some(s), Some(e)) if e > s => Some((e - s) as f64 * 1e-9),
        _ => None,
    };
    let channels: Vec<Value> = c
        .channels
        .iter()
        .map(|(topic, schema)| {
            json!({
                "topic": topic,
                "schema": schema,
                "schema_encoding": c.schemas.get(schema),
                "message_encoding": c.encodings.get(topic),
                "messages": counts.get(topic).copied().unwrap_or(0),
                "rate_hz": span_s.map(|d| counts.get(topic).copied().unwrap_or(0) as f64 / d),
                "bytes": bytes_of.get(topic.as_str()).copied().unwrap_or(0),
                "latency_us": delays.get_mut(topic.as_str()).and_then(|d| latency(d)),
            })
        })
        .collect();
    let metadata: serde_json::Map<String, Value> = c
        .metadata
        .iter()
        .map(|(k, v)| (k.clone(), json!(v.keys().collect::<Vec<_>>())))
        .collect();
    let outcomes = counts.get("outcome").copied().unwrap_or(0);
    let num = |k: &str| {
        c.meta(recording::META_RUN, k)
            .and_then(|v| v.parse::<u64>().ok())
    };
    json!({
        "file": file.display().to_string(),
        "bytes": bytes,
        "profile": layout.profile,
        "library": layout.library,
        "finished": c.finished,
        "truncated": c.truncated,
        "messages": c.messages.len(),
        "start_ns": start,
        "end_ns": end,
        "start_time": start.map(rfc3339),
        "end_time": end.map(rfc3339),
        "duration_s": match (start, end) {
            (Some(s), Some(e)) => json!((e - s) as f64 * 1e-9),
            _ => Value::Null,
        },
        "compression": layout.compression,
        "schemas": c.schemas,
        "channels": channels,
        "metadata": metadata,
        "run_id": c.meta(recording::META_RUN, "run_id"),
        "scenario": c.meta(recording::META_RUN, "scenario_name"),
        "seed": num("seed"),
        "requested_episodes": num("episodes"),
        "format_version": num("format_version"),
        // Episodes are etp's: null in a file without its `outcome` channel.
        "episodes": c.channels.contains_key("outcome").then_some(outcomes),
    })
}

/// Percentiles of a channel's `log_time − publish_time` (µs: p50, p99, min,
/// max); `None` when every message's two times are equal (formats 6 and
/// older, or another writer's file: no sender's time). Negative for a
/// sender whose clock is ahead of the recorder's (another host).
fn latency(d: &mut [i128]) -> Option<Value> {
    if d.iter().all(|&x| x == 0) {
        return None;
    }
    d.sort_unstable();
    // Nearest rank: the smallest value with at least p of them at or below it.
    let at = |p: f64| {
        let rank = (p * d.len() as f64).ceil() as usize;
        d[rank.clamp(1, d.len()) - 1] as f64 * 1e-3
    };
    Some(json!({"p50": at(0.5), "p99": at(0.99), "min": at(0.0), "max": at(1.0)}))
}

/// The info object as text.
pub fn render(v: &Value) -> String {
    let mut t = String::new();
    // Writing into a String cannot fail.
    let _ = write_info(&mut t, v);
    t
}

fn s(v: &Value) -> String {
    match v {
        Value::String(t) => t.clone(),
        Value::Null => "–".into(),
        v => v.to_string(),
    }
}

fn write_info(out: &mut String, v: &Value) -> std::fmt::Result {
    writeln!(
        out,
        "file:        {} ({} bytes)",
        s(&v["file"]),
        s(&v["bytes"])
    )?;
    writeln!(
        out,
        "profile:     {} · written by {}",
        s(&v["profile"]),
        s(&v["library"])
    )?;
    writeln!(
        out,
        "state:       {}",
        if v["finished"] == Value::Bool(true) {
            "finished".to_string()
        } else {
            format!("UNFINISHED ({})", s(&v["truncated"]))
        }
    )?;
    // An MCAP file etp did not write has no run to describe.
    let etp_run = !v["run_id"].is_null() || v["profile"] == recording::PROFILE;
    if etp_run {
        writeln!(
            out,
            "run:         {} · scenario {} · seed {} · {} episodes recorded (requested {}) · format {}",
            s(&v["run_id"]),
            s(&v["scenario"]),
            s(&v["seed"]),
            s(&v["episodes"]),
            s(&v["requested_episodes"]),
            s(&v["format_version"])
        )?;
    }
    let dur = v["duration_s"]
        .as_f64()
        .map_or("–".into(), |d| format!("{d:.3} s"));
    writeln!(out, "duration:    {dur}")?;
    writeln!(out, "start:       {}", s(&v["start_time"]))?;
    writeln!(out, "end:         {}", s(&v["end_time"]))?;
    writeln!(out, "messages:    {}", s(&v["messages"]))?;
    write!(out, "compression:")?;
    if let Some(m) = v["compression"].as_object() {
        for (k, c) in m {
            let name = if k.is_empty() { "none" } else { k };
            let (st, un) = (
                c["stored_bytes"].as_f64().unwrap_or(0.0),
                c["uncompressed_bytes"].as_f64().unwrap_or(0.0),
            );
            write!(
                out,
                " {name}: {} chunks, {} → {} bytes ({:.0} %)",
                s(&c["chunks"]),
                un,
                st,
                if un > 0.0 { 100.0 * st / un } else { 0.0 }
            )?;
        }
    }
    writeln!(out)?;
    writeln!(out, "channels:")?;
    if let Some(a) = v["channels"].as_array() {
        for c in a {
            let rate = c["rate_hz"]
                .as_f64()
                .map_or("–".into(), |r| format!("{r:.2}"));
            write!(
                out,
                "  {:<22} {:>9} msgs ({:>9} Hz) {:>11} B  {} ({}, {})",
                s(&c["topic"]),
                s(&c["messages"]),
                rate,
                s(&c["bytes"]),
                s(&c["schema"]),
                s(&c["schema_encoding"]),
                s(&c["message_encoding"])
            )?;
            let l = &c["latency_us"];
            if let (Some(p50), Some(p99)) = (l["p50"].as_f64(), l["p99"].as_f64()) {
                write!(out, "  published → logged p50 {p50:.0} µs, p99 {p99:.0} µs")?;
            }
            writeln!(out)?;
        }
    }
    writeln!(out, "metadata:")?;
    if let Some(m) = v["metadata"].as_object() {
        for (k, keys) in m {
            let keys: Vec<String> = keys
                .as_array()
                .map_or(Vec::new(), |a| a.iter().map(s).collect());
            writeln!(out, "  {k:<22} {}", keys.join(" "))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latency_is_null_without_sender_times_and_takes_any_time() {
        assert_eq!(latency(&mut [0, 0, 0]), None);
        let mut d: Vec<i128> = (1..=100).map(|us| us * 1000).collect();
        let l = latency(&mut d).expect("times");
        assert_eq!(l["p50"], 50.0);
        assert_eq!(l["p99"], 99.0);
        assert_eq!(
            (l["min"].as_f64(), l["max"].as_f64()),
            (Some(1.0), Some(100.0))
        );
        // A forged time from the network (u64::MAX) or a clock ahead of
        // the recorder's: a negative delay, no overflow.
        let mut d = [-i128::from(u64::MAX), 5_000];
        let l = latency(&mut d).expect("times");
        assert!(l["min"].as_f64().is_some_and(|m| m < -1e15), "{l}");
    }

    #[test]
    fn rfc3339_of_known_instants() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000000000Z");
        // 2000-02-29T12:34:56.5Z (a leap day).
        assert_eq!(
            rfc3339(951_827_696_500_000_000),
            "2000-02-29T12:34:56.500000000Z"
        );
        assert_eq!(
            rfc3339(1_798_761_600_000_000_001),
            "2027-01-01T00:00:00.000000001Z"
        );
    }
}
