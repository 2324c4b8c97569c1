//! The measured error of a strategy's prediction (docs/MODEL.md §7.3,
//! §7.4) through the real binary: `etp strategy` simulates the chosen
//! strategy and stores predicted − simulated with both sampling errors;
//! `--aggregation-check 0` leaves the file as it was; `etp validate`
//! measures the error again from its own episodes.

use super::schemas::validate;
use super::{Scratch, ok_json, s};
use serde_json::Value;

fn num(v: &Value, path: &[&str]) -> f64 {
    let mut x = v;
    for k in path {
        x = &x[*k];
    }
    x.as_f64()
        .unwrap_or_else(|| panic!("no number at {path:?} in {v}"))
}

fn read(path: &std::path::Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read")).expect("json")
}

#[test]
fn a_strategy_carries_the_measured_error_of_its_prediction() {
    let dir = Scratch::new("strategy-aggregation-error");
    let out = dir.path("open");
    super::certified::synthesize_open(&out);

    // Default: the check runs (4000 episodes) and is stored and reported.
    let checked = out.join("checked.json");
    let sel = ok_json(&[
        "strategy",
        s(&out),
        "--min-target",
        "0.9",
        "-o",
        s(&checked),
        "--json",
    ]);
    validate(&out, "strategy", &sel).expect("strategy --json matches its schema");
    let agg = &sel["aggregation"];
    assert_eq!(agg["episodes"].as_u64(), Some(4000), "{sel}");
    assert_eq!(agg["reference"], "predicted");
    let file = read(&checked);
    // The error is the prediction etp stands by minus the simulated value.
    for q in ["p_target", "p_collision", "energy_mean"] {
        let want = num(&file, &["predicted", q]) - num(&file, &["aggregation", "simulated", q]);
        assert!((num(agg, &["error", q]) - want).abs() < 1e-12, "{q}: {agg}");
        // Its own ± is the prediction's.
        assert_eq!(
            num(&file, &["aggregation", "reference_ci95", q]),
            num(&file, &["predicted_ci95", q])
        );
    }
    let ci = num(&file, &["aggregation", "simulated", "p_target_ci95"]);
    assert!(ci > 0.0 && ci < 0.02, "4000 episodes: ±{ci}");

    // --aggregation-check 0: the same strategy, without the check.
    let plain = out.join("plain.json");
    ok_json(&[
        "strategy",
        s(&out),
        "--min-target",
        "0.9",
        "--aggregation-check",
        "0",
        "-o",
        s(&plain),
        "--json",
    ]);
    let mut a = read(&plain);
    let mut b = file.clone();
    assert!(a.get("aggregation").is_none());
    for v in [&mut a, &mut b] {
        if let Some(m) = v.as_object_mut() {
            m.remove("aggregation");
            m.remove("content_sha256");
        }
    }
    assert_eq!(a, b, "the check changes nothing but its own field");

    // validate measures it again from its own episodes (seed 0, not the
    // check's), against the same reference.
    let v = ok_json(&["validate", s(&checked), "--episodes", "2000", "--json"]);
    let m = &v["error"];
    assert_eq!(m["episodes"].as_u64(), Some(2000), "{v}");
    assert_eq!(m["seed"].as_u64(), Some(0));
    assert_ne!(m["seed"], file["aggregation"]["seed"]);
    assert!(
        (num(m, &["error", "p_target"])
            - (num(&file, &["predicted", "p_target"]) - num(&v, &["p_target"])))
        .abs()
            < 1e-12,
        "{v}"
    );
    // Its interval joins validate's simulation and the prediction's own ±,
    // and so does validate's check of the prediction.
    let own = num(&file, &["predicted_ci95", "p_target"]);
    let both = num(&v, &["p_target_ci95"]).hypot(own);
    assert!(
        (num(m, &["error_ci95", "p_target"]) - both).abs() < 1e-12,
        "{v}"
    );
    let inside = num(m, &["error", "p_target"]).abs() <= both;
    assert_eq!(m["resolved"]["p_target"].as_bool(), Some(!inside));
    let check = v["checks"]
        .as_array()
        .and_then(|c| c.iter().find(|c| c["check"] == "predicted P_tar"))
        .expect("the prediction is checked");
    assert_eq!(check["holds"].as_bool(), Some(inside), "{v}");
}
