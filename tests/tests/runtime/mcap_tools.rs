//! Recording format 5 (issue 43): a new recording of a real `etp run
//! --record` read by a reader that is not etp's — Foxglove's Python protobuf
//! decoder (`mcap-protobuf-support`, pinned in `tests/src/pyenv.rs`) with
//! the schemas the file carries — every message decoded, every value equal
//! to etp's own decoding, counts equal to `etp replay summary`; `replay
//! verify` bit for bit; and the format-4 fixture (bincode channels) still
//! summarises, verifies, exports and repairs.

use super::recording::{out_file, python_json, read_finished, record, replay};
use super::serial;
use etp_runtime::recording;
use etp_tests::unique_run_id;
use serde_json::{Map, Value};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Every message of the file decoded by `mcap_protobuf.decoder` from the
/// file's own `FileDescriptorSet` schemas; per topic, each message as
/// `{field path: value or list}` (nested messages joined with `.`,
/// repeated fields as lists), and each channel's encodings.
const PY_DECODE: &str = r#"
import sys, json, struct
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

def bits(x):
    # A double as its 64 bits: compared exactly, whatever parses the JSON.
    return struct.unpack("<Q", struct.pack("<d", x))[0] if isinstance(x, float) else x

def flat(msg, prefix, out):
    for f in msg.DESCRIPTOR.fields:
        v = getattr(msg, f.name)
        key = prefix + f.name
        if f.message_type is not None:
            flat(v, key + ".", out)
        elif f.is_repeated:
            out[key] = [bits(x) for x in v]
        else:
            out[key] = bits(v)
    return out

out = {"channels": {}, "messages": {}}
with open(sys.argv[1], "rb") as fh:
    r = make_reader(fh, decoder_factories=[DecoderFactory()])
    s = r.get_summary()
    for c in s.channels.values():
        sc = s.schemas[c.schema_id]
        out["channels"][c.topic] = [c.message_encoding, sc.encoding, sc.name]
        out["messages"][c.topic] = []
    for schema, channel, message, proto in r.iter_decoded_messages(log_time_order=False):
        out["messages"][channel.topic].append(flat(proto, "", {}))
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
    assert_eq!(recording::FORMAT_VERSION, "5");
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

    // etp's decoding of every message, flattened as the Python side does.
    let mut ours: BTreeMap<String, Vec<Value>> = BTreeMap::new();
    for m in &c.messages {
        let mut row = Map::new();
        flatten(&m.decode().expect("decodes").to_json(), "", &mut row);
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
    let _ = std::fs::remove_file(&file);
}

/// `etp replay ARGS` (a command without `--json`) must succeed.
fn etp_replay(args: &[&str]) {
    let out = std::process::Command::new(etp_tests::bin_dir().join("etp"))
        .arg("replay")
        .args(args)
        .output()
        .expect("etp replay");
    assert!(
        out.status.success(),
        "etp replay {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/fixtures/open-2d-4-episodes.mcap")
}

#[test]
fn the_format_4_fixture_still_summarises_verifies_exports_and_repairs() {
    let path = fixture();
    let c = read_finished(&path);
    assert_eq!(
        c.meta(recording::META_RUN, "format_version"),
        Some(recording::LEGACY_FORMAT_VERSION)
    );
    for (topic, e) in &c.encodings {
        assert_eq!(e, recording::LEGACY_MESSAGE_ENCODING, "{topic}");
    }
    let p = path.display().to_string();
    let summary = replay(&["summary", &p]);
    assert_eq!(summary["counts"]["outcome"].as_u64(), Some(4));
    let v = replay(&["verify", &p]);
    assert_eq!(
        v["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        v["verify"]
    );
    assert_eq!(v["verify"]["episodes_checked"].as_u64(), Some(4));
    let info = replay(&["info", &p]);
    assert!(info["channels"].as_array().is_some_and(|a| !a.is_empty()));

    let dir = std::env::temp_dir().join(format!("etp-test-{}-old", unique_run_id("fx")));
    let out = dir.join("export");
    std::fs::create_dir_all(&dir).expect("dir");
    etp_replay(&["export", &p, &out.display().to_string()]);
    let outcome = std::fs::read_to_string(out.join("outcome.csv")).expect("outcome.csv");
    assert_eq!(outcome.lines().count(), 5, "{outcome}");

    // A repaired copy keeps format 4 (its metadata says so) and verifies.
    let copy = dir.join("copy.mcap");
    etp_replay(&["repair", &p, &copy.display().to_string()]);
    let cc = read_finished(&copy);
    assert_eq!(cc.encodings, c.encodings);
    assert_eq!(cc.messages.len(), c.messages.len());
    let v = replay(&["verify", &copy.display().to_string()]);
    assert_eq!(
        v["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        v["verify"]
    );
    let _ = std::fs::remove_dir_all(&dir);
}
