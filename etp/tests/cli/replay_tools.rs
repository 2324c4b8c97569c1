//! What bag users reach for, on the fixture recording: `--info`, the
//! selection flags (`--topics`, `--episodes`, `--start`/`--end`), `--cat`,
//! `--export` (read back with Python's csv and json modules, no etp code)
//! and `--publish --loop`.

use super::{Scratch, etp, fails_with, ok_json, s};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/fixtures/open-2d-4-episodes.mcap")
}

fn counts(v: &Value) -> BTreeMap<String, u64> {
    serde_json::from_value(v["counts"].clone()).expect("counts")
}

#[test]
fn info_describes_the_fixture() {
    let f = fixture();
    let v = ok_json(&["replay", "info", s(&f), "--json"]);
    let all = ok_json(&["replay", s(&f), "--json"]);
    assert_eq!(v["finished"].as_bool(), Some(true));
    assert_eq!(v["messages"], all["messages"]);
    assert_eq!(v["scenario"].as_str(), Some("open-2d"));
    assert_eq!(v["seed"].as_u64(), Some(7));
    assert_eq!(v["episodes"].as_u64(), Some(4));
    assert_eq!(v["profile"].as_str(), Some("etpareto"));
    let zstd = &v["compression"]["zstd"];
    assert!(zstd["chunks"].as_u64() > Some(0), "{v}");
    assert!(zstd["stored_bytes"].as_u64() < zstd["uncompressed_bytes"].as_u64());
    let d = v["duration_s"].as_f64().expect("duration");
    let (s0, s1) = (
        v["start_ns"].as_u64().expect("start"),
        v["end_ns"].as_u64().expect("end"),
    );
    assert!((d - (s1 - s0) as f64 * 1e-9).abs() < 1e-6 && d > 0.0);
    assert!(
        v["start_time"]
            .as_str()
            .is_some_and(|t| t.ends_with('Z') && t.starts_with("20"))
    );
    let per_channel: u64 = v["channels"]
        .as_array()
        .expect("channels")
        .iter()
        .map(|c| c["messages"].as_u64().expect("messages"))
        .sum();
    assert_eq!(Some(per_channel), all["messages"].as_u64());
    assert!(v["schemas"]["etp::Measurement"].is_string(), "{v}");
    assert!(v["metadata"]["etp.scenario"].is_array(), "{v}");
    let out = etp(&["replay", "info", s(&f)]);
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "duration:",
        "zstd",
        "measurement",
        "etp::Outcome",
        "etp.run",
    ] {
        assert!(text.contains(needle), "{needle} missing in\n{text}");
    }
}

#[test]
fn topics_episodes_and_time_select_messages() {
    let f = fixture();
    let all = ok_json(&["replay", s(&f), "--json"]);
    let only = ok_json(&[
        "replay",
        s(&f),
        "--topics",
        "outcome,sensor/*/handover",
        "--json",
    ]);
    let c = counts(&only);
    assert!(c.contains_key("outcome") && c.keys().any(|k| k.ends_with("/handover")));
    assert!(
        c.keys()
            .all(|k| k == "outcome" || (k.starts_with("sensor/") && k.ends_with("/handover"))),
        "{c:?}"
    );
    for (k, n) in &c {
        assert_eq!(Some(*n), all["counts"][k].as_u64(), "{k}");
    }
    assert_eq!(only["episodes"].as_u64(), Some(4));
    let two = ok_json(&["replay", s(&f), "--episodes", "1..3", "--json"]);
    assert_eq!(two["episodes"].as_u64(), Some(2));
    assert!(two["messages"].as_u64() < all["messages"].as_u64());
    let cat = etp(&["replay", "cat", s(&f), "--episodes", "1..=2"]);
    assert!(cat.status.success());
    for line in String::from_utf8_lossy(&cat.stdout).lines() {
        let v: Value = serde_json::from_str(line).expect("JSON line");
        let e = v["episode"].as_u64().expect("episode");
        assert!((1..=2).contains(&e), "{line}");
    }
    // Time: the whole span selects everything, its second half less.
    let info = ok_json(&["replay", "info", s(&f), "--json"]);
    let d = info["duration_s"].as_f64().expect("duration");
    let whole = ok_json(&[
        "replay",
        s(&f),
        "--start",
        "0",
        "--end",
        &format!("{}", d + 1.0),
        "--json",
    ]);
    assert_eq!(whole["messages"], all["messages"]);
    let half = ok_json(&[
        "replay",
        "info",
        s(&f),
        "--start",
        &format!("{}", d / 2.0),
        "--json",
    ]);
    let n = half["messages"].as_u64().expect("messages");
    assert!(n > 0 && Some(n) < all["messages"].as_u64(), "{n}");
    assert!(
        half["start_ns"].as_u64()
            >= Some(info["start_ns"].as_u64().expect("t0") + (d / 2.0 * 1e9) as u64)
    );
    fails_with(
        &["replay", s(&f), "--topics", "outcomes"],
        &["`outcomes`", "matches no channel"],
    );
    fails_with(&["replay", s(&f), "--episodes", "3..1"], &["empty"]);
    // `verify` re-runs whole recordings: it takes no selection.
    fails_with(
        &["replay", "verify", s(&f), "--episodes", "1..2"],
        &["--episodes"],
    );
}

#[test]
fn cat_prints_every_message_decoded_with_names() {
    let f = fixture();
    let all = ok_json(&["replay", s(&f), "--json"]);
    let out = etp(&["replay", "cat", s(&f)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    assert_eq!(Some(lines.len() as u64), all["messages"].as_u64());
    let times: Vec<u64> = lines
        .iter()
        .map(|l| l["log_time_ns"].as_u64().expect("time"))
        .collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "log-time order");
    let names: Vec<&str> = all["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .filter_map(|x| x["name"].as_str())
        .collect();
    let mut outcomes = 0;
    for l in &lines {
        match l["topic"].as_str() {
            Some("outcome") => {
                outcomes += 1;
                assert!(
                    matches!(l["outcome"].as_str(), Some("target" | "collision" | "free")),
                    "{l}"
                );
                assert_eq!(l["sender"].as_str(), Some("agent"));
                assert!(
                    l["degraded"].is_boolean() && l["dead_sensor"].is_null(),
                    "{l}"
                );
            }
            Some("measurement") => {
                let sender = l["sender"].as_str().expect("sender");
                assert!(names.contains(&sender), "{sender} not in {names:?}");
                assert!(l["y_0"].is_f64(), "{l}");
            }
            Some("control") => {
                assert_eq!(l["sender"].as_str(), Some("coordinator"));
                assert!(matches!(l["kind"].as_str(), Some("start" | "stop")), "{l}");
            }
            _ => {}
        }
    }
    assert_eq!(outcomes, 4);
    // A closed stdout ends it quietly.
    let sh = Command::new("sh")
        .args([
            "-c",
            &format!(
                "{} replay cat {} | head -1",
                env!("CARGO_BIN_EXE_etp"),
                s(&f)
            ),
        ])
        .output()
        .expect("sh");
    assert!(
        sh.status.success() && sh.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&sh.stderr)
    );
}

/// Per-sensor measurement rows and outcomes of an export, read by Python's
/// csv / json modules alone (what a notebook does).
fn python_counts(dir: &Path, format: &str) -> Value {
    let script = r#"
import sys, json, csv, os
d, fmt = sys.argv[1], sys.argv[2]
def rows(name):
    p = os.path.join(d, name + "." + fmt)
    with open(p, newline="") as f:
        if fmt == "csv":
            return list(csv.DictReader(f))
        return [json.loads(l) for l in f]
per_sensor, outcomes = {}, {}
for r in rows("measurement"):
    per_sensor[r["sender"]] = per_sensor.get(r["sender"], 0) + 1
    int(r["episode"]); float(r["y_0"])
for r in rows("outcome"):
    outcomes[r["outcome"]] = outcomes.get(r["outcome"], 0) + 1
ledger = {}
for r in rows("ledger"):
    ledger[r["sender"]] = ledger.get(r["sender"], 0) + int(r["transmissions"])
manifest = json.load(open(os.path.join(d, "tables.json")))
print(json.dumps({"per_sensor": per_sensor, "outcomes": outcomes, "ledger": ledger,
                  "tables": len(manifest["tables"])}))
"#;
    let out = Command::new(crate::pyenv::python())
        .args(["-c", script, s(dir), format])
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "python: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("python JSON")
}

#[test]
fn export_tables_read_by_python_match_the_run_report() {
    let dir = Scratch::new("export");
    let rec = dir.path("run.mcap");
    let run_id = format!("t{}-export", std::process::id());
    let report = ok_json(&[
        "run",
        "--scenario",
        "open-2d",
        "--delta",
        "1.0518",
        "--episodes",
        "3",
        "--seed",
        "3",
        "--predict-episodes",
        "100",
        "--run-id",
        &run_id,
        "--record",
        s(&rec),
        "--json",
    ]);
    let out = dir.path("csv");
    let v = ok_json(&["replay", s(&rec), "--json"]);
    let e = ok_json(&["replay", "export", s(&rec), s(&out), "--json"]);
    assert_eq!(
        e["exported"]["tables"].as_u64(),
        Some(counts(&v).len() as u64)
    );
    assert!(out.join("outcome.csv").is_file() && out.join("sensor-0-truth.csv").is_file());
    let header = std::fs::read_to_string(out.join("measurement.csv")).expect("csv");
    assert!(
        header.starts_with("log_time_ns,run,episode,step,leg,sender,seq,dim,sequence,y_0,"),
        "{header}"
    );
    // Nothing is overwritten without --force.
    fails_with(
        &["replay", "export", s(&rec), s(&out)],
        &["already exists", "--force"],
    );
    ok_json(&["replay", "export", s(&rec), s(&out), "--force", "--json"]);
    let jl = dir.path("jsonl");
    ok_json(&[
        "replay",
        "export",
        s(&rec),
        s(&jl),
        "--format",
        "jsonl",
        "--json",
    ]);
    for (d, fmt) in [(&out, "csv"), (&jl, "jsonl")] {
        let py = python_counts(d, fmt);
        for sensor in report["sensors"].as_array().expect("sensors") {
            let name = sensor["name"].as_str().expect("name");
            let n = py["per_sensor"][name].as_u64().unwrap_or(0);
            assert_eq!(
                Some(n),
                sensor["transmissions"].as_u64(),
                "{fmt}: {name}: {py}"
            );
            assert_eq!(
                py["ledger"][name].as_u64().unwrap_or(0),
                n,
                "{fmt}: {name}: {py}"
            );
        }
        let total: u64 = py["outcomes"]
            .as_object()
            .expect("outcomes")
            .values()
            .filter_map(Value::as_u64)
            .sum();
        assert_eq!(Some(total), report["episodes"].as_u64(), "{py}");
        assert_eq!(py["tables"].as_u64(), Some(counts(&v).len() as u64));
    }
}

#[test]
fn publish_loop_repeats_the_traffic() {
    let f = fixture();
    let run_id = format!("t{}-loop", std::process::id());
    let v = ok_json(&[
        "replay",
        "publish",
        s(&f),
        "--topics",
        "outcome,ledger",
        "--rate",
        "inf",
        "--loop",
        "3",
        "--run-id",
        &run_id,
        "--json",
    ]);
    let n = v["messages"].as_u64().expect("messages");
    assert!(n > 0);
    assert_eq!(v["published"]["messages"].as_u64(), Some(3 * n), "{v}");
    assert_eq!(v["published"]["loops"].as_u64(), Some(3));
    // The old flags are gone: one tool per subcommand.
    fails_with(&["replay", s(&f), "--loop", "2"], &["--loop"]);
    fails_with(&["replay", s(&f), "--publish"], &["--publish"]);
}

#[test]
fn replay_plot_draws_measured_against_predicted() {
    let dir = Scratch::new("replay-plot");
    let f = dir.path("run.mcap");
    std::fs::copy(fixture(), &f).expect("copy fixture");
    let v = ok_json(&["replay", "plot", s(&f), "--json"]);
    let png = dir.path("run-replay.png");
    assert_eq!(v["plot"].as_str(), Some(s(&png)));
    assert!(std::fs::metadata(&png).expect("png").len() > 10_000);
    let svg = std::fs::read_to_string(dir.path("run-replay.svg")).expect("svg");
    for needle in [
        "s0",
        "s4",
        "P_tar",
        "P_coll",
        "measured, 95 % interval",
        "predicted",
    ] {
        assert!(svg.contains(needle), "{needle} missing in the figure");
    }
    let before = std::fs::read(&png).expect("png");
    fails_with(
        &["replay", "plot", s(&f)],
        &["run-replay", "already exists", "--force"],
    );
    assert_eq!(std::fs::read(&png).expect("png"), before);
}

/// The recording decodes outside etp: Python's `mcap` reader and the
/// `struct` format each channel's schema text states unpack every message
/// (sizes agree), and the values are those `--cat` prints.
#[test]
fn schema_text_unpacks_every_message_in_python() {
    let script = r#"
import sys, json, re, struct
from mcap.reader import make_reader
sizes, first = {}, None
with open(sys.argv[1], "rb") as f:
    for schema, channel, msg in make_reader(f).iter_messages():
        fmt = re.search(r'struct\.unpack\("([^"]+)"', schema.data.decode()).group(1)
        assert struct.calcsize(fmt) == len(msg.data), (channel.topic, fmt, len(msg.data))
        vals = struct.unpack(fmt, msg.data)
        sizes[schema.name] = len(msg.data)
        if channel.topic == "measurement" and first is None:
            first = {"episode": vals[1], "step": vals[2], "sender": vals[4], "y_0": vals[8]}
print(json.dumps({"sizes": sizes, "first": first}))
"#;
    let f = fixture();
    let out = Command::new(crate::pyenv::python())
        .args(["-c", script, s(&f)])
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let py: Value = serde_json::from_slice(&out.stdout).expect("json");
    // Every kind of the catalogue has a schema in the fixture (the lossy
    // radio's `ack` included).
    assert_eq!(py["sizes"].as_object().map(|m| m.len()), Some(11), "{py}");
    let cat = etp(&["replay", "cat", s(&f), "--topics", "measurement"]);
    let line: Value = serde_json::from_str(
        String::from_utf8_lossy(&cat.stdout)
            .lines()
            .next()
            .expect("a measurement"),
    )
    .expect("json line");
    let first = &py["first"];
    assert_eq!(first["episode"], line["episode"]);
    assert_eq!(first["step"], line["step"]);
    assert_eq!(first["y_0"].as_f64(), line["y_0"].as_f64());
    assert_eq!(
        line["sender"].as_str(),
        Some(format!("s{}", first["sender"]).as_str())
    );
}
