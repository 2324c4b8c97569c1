//! `etp replay foxglove FILE OUT`: the copy read back by the independent
//! Python `mcap` reader (JSON messages, Foxglove schemas, counts that match
//! the source recording; Python `jsonschema` on a sample when installed),
//! and no silent overwrite.

use super::recording::{out_file, python_json, record, replay};
use super::serial;
use etp_tests::{bin_dir, unique_run_id};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// What Python's `mcap` reader sees in a Foxglove copy, as one JSON object:
/// the channels with their encodings and schema names, messages per topic,
/// whether every payload parses as JSON and the file is in time order, the
/// `/trajectories` entity ids, and (with `jsonschema`) the validation errors
/// of a sample of every topic (the first 20 messages and every 97th).
const INSPECT: &str = r#"
import sys, json
from mcap.reader import make_reader
try:
    import jsonschema
except ImportError:
    jsonschema = None
out = {"channels": [], "counts": {}, "bad_json": 0, "time_order": True,
       "trajectory_ids": [], "validated": 0, "errors": [], "ellipses": 0,
       "jsonschema": jsonschema is not None}
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    s = r.get_summary()
    for c in s.channels.values():
        sc = s.schemas[c.schema_id]
        out["channels"].append({"topic": c.topic, "message_encoding": c.message_encoding,
                                "schema_name": sc.name, "schema_encoding": sc.encoding})
        out["counts"][c.topic] = 0
    last = 0
    seen = {}
    for schema, channel, message in r.iter_messages(log_time_order=False):
        n = out["counts"][channel.topic]
        out["counts"][channel.topic] = n + 1
        if message.log_time < last:
            out["time_order"] = False
        last = message.log_time
        try:
            v = json.loads(message.data)
        except ValueError:
            out["bad_json"] += 1
            continue
        if channel.topic == "/trajectories":
            out["trajectory_ids"] += [e["id"] for e in v["entities"]]
        if channel.topic == "/agent" and len(v["entities"][0].get("spheres", [])) >= 3:
            out["ellipses"] += 1
        if jsonschema is not None and (n < 20 or n % 97 == 0):
            sid = schema.id
            if sid not in seen:
                seen[sid] = jsonschema.Draft7Validator(json.loads(schema.data))
            errs = list(seen[sid].iter_errors(v))
            out["validated"] += 1
            out["errors"] += [channel.topic + ": " + e.message for e in errs[:3]]
print(json.dumps(out))
"#;

fn inspect(file: &Path) -> Value {
    python_json(INSPECT, file)
}

#[test]
fn the_foxglove_copy_is_json_with_foxglove_schemas_and_matches_the_recording() {
    let _serial = serial();
    let id = unique_run_id("fox");
    let file = out_file(&id);
    let fox = std::env::temp_dir().join(format!("etp-test-{id}-foxglove.mcap"));
    let v = record(&id, &file, "20", "7");
    let counts: BTreeMap<String, u64> =
        serde_json::from_value(v["recording"]["counts"].clone()).expect("recording.counts");
    assert_eq!(counts["outcome"], 20);
    let r = replay(&[
        "foxglove",
        &file.display().to_string(),
        &fox.display().to_string(),
    ]);
    let st = &r["foxglove"];
    let topic = |t: &str| st["topics"][t].as_u64().unwrap_or(u64::MAX);
    assert_eq!(topic("/transmissions"), counts["measurement"], "{st}");
    assert_eq!(topic("/outcomes"), counts["outcome"], "{st}");
    assert_eq!(topic("/trajectories"), counts["outcome"], "{st}");
    assert_eq!(
        topic("/agent"),
        counts["slot"],
        "one /agent update per slot"
    );
    assert_eq!(topic("/scene"), 20, "the map at every episode start");
    assert_eq!(st["episodes"].as_u64(), Some(20));
    assert_eq!(st["incomplete_episodes"].as_u64(), Some(0));
    let size = std::fs::metadata(&fox).expect("the copy exists").len();
    assert_eq!(st["bytes"].as_u64(), Some(size));

    {
        let p = inspect(&fox);
        let channels = p["channels"].as_array().expect("channels");
        assert_eq!(channels.len(), 5, "{p}");
        for c in channels {
            assert_eq!(c["message_encoding"], "json", "{c}");
            assert_eq!(c["schema_encoding"], "jsonschema", "{c}");
            let name = c["schema_name"].as_str().unwrap_or_default();
            assert!(
                name == "foxglove.SceneUpdate" || name == "foxglove.Log",
                "{c}"
            );
        }
        // Every slot's prior (re-run from the recorded inputs: the agent no
        // longer sends it) is drawn as an ellipse with its mean.
        assert_eq!(p["ellipses"].as_u64(), Some(counts["slot"]), "{p}");
        let py: BTreeMap<String, u64> =
            serde_json::from_value(p["counts"].clone()).expect("counts");
        let ours: BTreeMap<String, u64> =
            serde_json::from_value(st["topics"].clone()).expect("topics");
        assert_eq!(py, ours, "python mcap counts == etp's");
        assert_eq!(py["/transmissions"], counts["measurement"]);
        assert_eq!(p["bad_json"].as_u64(), Some(0), "every message is JSON");
        assert_eq!(
            p["time_order"].as_bool(),
            Some(true),
            "written in time order"
        );
        let mut ids: Vec<String> =
            serde_json::from_value(p["trajectory_ids"].clone()).expect("ids");
        ids.sort();
        ids.dedup();
        let want: Vec<String> = {
            let mut w: Vec<String> = (0..20).map(|e| format!("episode-{e}")).collect();
            w.sort();
            w
        };
        assert_eq!(ids, want, "one path entity per episode");
        assert_eq!(
            p["jsonschema"].as_bool(),
            Some(true),
            "the pinned venv has jsonschema"
        );
        assert!(p["validated"].as_u64() > Some(100), "{}", p["validated"]);
        assert_eq!(p["errors"], Value::Array(vec![]), "schema violations");
    }

    // An existing OUT is refused without --force and left untouched.
    let before = b"not yours to overwrite".to_vec();
    std::fs::write(&fox, &before).expect("write");
    let refused = Command::new(bin_dir().join("etp"))
        .args(["replay", "foxglove", &file.display().to_string()])
        .arg(&fox)
        .output()
        .expect("etp replay");
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("already exists"), "{err}");
    assert_eq!(std::fs::read(&fox).expect("still there"), before);
    // With --force it is replaced by the copy.
    let forced = replay(&[
        "foxglove",
        &file.display().to_string(),
        &fox.display().to_string(),
        "--force",
    ]);
    assert_eq!(forced["foxglove"]["topics"], st["topics"]);
    let magic = std::fs::read(&fox).expect("the copy");
    assert!(magic.starts_with(b"\x89MCAP0\r\n"), "an MCAP file");
    let _ = std::fs::remove_file(&file);
    let _ = std::fs::remove_file(&fox);
}
