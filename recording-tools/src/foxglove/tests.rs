//! Tests of the Foxglove copy: the messages against the stored official
//! schemas, and a drain-ordered recording written as a time-ordered copy.

use super::*;
use nalgebra::{Matrix3, Vector3};
use serde_json::Value;

/// Every object the schema describes has its required keys, and each
/// value the schema types is of that type (number, integer, string,
/// boolean, array, object; enums by their `const`s). A small checker of
/// the parts of JSON Schema the Foxglove schemas use, so the test needs
/// no validator crate (the end-to-end test also runs Python's
/// `jsonschema` when it is there).
fn check(schema: &Value, v: &Value, at: &str, errors: &mut Vec<String>) {
    if let Some(options) = schema.get("oneOf").and_then(Value::as_array) {
        if !options.iter().any(|o| o.get("const") == Some(v)) {
            errors.push(format!("{at}: {v} is none of the enum's values"));
        }
        return;
    }
    let ok = match schema.get("type").and_then(Value::as_str) {
        Some("number") => v.is_number(),
        Some("integer") => v.is_u64() || v.is_i64(),
        Some("string") => v.is_string(),
        Some("boolean") => v.is_boolean(),
        Some("array") => v.is_array(),
        Some("object") => v.is_object(),
        _ => true,
    };
    if !ok {
        errors.push(format!("{at}: {v} is not of type {}", schema["type"]));
        return;
    }
    for (k, bound) in [("minimum", 1.0), ("maximum", -1.0)] {
        if let (Some(limit), Some(x)) = (schema.get(k).and_then(Value::as_f64), v.as_f64())
            && (x - limit) * bound < 0.0
        {
            errors.push(format!("{at}: {x} beyond {k} {limit}"));
        }
    }
    if let Some(required) = schema.get("required").and_then(Value::as_array) {
        for r in required.iter().filter_map(Value::as_str) {
            if v.get(r).is_none() {
                errors.push(format!("{at}: required `{r}` missing"));
            }
        }
    }
    if let (Some(props), Some(obj)) = (
        schema.get("properties").and_then(Value::as_object),
        v.as_object(),
    ) {
        for (k, sub) in props {
            if let Some(x) = obj.get(k) {
                check(sub, x, &format!("{at}.{k}"), errors);
            }
        }
        for k in obj.keys().filter(|k| !props.contains_key(*k)) {
            errors.push(format!("{at}: `{k}` is not in the schema"));
        }
    }
    if let (Some(items), Some(arr)) = (schema.get("items"), v.as_array()) {
        for (i, x) in arr.iter().enumerate() {
            check(items, x, &format!("{at}[{i}]"), errors);
        }
    }
}

fn validate(schema_text: &str, m: &impl serde::Serialize) -> Vec<String> {
    let schema: Value = serde_json::from_str(schema_text).expect("schema parses");
    let v = serde_json::to_value(m).expect("message serialises");
    let mut errors = Vec::new();
    check(&schema, &v, "$", &mut errors);
    errors
}

#[test]
fn the_stored_schemas_are_the_foxglove_ones() {
    for (text, title) in [
        (msg::SCENE_UPDATE_SCHEMA, msg::SCENE_UPDATE),
        (msg::LOG_SCHEMA, msg::LOG),
    ] {
        let v: Value = serde_json::from_str(text).expect("schema parses");
        assert_eq!(v["title"], title);
    }
}

fn sample_view(dim: usize) -> AgentView {
    let mut cov = Matrix3::identity() * 0.01;
    cov[(0, 1)] = 0.004;
    cov[(1, 0)] = 0.004;
    AgentView {
        episode: 3,
        step: 17,
        leg: 2,
        dim,
        sensor: Some("s1".into()),
        delta: Some(1.4986),
        truth: Some(Vector3::new(1.0, 2.0, 0.0)),
        prior: Some((Vector3::new(1.1, 2.05, 0.0), cov)),
        transmitted: Some(true),
    }
}

#[test]
fn scene_updates_satisfy_the_scene_update_schema() {
    let t = Time::from_ns(1_700_000_000_123_456_789);
    assert_eq!(
        t,
        Time {
            sec: 1_700_000_000,
            nsec: 123_456_789
        }
    );
    for name in ["winding-2d", "superg-3d", "open-2d"] {
        let s = Scenario::builtin(name).expect("built-in scenario");
        let m = scene::scene(&s, t);
        assert_eq!(m.entities.len(), 4);
        assert_eq!(m.entities[0].cubes.len(), s.obstacles.len());
        let errors = validate(msg::SCENE_UPDATE_SCHEMA, &m);
        assert!(errors.is_empty(), "{name}: {errors:#?}");
    }
    for dim in [2, 3] {
        let m = scene::agent(&sample_view(dim), t);
        let e = &m.entities[0];
        assert_eq!((e.spheres.len(), e.texts.len()), (3, 1));
        let errors = validate(msg::SCENE_UPDATE_SCHEMA, &m);
        assert!(errors.is_empty(), "{errors:#?}");
    }
    let path = [Vector3::zeros(), Vector3::new(1.0, 1.0, 0.0)];
    let m = scene::trajectory(7, &path, Outcome::COLLISION, t);
    assert_eq!(m.entities[0].id, "episode-7");
    assert_eq!(m.entities[0].lines[0].points.len(), 2);
    assert!(validate(msg::SCENE_UPDATE_SCHEMA, &m).is_empty());
    // The checker is not vacuous: a missing required key is found.
    let mut v = serde_json::to_value(&m).expect("serialises");
    v["entities"][0]
        .as_object_mut()
        .expect("object")
        .remove("lifetime");
    v["entities"][0]["lines"][0]["type"] = Value::from(7);
    let mut errors = Vec::new();
    let schema: Value = serde_json::from_str(msg::SCENE_UPDATE_SCHEMA).expect("schema");
    check(&schema, &v, "$", &mut errors);
    assert_eq!(errors.len(), 2, "{errors:#?}");
}

#[test]
fn an_unknown_slot_and_no_prior_still_draw_the_agent() {
    let mut a = sample_view(2);
    a.prior = None;
    a.transmitted = None;
    let m = scene::agent(&a, Time::from_ns(0));
    assert_eq!(m.entities[0].spheres.len(), 1);
    assert!(validate(msg::SCENE_UPDATE_SCHEMA, &m).is_empty());
    a.truth = Some(Vector3::new(f64::NAN, 0.0, 0.0));
    let m = scene::agent(&a, Time::from_ns(0));
    assert!(m.entities[0].spheres.is_empty());
}

#[test]
fn logs_satisfy_the_log_schema() {
    let log = Log {
        timestamp: Time::from_ns(5),
        level: msg::WARNING,
        message: "x".into(),
        name: "s0".into(),
        file: "",
        line: 0,
    };
    let errors = validate(msg::LOG_SCHEMA, &log);
    assert!(errors.is_empty(), "{errors:#?}");
}

/// A recording in the recorder's drain order: episode 0 (3 slots at
/// sensor 1, one transmission, an outcome) whose last truths are stamped
/// after episode 1 has started; episode 1 cut off without an outcome.
fn synthetic() -> Contents {
    use etp_runtime::wire::{agent_to_sensor as a2s, sensor_to_agent as s2a, to_wire_vec};
    let mut c = Contents::default();
    c.metadata.insert(
        recording::META_SCENARIO.into(),
        BTreeMap::from([(
            "toml".into(),
            etp_shared::scenario::builtin_text("winding-2d")
                .expect("built-in")
                .into(),
        )]),
    );
    let h = |episode: u64, step: u32| Header {
        episode,
        step,
        leg: 1,
        sender: 1,
        ..Header::default()
    };
    let mut push = |topic: &str, t: u64, data: Vec<u8>| {
        c.channels.insert(topic.into(), String::new());
        c.messages.push(recording::RawMessage {
            topic: topic.into(),
            sequence: 0,
            log_time: t,
            publish_time: t,
            data,
            encoding: Some(recording::Encoding::Protobuf),
        });
    };
    let enc = |r: Result<Vec<u8>, recording::RecordingError>| r.expect("encodes");
    let truth = |e, k, x: f64| {
        enc(recording::encode(&a2s::Truth {
            header: h(e, k),
            dim: 2,
            _pad: 0,
            x: to_wire_vec(&[x, 1.0]),
        }))
    };
    let handover = |e| {
        enc(recording::encode(&a2s::Handover {
            header: h(e, 0),
            dim: 2,
            ..a2s::Handover::default()
        }))
    };
    let slot = |e, k, sent| {
        enc(recording::encode(&s2a::Slot {
            header: h(e, k),
            delivered: sent,
            attempts: sent,
            prior_digest: 0,
        }))
    };
    push("sensor/1/handover", 101, handover(0));
    for k in 1..=3u32 {
        push("slot", 110 + u64::from(k), slot(0, k, u32::from(k == 2)));
    }
    push(
        "measurement",
        112,
        enc(recording::encode(&s2a::Measurement {
            header: h(0, 2),
            dim: 2,
            sequence: 1,
            y: to_wire_vec(&[2.0, 1.0]),
        })),
    );
    push(
        "outcome",
        120,
        enc(recording::encode(&Outcome {
            header: h(0, 3),
            outcome: Outcome::TARGET,
            steps: 3,
            slots: 3,
            received: 1,
            ..Outcome::default()
        })),
    );
    push("sensor/1/handover", 118, handover(1));
    for k in 1..=3u32 {
        push("sensor/1/truth", 121, truth(0, k, f64::from(k)));
    }
    push("sensor/1/truth", 119, truth(1, 1, 0.5));
    c
}

#[test]
fn a_drain_ordered_recording_becomes_a_time_ordered_copy() {
    let c = synthetic();
    let dir = std::env::temp_dir().join(format!("etp-foxglove-unit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let out = dir.join("copy.mcap");
    let st = write_foxglove(&c, &out, Clock::Recorded).expect("written");
    assert_eq!((st.episodes, st.incomplete_episodes), (1, 1));
    let want = [
        (SCENE, 2),
        (AGENT, 4),
        (TRAJECTORIES, 1),
        (TRANSMISSIONS, 1),
        (OUTCOMES, 1),
    ];
    for (topic, n) in want {
        assert_eq!(st.topics[topic], n, "{topic}: {st:?}");
    }
    let buf = std::fs::read(&out).expect("read back");
    assert_eq!(st.bytes, buf.len() as u64);
    let back = recording::read_lenient("copy", &buf).expect("an MCAP file");
    assert!(back.finished);
    assert_eq!(back.channels[AGENT], msg::SCENE_UPDATE);
    assert_eq!(back.channels[OUTCOMES], msg::LOG);
    let times: Vec<u64> = back.messages.iter().map(|m| m.log_time).collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
    assert_eq!(times.first(), Some(&101), "the map comes first");
    // Episode 0 slot 3 is drawn when its truth arrives (121); its path
    // has the three true positions; slot 2 transmitted (orange).
    let agents: Vec<Value> = back
        .messages
        .iter()
        .filter(|m| m.topic == AGENT)
        .map(|m| serde_json::from_slice(&m.data).expect("JSON"))
        .collect();
    let step = |v: &Value| v["entities"][0]["metadata"][1]["value"].clone();
    let ep0_k2 = agents
        .iter()
        .find(|v| v["entities"][0]["metadata"][0]["value"] == "0" && step(v) == "2")
        .expect("episode 0 slot 2");
    // No prior in this file (no waypoints to re-run from): the truth is the only sphere.
    assert_eq!(ep0_k2["entities"][0]["spheres"][0]["color"]["r"], 1.0);
    assert_eq!(ep0_k2["entities"][0]["timestamp"]["nsec"], 121);
    let path: Value = back
        .messages
        .iter()
        .find(|m| m.topic == TRAJECTORIES)
        .map(|m| serde_json::from_slice(&m.data).expect("JSON"))
        .expect("a path");
    assert_eq!(path["entities"][0]["id"], "episode-0");
    assert_eq!(
        path["entities"][0]["lines"][0]["points"]
            .as_array()
            .map(Vec::len),
        Some(3)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sensor_index_from_topic() {
    assert_eq!(sensor_of_topic("sensor/12/truth"), Some(12));
    assert_eq!(sensor_of_topic("measurement"), None);
    assert_eq!(sensor_of_topic("sensor/x/truth"), None);
    assert_eq!(sensor_of_topic("sensor/1/handover"), None);
}

#[test]
fn the_step_clock_spaces_slots_by_ten_milliseconds_and_episodes_in_sequence() {
    let c = synthetic();
    let dir = std::env::temp_dir().join(format!("etp-foxglove-clock-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let out = dir.join("copy.mcap");
    let st = write_foxglove(&c, &out, Clock::Step).expect("written");
    assert_eq!(st.clock, Clock::Step);
    let back = recording::read_lenient("copy", &std::fs::read(&out).expect("read")).expect("mcap");
    let times: Vec<u64> = back.messages.iter().map(|m| m.log_time).collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
    let t0 = 101; // the earliest recorded time
    let agent_time = |episode: &str, step: &str| {
        back.messages
            .iter()
            .filter(|m| m.topic == AGENT)
            .find(|m| {
                let v: Value = serde_json::from_slice(&m.data).expect("JSON");
                v["entities"][0]["metadata"][0]["value"] == episode
                    && v["entities"][0]["metadata"][1]["value"] == step
            })
            .map(|m| m.log_time)
    };
    assert_eq!(agent_time("0", "1"), Some(t0 + STEP_NS));
    assert_eq!(agent_time("0", "3"), Some(t0 + 3 * STEP_NS));
    // Episode 0 ends at step 3; episode 1 starts two steps later (offset 5).
    assert_eq!(agent_time("1", "1"), Some(t0 + 6 * STEP_NS));
    let outcome = back
        .messages
        .iter()
        .find(|m| m.topic == OUTCOMES)
        .expect("outcome");
    assert_eq!(outcome.log_time, t0 + 3 * STEP_NS);
    let _ = std::fs::remove_dir_all(&dir);
}
