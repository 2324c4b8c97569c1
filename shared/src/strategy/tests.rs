use super::*;
use nalgebra::DMatrix;

fn prediction() -> Prediction {
    Prediction {
        p_target: 0.9,
        p_collision: 0.1,
        p_free: 0.0,
        energy_mean: 10.0,
    }
}

#[test]
fn constant_strategy_round_trips_and_checks_the_scenario() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let st = Strategy::constant(&s, 2, Some(prediction()));
    let back = Strategy::from_json(&st.to_json()).expect("round trip");
    assert_eq!(back, st);
    back.policy.check_scenario(&s).expect("same scenario");
    assert_eq!(
        back.policy
            .scenario()
            .expect("built-in by name")
            .content_hash,
        s.content_hash
    );
    let mut tampered = back.clone();
    tampered.policy.scenario_toml = Some(
        crate::scenario::builtin_text("winding-2d")
            .expect("built-in")
            .replace("k_max = 200", "k_max = 201"),
    );
    assert!(matches!(
        tampered.policy.scenario(),
        Err(StrategyError::ScenarioMismatch { .. })
    ));
    let other = Scenario::builtin("open-2d").expect("built-in");
    assert!(matches!(
        back.policy.check_scenario(&other),
        Err(StrategyError::ScenarioMismatch { .. })
    ));
    let cov = DMatrix::identity(2, 2);
    assert_eq!(back.policy.draw(3, &cov, 0.7), 2);
    // One δ edited (still a consistent file on its own): refused, naming the field.
    let mut bent = back.clone();
    bent.policy.deltas[2] = 3.5;
    let bent = Strategy::from_json(&bent.to_json()).expect("consistent on its own");
    let e = bent
        .policy
        .check_scenario(&s)
        .expect_err("δ not in Δ")
        .to_string();
    assert!(e.contains("`deltas`") && e.contains("3.5"), "{e}");
    let mut fewer = back.clone();
    fewer.policy.deltas.pop();
    for st in &mut fewer.policy.states {
        st.omega.pop();
    }
    assert!(matches!(
        fewer.policy.check_scenario(&s),
        Err(StrategyError::Invalid(_))
    ));
}

#[test]
fn corrupted_strategies_are_refused() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let text = Strategy::constant(&s, 0, Some(prediction())).to_json();
    assert!(matches!(
        Strategy::from_json(&text[..text.len() / 2]),
        Err(StrategyError::Parse(_))
    ));
    let bad = text.replacen("\"format_version\": 2", "\"format_version\": 99", 1);
    assert!(matches!(
        Strategy::from_json(&bad),
        Err(StrategyError::Version { .. })
    ));
    let mut broken = Strategy::constant(&s, 0, Some(prediction()));
    broken.policy.states[4].omega[0] = 0.5;
    let bad = broken.to_json();
    assert!(matches!(
        Strategy::from_json(&bad),
        Err(StrategyError::Invalid(_))
    ));
}

#[test]
fn the_whole_file_is_covered_by_its_hash() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let mut st = Strategy::constant(&s, 1, Some(prediction()));
    st.predictions.leg_energy = Some(vec![1.5; s.legs.len()]);
    let text = st.to_json();
    assert!(text.trim_end().ends_with('}'));
    assert_eq!(Strategy::from_sealed_json(&text).expect("sealed"), st);
    // A trailing newline (an editor's) is not an edit.
    Strategy::from_sealed_json(&format!("{text}\n")).expect("trailing newline");
    // Every field is covered, those no other check looks at included.
    for (from, to) in [
        (
            "\"scenario_name\": \"winding-2d\"",
            "\"scenario_name\": \"winding-3d\"",
        ),
        ("\"p_target\": 0.9", "\"p_target\": 0.5"),
        ("\"energy_mean\": 10.0", "\"energy_mean\": 1.0"),
        ("1.5,", "0.5,"),
        ("\"label\": \"constant", "\"label\": \"Constant"),
        (
            "{\n  \"format_version\"",
            "{\n  \"extra\": 1,\n  \"format_version\"",
        ),
    ] {
        assert!(text.contains(from), "{from}");
        let edited = text.replacen(from, to, 1);
        for e in [
            Strategy::from_sealed_json(&edited),
            Strategy::from_json(&edited),
        ] {
            let e = e.expect_err(from).to_string();
            assert!(
                e.contains("changed after it was written") && e.contains("etp strategy"),
                "{e}"
            );
        }
    }
    // Reformatted (the seal no longer the last key as written): refused.
    let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    let compact = serde_json::to_string(&v).expect("JSON");
    assert!(matches!(
        Strategy::from_sealed_json(&compact),
        Err(StrategyError::Tampered(_))
    ));
    // A file written before the seal: refused as a strategy file, saying
    // what to do; accepted where recordings are read.
    let old = serde_json::to_string_pretty(&st).expect("JSON");
    let e = Strategy::from_sealed_json(&old).expect_err("unsealed");
    assert!(matches!(e, StrategyError::Unsealed));
    assert!(e.to_string().contains("etp strategy"), "{e}");
    assert_eq!(Strategy::from_json(&old).expect("recorded, unsealed"), st);
    assert!(matches!(
        Strategy::from_sealed_json("{ not json"),
        Err(StrategyError::Parse(_))
    ));
}

#[test]
fn a_version_1_file_reads_with_its_values_under_diagnostics() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let st = Strategy::constant(&s, 1, Some(prediction()));
    let mut v: serde_json::Value = serde_json::from_str(&st.to_json()).expect("JSON");
    let m = v.as_object_mut().expect("object");
    m.remove("content_sha256");
    m.remove("predicted_ci95");
    m.remove("prediction_basis");
    m.insert("format_version".into(), 1.into());
    let cf = serde_json::json!({"p_target": 0.8, "p_collision": 0.15, "p_free": 0.05, "energy_mean": 11.0});
    m.insert("crossfit".into(), cf);
    let old = serde_json::to_string_pretty(&v).expect("JSON");
    let back = Strategy::from_json(&old).expect("version 1");
    assert_eq!(back.provenance.format_version, STRATEGY_FORMAT_VERSION);
    assert_eq!(back.predictions.predicted, Some(prediction()));
    assert_eq!(back.predictions.prediction_basis, format::VERSION_1_BASIS);
    let d = back.predictions.diagnostics.expect("diagnostics");
    assert_eq!(d.selection.selection_time, Some(prediction()));
    assert_eq!(d.selection.crossfit.map(|c| c.p_target), Some(0.8));
    // Written again, it is a version 2 file that reads as itself.
    let again = Strategy::from_sealed_json(&back_json(&old)).expect("v2");
    assert_eq!(again.provenance.format_version, 2);
}

fn back_json(old: &str) -> String {
    Strategy::from_json(old).expect("v1").to_json()
}

#[test]
fn sampling_follows_the_cdf() {
    let w = [0.0, 0.25, 0.0, 0.75];
    assert_eq!(sample_index(&w, 0.0), 1);
    assert_eq!(sample_index(&w, 0.2499), 1);
    assert_eq!(sample_index(&w, 0.25), 3);
    assert_eq!(sample_index(&w, 0.999_999), 3);
}
