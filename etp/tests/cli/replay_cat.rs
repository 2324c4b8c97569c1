//! `etp replay cat --json`: the lines of `mcap cat --json` (the Go `mcap`
//! CLI's shape: topic, sequence, log_time, publish_time as seconds with nine
//! decimals, data as the protobuf JSON mapping), checked message for message
//! against Python's `mcap` reader with Foxglove's protobuf decoder and
//! protobuf's own JSON mapping (`json_format.MessageToDict`), which know
//! nothing of etp but the schemas the file carries (on a new recording:
//! the committed fixture is of format 4, whose bincode channels Python
//! cannot decode).

use super::{Scratch, etp, ok_json, s};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/fixtures/open-2d-4-episodes.mcap")
}

/// Per (topic, sequence): [log_time ns, publish_time ns, data], every message
/// of the file decoded by Python's reader from the file's own schemas.
const PY_CAT: &str = r#"
import sys, json
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from google.protobuf.json_format import MessageToDict

out = {}
with open(sys.argv[1], "rb") as fh:
    r = make_reader(fh, decoder_factories=[DecoderFactory()])
    for schema, channel, message, proto in r.iter_decoded_messages(log_time_order=False):
        key = f"{channel.topic} {message.sequence}"
        assert key not in out, key
        out[key] = [message.log_time, message.publish_time, MessageToDict(proto)]
print(json.dumps(out))
"#;

/// The ns of a time written as `mcap cat --json` writes it (a JSON number
/// of seconds with exactly nine decimals), read from the line's text: a
/// 64-bit float would lose the nanoseconds.
fn decimal_time(line: &str, key: &str) -> u64 {
    let tag = format!("\"{key}\":");
    let at = line
        .find(&tag)
        .unwrap_or_else(|| panic!("no {key} in {line}"))
        + tag.len();
    let text: String = line[at..]
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    let (sec, ns) = text.split_once('.').expect("seconds.nanoseconds");
    assert_eq!(ns.len(), 9, "nine decimals: {line}");
    sec.parse::<u64>().expect("seconds") * 1_000_000_000 + ns.parse::<u64>().expect("ns")
}

fn py_cat(file: &Path) -> BTreeMap<String, Value> {
    serde_json::from_value(super::replay_subcommands::python(PY_CAT, file)).expect("an object")
}

#[test]
fn cat_json_lines_are_mcap_cat_json_lines_message_for_message() {
    let dir = Scratch::new("cat-json");
    let f = dir.path("run.mcap");
    let run_id = format!("t{}-catjson", std::process::id());
    ok_json(&[
        "run",
        "--scenario",
        "open-2d",
        "--delta",
        "1.0518",
        "--episodes",
        "2",
        "--seed",
        "3",
        "--predict-episodes",
        "100",
        "--run-id",
        &run_id,
        "--record",
        s(&f),
        "--json",
    ]);
    let out = etp(&["replay", "cat", s(&f), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let theirs = py_cat(&f);
    assert_eq!(text.lines().count(), theirs.len(), "one line per message");
    let mut last = 0;
    for line in text.lines() {
        let v: Value = serde_json::from_str(line).expect("a JSON line");
        let keys: Vec<&str> = v
            .as_object()
            .expect("an object")
            .keys()
            .map(String::as_str)
            .collect();
        let mut want = vec!["data", "log_time", "publish_time", "sequence", "topic"];
        want.sort_unstable();
        assert_eq!(keys, want, "mcap's fields: {line}");
        // mcap's field order, as its Go struct writes them.
        let order: Vec<usize> = ["topic", "sequence", "log_time", "publish_time", "data"]
            .iter()
            .map(|k| line.find(&format!("\"{k}\":")).expect("field"))
            .collect();
        assert!(order.windows(2).all(|w| w[0] < w[1]), "{line}");
        let topic = v["topic"].as_str().expect("topic");
        let seq = v["sequence"].as_u64().expect("sequence");
        let key = format!("{topic} {seq}");
        let Some(t) = theirs.get(&key) else {
            panic!("{key}: not in the file according to Python: {line}")
        };
        let log_time = decimal_time(line, "log_time");
        assert_eq!(Some(log_time), t[0].as_u64(), "{key}");
        assert_eq!(
            Some(decimal_time(line, "publish_time")),
            t[1].as_u64(),
            "{key}"
        );
        assert!(log_time >= last, "log-time order");
        last = log_time;
        assert_eq!(
            v["data"], t[2],
            "{key}: data differs from protobuf's JSON mapping"
        );
    }
    // The mapping's types: 64-bit integers as strings, a header nested.
    let first = text
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).expect("JSON"))
        .find(|v| v["topic"] == "outcome")
        .expect("an outcome");
    assert!(first["data"]["header"]["run"].is_string(), "{first}");
    // Format 6: codes and ids by their enum names, as `mcap cat --json` shows them.
    assert_eq!(first["data"]["header"]["sender"], "AGENT", "{first}");
    assert!(
        matches!(
            first["data"]["outcome"].as_str(),
            Some("TARGET" | "COLLISION" | "FREE")
        ),
        "{first}"
    );
    assert!(first["data"]["dead_sensor"] == "NONE", "{first}");
}

/// A format-4 file's payloads as their format-6 protobuf message: the
/// same line shape, the values of the typed rows.
#[test]
fn cat_json_reads_a_format_4_file_as_its_protobuf_messages() {
    let out = etp(&[
        "replay",
        "cat",
        s(&fixture()),
        "--json",
        "--topics",
        "outcome",
    ]);
    assert!(out.status.success());
    let rows = etp(&["replay", "cat", s(&fixture()), "--topics", "outcome"]);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let rows = String::from_utf8_lossy(&rows.stdout).into_owned();
    assert_eq!(text.lines().count(), 4);
    for (l, r) in text.lines().zip(rows.lines()) {
        let v: Value = serde_json::from_str(l).expect("JSON line");
        let r: Value = serde_json::from_str(r).expect("JSON line");
        assert_eq!(v["topic"], "outcome");
        assert_eq!(
            decimal_time(l, "log_time"),
            r["log_time_ns"].as_u64().expect("ns")
        );
        assert_eq!(
            v["data"]["header"]["run"].as_str(),
            r["run"].as_str(),
            "{l}\n{r}"
        );
        assert_eq!(v["data"]["steps"], r["steps"], "{l}\n{r}");
    }
}

#[test]
fn cat_without_json_keeps_the_typed_rows() {
    let out = etp(&["replay", "cat", s(&fixture()), "--topics", "outcome"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert_eq!(text.lines().count(), 4);
    for l in text.lines() {
        let v: Value = serde_json::from_str(l).expect("JSON line");
        assert!(v["log_time_ns"].is_u64() && v.get("data").is_none(), "{v}");
        assert!(v["outcome"].is_string(), "{v}");
    }
}
