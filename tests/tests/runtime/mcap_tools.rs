//! Recording format 7: a new recording of a real `etp run --record` read by
//! a reader that is not etp's — Foxglove's Python protobuf decoder
//! (`mcap-protobuf-support`, pinned in `tests/src/pyenv.rs`) with the
//! schemas the file carries — every message decoded, every value equal to
//! etp's own decoding as format 6 maps it (codes by enum name, flags as
//! bools, arrays of the used length), counts equal to `etp replay summary`;
//! `replay verify` bit for bit; each message's `publish_time` its sender's
//! time, before the recorder's `log_time`. The older formats' fixtures:
//! `mcap_tools_fixtures`.

use super::recording::{out_file, python_json, read_finished, record, replay};
use super::serial;
use etp_runtime::recording;
use etp_runtime::wire::Kind;
use etp_runtime::wire::catalogue::{HEADER_NAMES, Named};
use etp_tests::unique_run_id;
use serde_json::{Map, Value};
use std::collections::BTreeMap;

/// Every message of the file decoded by `mcap_protobuf.decoder` from the
/// file's own `FileDescriptorSet` schemas; per topic, each message as
/// `{field path: value or list}` (nested messages joined with `.`,
/// repeated fields as lists, an enum as its number), the names of its enum
/// values (`{path: name}`, from the schema), each channel's encodings, and
/// each message's `[log_time, publish_time]`.
const PY_DECODE: &str = r#"
import sys, json, struct
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

def bits(x):
    # A double as its 64 bits: compared exactly, whatever parses the JSON.
    return struct.unpack("<Q", struct.pack("<d", x))[0] if isinstance(x, float) else x

def flat(msg, prefix, out, names):
    for f in msg.DESCRIPTOR.fields:
        v = getattr(msg, f.name)
        key = prefix + f.name
        if f.message_type is not None:
            flat(v, key + ".", out, names)
        elif f.is_repeated:
            out[key] = [bits(x) for x in v]
        else:
            out[key] = bits(v)
            if f.enum_type is not None:
                named = f.enum_type.values_by_number.get(v)
                names[key] = named.name if named is not None else None
    return out

out = {"channels": {}, "messages": {}, "names": {}, "times": {}}
with open(sys.argv[1], "rb") as fh:
    r = make_reader(fh, decoder_factories=[DecoderFactory()])
    s = r.get_summary()
    for c in s.channels.values():
        sc = s.schemas[c.schema_id]
        out["channels"][c.topic] = [c.message_encoding, sc.encoding, sc.name]
        out["messages"][c.topic] = []
        out["names"][c.topic] = []
        out["times"][c.topic] = []
    for schema, channel, message, proto in r.iter_decoded_messages(log_time_order=False):
        names = {}
        out["messages"][channel.topic].append(flat(proto, "", {}, names))
        out["names"][channel.topic].append(names)
        out["times"][channel.topic].append([message.log_time, message.publish_time])
print(json.dumps(out))
"#;

/// A decoded payload as the Python side writes it: fields by path, arrays
/// flattened row-major, padding left out (it has no protobuf field), every
/// double as its 64 bits (so the comparison is exact, not through text).
fn flatten(v: &Value, prefix: &str, out: &mut Map<String, Value>) {
    fn bits(x: &Value) -> Value {
        match x.as_f64() {
            Some(f) if x.is_f64() => Value::from(f.to_bits()),
            _ => x.clone(),
        }
    }
    fn scalars(v: &Value, out: &mut Vec<Value>) {
        match v {
            Value::Array(a) => a.iter().for_each(|x| scalars(x, out)),
            x => out.push(bits(x)),
        }
    }
    if let Value::Object(o) = v {
        for (k, x) in o.iter().filter(|(k, _)| !k.starts_with('_')) {
            let key = format!("{prefix}{k}");
            match x {
                Value::Object(_) => flatten(x, &format!("{key}."), out),
                Value::Array(_) => {
                    let mut list = Vec::new();
                    scalars(x, &mut list);
                    out.insert(key, Value::Array(list));
                }
                s => {
                    out.insert(key, bits(s));
                }
            }
        }
    }
}

/// A payload (etp's decoding, `Recorded::to_json`) as format 6 records
/// it, by the rules of `wire::proto` applied here rather than by its code:
/// arrays cut to `dim` entries per axis, the catalogue's flags as bools, its
/// codes and ids as protobuf's int32 enum numbers of their u32.
fn as_recorded(kind: Kind, payload: &Value) -> Value {
    let mut v = payload.clone();
    let dim = v["dim"].as_u64().and_then(|d| usize::try_from(d).ok());
    if let (Some(d), Value::Object(o)) = (dim, &mut v) {
        for x in o.values_mut() {
            if let Value::Array(a) = x {
                a.truncate(d);
                for row in a.iter_mut() {
                    if let Value::Array(r) = row {
                        r.truncate(d);
                    }
                }
            }
        }
    }
    for (path, named) in HEADER_NAMES.iter().chain(kind.named_fields()) {
        if let Some(x) = v.pointer_mut(&format!("/{}", path.replace('.', "/"))) {
            let code = x
                .as_u64()
                .and_then(|c| u32::try_from(c).ok())
                .expect("a u32 code");
            *x = match named {
                Named::Flag => Value::Bool(code == 1),
                _ => Value::from(i32::from_ne_bytes(code.to_ne_bytes())),
            };
        }
    }
    v
}

/// Per topic, the messages as sorted JSON texts (channels with several
/// publishers interleave in the recorder's drain order).
fn sorted(m: BTreeMap<String, Vec<Value>>) -> BTreeMap<String, Vec<String>> {
    m.into_iter()
        .map(|(t, v)| {
            let mut s: Vec<String> = v.iter().map(Value::to_string).collect();
            s.sort();
            (t, s)
        })
        .collect()
}

/// Every message of `file` decoded the way the Rust `mcap` CLI's `cat
/// --json` does (its `commands/cat.rs`): the channel's schema data as a
/// `prost_reflect::DescriptorPool`, the message looked up by the schema's
/// name, `DynamicMessage::decode`, then serde — with every field written and
/// 64-bit integers as numbers, so the values compare with etp's. Nothing of
/// etp's descriptors is used: only what the file carries. The `mcap` CLI
/// itself is not on crates.io (its crate is `publish = false`, released as
/// GitHub binaries only), so the test set-up cannot install it.
fn cat_json_like_the_rust_mcap_cli(file: &std::path::Path) -> BTreeMap<String, Vec<Value>> {
    use prost_reflect::{DescriptorPool, DynamicMessage, SerializeOptions};
    let bytes = std::fs::read(file).expect("recording");
    let summary = mcap::read::Summary::read(&bytes)
        .expect("summary reads")
        .expect("a summary");
    let mut out: BTreeMap<String, Vec<Value>> = summary
        .channels
        .values()
        .map(|c| (c.topic.clone(), Vec::new()))
        .collect();
    let options = SerializeOptions::new()
        .skip_default_fields(false)
        .stringify_64_bit_integers(false)
        .use_enum_numbers(true)
        .use_proto_field_name(true);
    for m in mcap::MessageStream::new(&bytes).expect("stream") {
        let m = m.expect("a message");
        let schema = m.channel.schema.as_ref().expect("a schema");
        assert_eq!(schema.encoding, "protobuf");
        assert_eq!(m.channel.message_encoding, "protobuf");
        let pool = DescriptorPool::decode(schema.data.as_ref()).expect("a FileDescriptorSet");
        let desc = pool
            .get_message_by_name(&schema.name)
            .unwrap_or_else(|| panic!("no message {} in its schema", schema.name));
        let msg = DynamicMessage::decode(desc, m.data.as_ref()).expect("decodes");
        let json = msg
            .serialize_with_options(serde_json::value::Serializer, &options)
            .expect("to JSON");
        let mut row = Map::new();
        flatten(&json, "", &mut row);
        out.entry(m.channel.topic.clone())
            .or_default()
            .push(Value::Object(row));
    }
    let total: usize = out.values().map(Vec::len).sum();
    assert_eq!(
        Some(total as u64),
        summary.stats.map(|s| s.message_count),
        "`mcap info`'s message count"
    );
    out
}

/// The messages of two decoders, per topic, are the same.
fn assert_same(
    who: &str,
    ours: &BTreeMap<String, Vec<String>>,
    theirs: BTreeMap<String, Vec<Value>>,
) {
    let theirs = sorted(theirs);
    assert_eq!(
        ours.keys().collect::<Vec<_>>(),
        theirs.keys().collect::<Vec<_>>(),
        "{who}"
    );
    for (topic, v) in ours {
        assert_eq!(v.len(), theirs[topic].len(), "{who}: {topic}");
        let diff = v.iter().zip(&theirs[topic]).position(|(a, b)| a != b);
        assert!(
            diff.is_none(),
            "{topic}: etp and {who} decode differently: {:?} vs {:?}",
            diff.map(|i| &v[i]),
            diff.map(|i| &theirs[topic][i])
        );
    }
}

/// Each message's `publish_time` as the Python reader reads it (`times`:
/// per topic, `[log_time, publish_time]` in file order) is etp's reader's,
/// and is the sender's: on one host at or before the recorder's `log_time`
/// (one clock), not the `log_time` again, and within the run.
fn publish_times_are_the_senders(c: &recording::Contents, times: &Value) {
    let times: BTreeMap<String, Vec<(u64, u64)>> =
        serde_json::from_value(times.clone()).expect("times");
    // Every channel, those without a message (a run with no `drift` flag)
    // too, as the Python reader lists them.
    let mut ours: BTreeMap<String, Vec<(u64, u64)>> =
        c.channels.keys().map(|t| (t.clone(), Vec::new())).collect();
    for m in &c.messages {
        ours.entry(m.topic.clone())
            .or_default()
            .push((m.log_time, m.publish_time));
    }
    assert_eq!(ours, times, "etp's reader vs Python's mcap reader");
    let all: Vec<(u64, u64)> = times.values().flatten().copied().collect();
    assert!(all.len() > 100, "{}", all.len());
    for &(log, publish) in &all {
        assert!(publish <= log, "published at {publish}, logged at {log}");
    }
    assert!(
        all.iter().any(|&(log, publish)| publish < log),
        "every publish_time is its log_time"
    );
    let first_log = all.iter().map(|t| t.0).min().unwrap_or(0);
    let last_log = all.iter().map(|t| t.0).max().unwrap_or(0);
    // Published during the run: after the recorder was started (a few
    // seconds before its first message at most), before its last.
    for &(_, publish) in &all {
        assert!(
            publish + 60_000_000_000 > first_log && publish <= last_log,
            "{publish} outside the run"
        );
    }
}

#[test]
fn a_new_recording_decodes_in_foxgloves_protobuf_reader_value_for_value() {
    let _serial = serial();
    let id = unique_run_id("pb");
    let file = out_file(&id);
    record(&id, &file, "6", "5");
    let c = read_finished(&file);
    // The file states its format, and every channel is protobuf.
    assert_eq!(
        c.meta(recording::META_RUN, "format_version"),
        Some(recording::FORMAT_VERSION)
    );
    assert_eq!(recording::FORMAT_VERSION, "7");
    assert!(!c.encodings.is_empty());
    for (topic, e) in &c.encodings {
        assert_eq!(e, "protobuf", "{topic}");
        assert_eq!(
            c.channels[topic],
            recording::kind_of_topic(topic)
                .expect("etp topic")
                .proto_name()
        );
    }

    // etp's decoding of every message, as format 7 records it, flattened
    // as the Python side does.
    // Every channel, those without a message (`drift` of a run that
    // flagged nothing) too, as the other readers list them.
    let mut ours: BTreeMap<String, Vec<Value>> =
        c.channels.keys().map(|t| (t.clone(), Vec::new())).collect();
    for m in &c.messages {
        let mut row = Map::new();
        let payload = m.decode().expect("decodes");
        flatten(
            &as_recorded(payload.kind(), &payload.to_json()),
            "",
            &mut row,
        );
        ours.entry(m.topic.clone())
            .or_default()
            .push(Value::Object(row));
    }
    let py = python_json(PY_DECODE, &file);
    for (topic, ch) in py["channels"].as_object().expect("channels") {
        assert_eq!(ch[0], "protobuf", "{topic}");
        assert_eq!(ch[1], "protobuf", "{topic}");
    }
    let theirs: BTreeMap<String, Vec<Value>> =
        serde_json::from_value(py["messages"].clone()).expect("messages");
    publish_times_are_the_senders(&c, &py["times"]);
    // Counts: Python's decoder, etp's reader and `replay summary` agree.
    let summary = replay(&["summary", &file.display().to_string()]);
    let counts: BTreeMap<String, u64> =
        serde_json::from_value(summary["counts"].clone()).expect("summary counts");
    let py_counts: BTreeMap<String, u64> = theirs
        .iter()
        .map(|(t, v)| (t.clone(), v.len() as u64))
        .collect();
    assert_eq!(py_counts, counts, "Python decoder vs etp replay summary");
    assert!(counts["measurement"] > 50, "{counts:?}");
    assert_eq!(counts["outcome"], 6);
    // What a Foxglove user reads: codes and ids by name, arrays as long as
    // the data.
    let names = &py["names"];
    let name_of = |topic: &str, path: &str| -> Vec<String> {
        names[topic]
            .as_array()
            .expect("names")
            .iter()
            .map(|n| n[path].as_str().unwrap_or("(unnamed)").to_string())
            .collect()
    };
    for o in name_of("outcome", "outcome") {
        assert!(["TARGET", "COLLISION", "FREE"].contains(&o.as_str()), "{o}");
    }
    assert!(
        name_of("outcome", "header.sender")
            .iter()
            .all(|s| s == "AGENT")
    );
    assert!(
        name_of("outcome", "dead_sensor")
            .iter()
            .all(|s| s == "NONE")
    );
    assert!(
        name_of("control", "header.sender")
            .iter()
            .all(|s| s == "COORDINATOR")
    );
    assert!(
        name_of("control", "kind")
            .iter()
            .all(|s| s == "START" || s == "STOP")
    );
    let senders = name_of("measurement", "header.sender");
    assert!(
        senders.iter().all(|s| s.starts_with("SENSOR_")),
        "{senders:?}"
    );
    for m in theirs["measurement"].iter().chain(&theirs["waypoint"]) {
        let dim = m["dim"].as_u64().expect("dim");
        assert!(dim < 6, "{m}");
        for (array, len) in [("y", dim), ("mean", dim), ("cov", dim * dim)] {
            if let Some(a) = m.get(array) {
                assert_eq!(
                    a.as_array().map(Vec::len),
                    Some(len as usize),
                    "{array}: {m}"
                );
            }
        }
    }
    assert!(
        theirs["slot"].iter().all(|m| m["delivered"].is_boolean()),
        "slot.delivered is a bool"
    );

    // Value for value, doubles bit for bit.
    let ours = sorted(ours);
    assert_same("mcap_protobuf (Python)", &ours, theirs);
    assert_same(
        "the Rust mcap CLI's cat --json decoding",
        &ours,
        cat_json_like_the_rust_mcap_cli(&file),
    );

    // `replay verify`: the estimator re-run on the decoded values, exact.
    let v = replay(&["verify", &file.display().to_string()]);
    assert_eq!(
        v["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        v["verify"]
    );
    assert_eq!(v["verify"]["episodes_checked"].as_u64(), Some(6));

    // A forged payload (valid protobuf, one field more than etp writes) is
    // refused by name, not read as something else.
    let i = c
        .messages
        .iter()
        .position(|m| m.topic == "measurement")
        .expect("a measurement");
    let mut forged = c.messages[i].clone();
    forged.data.extend_from_slice(&[0xF8, 0x01, 0x07]);
    let e = forged.decode().expect_err("forged").to_string();
    assert!(e.contains("measurement") && e.contains("canonical"), "{e}");

    // Every tool reads it, as it reads the older formats' fixtures.
    super::mcap_tools_fixtures::every_tool_reads(&file, recording::FORMAT_VERSION, 6);
    let _ = std::fs::remove_file(&file);
}
