//! Every command's `--json` against its published JSON Schema (`schemas/`,
//! validated by Python's `jsonschema`), and the shared vocabulary: the same
//! key has the same value across commands that describe the same run.

use super::{Scratch, ok_json, s};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn schema(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../schemas/{name}.json"))
}

/// Validate `doc` against `schemas/<name>.json`; the validator's complaint on failure.
fn validate(dir: &Path, name: &str, doc: &Value) -> Result<(), String> {
    let file = dir.join(format!("{name}-output.json"));
    std::fs::write(&file, doc.to_string()).expect("write output");
    let script = r#"
import sys, json, jsonschema
schema = json.load(open(sys.argv[1]))
jsonschema.Draft202012Validator.check_schema(schema)
errors = sorted(jsonschema.Draft202012Validator(schema).iter_errors(json.load(open(sys.argv[2]))), key=str)
for e in errors:
    print(list(e.absolute_path), e.message)
sys.exit(1 if errors else 0)
"#;
    let out = Command::new(crate::pyenv::python())
        .args(["-c", script, s(&schema(name)), s(&file)])
        .output()
        .expect("python3");
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ))
    }
}

#[test]
fn every_command_json_matches_its_schema_and_the_vocabulary() {
    let dir = Scratch::new("schemas");
    let rec = dir.path("run.mcap");
    let run_id = format!("t{}-schemas", std::process::id());
    let run = ok_json(&[
        "run",
        "--scenario",
        "open-2d",
        "--delta",
        "1.0518",
        "--episodes",
        "2",
        "--seed",
        "5",
        "--predict-episodes",
        "100",
        "--run-id",
        &run_id,
        "--record",
        s(&rec),
        "--json",
    ]);
    let replay = ok_json(&["replay", s(&rec), "--json"]);
    let info = ok_json(&["replay", s(&rec), "--info", "--json"]);
    let sim = ok_json(&[
        "simulate",
        "open-2d",
        "--delta",
        "1.0518",
        "--episodes",
        "20",
        "--seed",
        "5",
        "--json",
    ]);
    // The recorded strategy, through the export's tables.json (metadata).
    let tables = dir.path("tables");
    ok_json(&[
        "replay",
        s(&rec),
        "--topics",
        "outcome",
        "--export",
        s(&tables),
        "--json",
    ]);
    let manifest: Value = serde_json::from_str(
        &std::fs::read_to_string(tables.join("tables.json")).expect("tables.json"),
    )
    .expect("json");
    let strategy = dir.path("strategy.json");
    std::fs::write(
        &strategy,
        manifest["metadata"]["etp.strategy"]["json"]
            .as_str()
            .expect("strategy"),
    )
    .expect("write strategy");
    let val = ok_json(&[
        "validate",
        s(&strategy),
        "--episodes",
        "20",
        "--seed",
        "5",
        "--json",
    ]);

    // One vocabulary: identity and sensors agree across the commands.
    for (what, v) in [
        ("run", &run),
        ("replay", &replay),
        ("simulate", &sim),
        ("validate", &val),
    ] {
        assert_eq!(v["scenario"].as_str(), Some("open-2d"), "{what}");
        assert_eq!(v["seed"].as_u64(), Some(5), "{what}: seed is a number");
        assert_eq!(v["delta"].as_f64(), Some(1.0518), "{what}");
        assert!(v["strategy"].is_string(), "{what}");
        let names: Vec<&str> = v["sensors"]
            .as_array()
            .expect("sensors")
            .iter()
            .filter_map(|x| x["name"].as_str())
            .collect();
        assert_eq!(
            names,
            ["s0", "s1", "s2", "s3", "s4"],
            "{what}: every sensor, by name"
        );
        assert!(v["transmissions"].as_u64().is_some(), "{what}");
    }
    assert_eq!(run["transmissions"], replay["transmissions"]);
    assert_eq!(run["received"], replay["received"]);
    assert_eq!(run["strategy"], replay["strategy"]);
    assert_eq!(info["format_version"], replay["format_version"]);
    for (name, v) in [
        ("run", &run),
        ("replay", &replay),
        ("replay-info", &info),
        ("simulate", &sim),
        ("validate", &val),
    ] {
        validate(&dir.0, name, v)
            .unwrap_or_else(|e| panic!("etp {name} --json against schemas/{name}.json:\n{e}\n{v}"));
    }
    // The schemas can fail: a seed given as a string is refused.
    let mut bad = replay.clone();
    bad["seed"] = Value::from("5");
    assert!(validate(&dir.0, "replay", &bad).is_err());
}
