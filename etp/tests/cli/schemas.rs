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
pub(super) fn validate(dir: &Path, name: &str, doc: &Value) -> Result<(), String> {
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
    let info = ok_json(&["replay", "info", s(&rec), "--json"]);
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
        "export",
        s(&rec),
        s(&tables),
        "--topics",
        "outcome",
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
        // One name for the total plant steps (was `total_steps` in
        // simulate/validate), intervals where run has them.
        assert!(v["steps"].as_u64().is_some_and(|n| n > 0), "{what}: steps");
        assert!(v.get("total_steps").is_none(), "{what}");
        for k in ["p_target_ci95", "energy_mean_ci95"] {
            assert!(v[k].as_f64().is_some(), "{what}: {k}");
        }
    }
    for (i, s) in replay["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .enumerate()
    {
        assert_eq!(s["received"], run["sensors"][i]["received"], "{s}");
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

/// `check`, `synthesize`, `strategy`, `bench` and `demo` against their
/// schemas; every schema in `schemas/` is exercised by one of these two
/// tests, and every schema is strict (an unknown key is refused) and
/// describes every field it declares.
#[test]
fn the_pipeline_commands_json_match_their_strict_described_schemas() {
    let dir = Scratch::new("schemas-pipeline");
    let syn = dir.path("syn");
    let check = ok_json(&["check", "open-2d", "--json"]);
    let synthesize = ok_json(&[
        "synthesize",
        "open-2d",
        "--samples",
        "200",
        "--holdout-samples",
        "0",
        "-o",
        s(&syn),
        "--json",
    ]);
    // Adaptive splitting's report (one round at least, whatever it finds).
    let split = ok_json(&[
        "synthesize",
        "open-2d",
        "--samples",
        "200",
        "--holdout-samples",
        "0",
        "--aggregation-episodes",
        "0",
        "--split-budget",
        "2",
        "--split-rounds",
        "1",
        "--split-episodes",
        "500",
        "-o",
        s(&dir.path("syn-split")),
        "--json",
    ]);
    assert_eq!(
        split["mdp"]["split"]["rounds"].as_array().map(Vec::len),
        Some(1),
        "{split}"
    );
    assert!(
        synthesize["mdp"]["split"].is_null(),
        "splitting is off by default"
    );
    let strategy = ok_json(&["strategy", s(&syn), "--min-target", "0.5", "--json"]);
    let strategy_front = ok_json(&["strategy", "front", s(&syn), "--points", "2", "--json"]);
    let bench = ok_json(&[
        "bench",
        "open-2d",
        "--episodes",
        "20",
        "--repeats",
        "1",
        "--json",
    ]);
    // Run in the scratch folder: were the demo to write outside `-o`
    // (`recordings/` of its working folder), it would show there.
    let demo_out = Command::new(env!("CARGO_BIN_EXE_etp"))
        .args([
            "demo",
            "--scenario",
            "open-2d",
            "--samples",
            "200",
            "--min-target",
            "0.5",
            "--validate-episodes",
            "40",
            "--run-episodes",
            "3",
            "-o",
            s(&dir.path("demo")),
            "--json",
        ])
        .current_dir(&dir.0)
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .expect("spawn etp demo");
    assert!(
        demo_out.status.success(),
        "etp demo: {}",
        String::from_utf8_lossy(&demo_out.stderr)
    );
    let demo: Value = serde_json::from_slice(&demo_out.stdout).expect("demo prints one JSON value");
    // Every output where `-o` said, the recording too.
    let recording = PathBuf::from(
        demo["multi_process"]["recording"]["path"]
            .as_str()
            .expect("the demo's recording"),
    );
    assert_eq!(recording, dir.path("demo").join("run.mcap"), "{demo}");
    assert!(recording.is_file());
    assert!(
        !dir.path("recordings").exists(),
        "the demo wrote outside its -o folder"
    );
    let docs = [
        ("check", &check),
        ("synthesize", &synthesize),
        ("synthesize", &split),
        ("strategy", &strategy),
        ("strategy-front", &strategy_front),
        ("bench", &bench),
        ("demo", &demo),
    ];
    for (name, v) in docs {
        validate(&dir.0, name, v)
            .unwrap_or_else(|e| panic!("etp {name} --json against schemas/{name}.json:\n{e}\n{v}"));
    }
    // The multi-process part of the demo is a run report.
    validate(&dir.0, "run", &demo["multi_process"]).expect("demo's run against run.json");
    // Every schema is one of the tested commands'.
    let tested = [
        "run",
        "replay",
        "replay-info",
        "simulate",
        "validate",
        "check",
        "synthesize",
        "strategy",
        "strategy-front",
        "bench",
        "demo",
        "fronts",
        "compare",
        "trigger-curves",
        // `etp study`'s table: validated in study.rs
        // (`a_study_case_is_what_the_commands_make`).
        "study",
    ];
    let root = schema("x").parent().expect("schemas/").to_path_buf();
    let mut files: Vec<String> = std::fs::read_dir(&root)
        .expect("schemas/")
        .filter_map(|e| {
            e.ok()?
                .file_name()
                .to_str()?
                .strip_suffix(".json")
                .map(str::to_string)
        })
        .collect();
    files.sort();
    let mut want: Vec<String> = tested.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(
        files, want,
        "a schema without a test, or a test without a schema"
    );
    // Strict for real: an unknown key is refused.
    let mut extra = check.clone();
    extra["colour"] = Value::from("blue");
    assert!(validate(&dir.0, "check", &extra).is_err());
}

/// Strict and described: every object with properties refuses other keys,
/// and every declared property, in variants (`oneOf`, …) and definitions
/// too, has a description — every schema of `schemas/`, without running a
/// command.
#[test]
fn every_schema_is_strict_and_every_property_described() {
    fn walk(v: &Value, at: &str, bad: &mut Vec<String>) {
        if let Some(props) = v.get("properties").and_then(Value::as_object) {
            if v.get("additionalProperties") != Some(&Value::Bool(false)) {
                bad.push(format!("{at}: additionalProperties is not false"));
            }
            for (k, p) in props {
                if !p.get("description").is_some_and(Value::is_string) {
                    bad.push(format!("{at}.{k}: no description"));
                }
                walk(p, &format!("{at}.{k}"), bad);
            }
        }
        if let Some(items) = v.get("items") {
            walk(items, &format!("{at}[]"), bad);
        }
        for key in ["oneOf", "anyOf", "allOf"] {
            let variants = v.get(key).and_then(Value::as_array).into_iter().flatten();
            for (i, variant) in variants.enumerate() {
                walk(variant, &format!("{at}/{key}[{i}]"), bad);
            }
        }
        for key in ["$defs", "definitions", "patternProperties"] {
            for (k, def) in v.get(key).and_then(Value::as_object).into_iter().flatten() {
                walk(def, &format!("{at}/{key}/{k}"), bad);
            }
        }
        if let Some(extra) = v.get("additionalProperties").filter(|x| x.is_object()) {
            walk(extra, &format!("{at}/additionalProperties"), bad);
        }
    }
    let root = schema("x").parent().expect("schemas/").to_path_buf();
    let mut bad = Vec::new();
    let mut seen = 0;
    for e in std::fs::read_dir(&root).expect("schemas/").flatten() {
        let path = e.path();
        if path.extension().and_then(|x| x.to_str()) != Some("json") {
            continue;
        }
        let text = std::fs::read_to_string(&path).expect("schema");
        let v: Value = serde_json::from_str(&text).expect("schema JSON");
        walk(&v, &e.file_name().to_string_lossy(), &mut bad);
        seen += 1;
    }
    assert!(seen >= 10, "only {seen} schemas in {}", root.display());
    assert!(bad.is_empty(), "{bad:#?}");
}
