//! Predictions that hold (docs/MODEL.md §4.1) through the real binary:
//! front.json carries the certified front; `strategy --confidence` returns a
//! strategy whose certified bounds meet the request; strategy.json and
//! `validate` carry selection-time, cross-fitted and certified values.

use super::{Scratch, fails_with, ok_json, s};

/// A small synthesis of open-2d with a held-out sample into `out`.
pub(super) fn synthesize_open(out: &std::path::Path) {
    ok_json(&[
        "synthesize",
        "open-2d",
        "--samples",
        "1000",
        "--holdout-samples",
        "1000",
        "--seed",
        "3",
        "--no-kf-baseline",
        "-o",
        s(out),
        "--json",
    ]);
}

#[test]
fn certified_strategy_meets_its_bounds_and_reports_all_three_predictions() {
    let dir = Scratch::new("certified");
    let out = dir.path("open");
    synthesize_open(&out);
    let front: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("front.json")).expect("front"))
            .expect("json");
    let vertices = front["vertices"].as_array().map(Vec::len).unwrap_or(0);
    let points = front["certified"]["points"]
        .as_array()
        .expect("certified front");
    assert_eq!(points.len(), vertices);
    assert_eq!(front["certified"]["confidence"].as_f64(), Some(0.95));
    let best_low = points
        .iter()
        .filter_map(|p| p["p_target_low"].as_f64())
        .fold(0.0, f64::max);
    // Each certified lower bound lies below its vertex's nominal P_tar.
    for p in points {
        let k = p["vertex"].as_u64().expect("index") as usize;
        let nominal = front["vertices"][k]["objectives"]["p_target"]
            .as_f64()
            .expect("p_target");
        assert!(p["p_target_low"].as_f64().unwrap_or(2.0) <= nominal + 1e-12);
    }

    let request = best_low - 0.01;
    let r = format!("{request}");
    let strategy = out.join("certified.json");
    let sel = ok_json(&[
        "strategy",
        s(&out),
        "--min-target",
        &r,
        "--confidence",
        "0.95",
        "-o",
        s(&strategy),
        "--json",
    ]);
    let cert = &sel["predictions"]["certified"];
    assert!(
        cert["p_target_low"].as_f64().unwrap_or(0.0) >= request,
        "{sel}"
    );
    assert!(
        sel["predictions"]["crossfit"]["p_target"]
            .as_f64()
            .is_some()
    );
    assert!(
        sel["method"]
            .as_str()
            .unwrap_or("")
            .contains("conservative")
    );
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&strategy).expect("strategy")).expect("json");
    assert_eq!(file["certified"]["confidence"].as_f64(), Some(0.95));
    assert!(file["crossfit"]["p_target"].as_f64().is_some());

    let v = ok_json(&["validate", s(&strategy), "--episodes", "500", "--json"]);
    let checks = v["checks"].as_array().expect("checks");
    assert!(checks.len() >= 7, "{v}");
    assert!(
        v["predictions"]["optimizer_bias"]["p_target"]
            .as_f64()
            .is_some()
    );

    // Beyond the best certified P_tar: refused, naming the best bound.
    fails_with(
        &[
            "strategy",
            s(&out),
            "--min-target",
            "0.999",
            "--confidence",
            "0.95",
            "-o",
            s(&out.join("x.json")),
        ],
        &["certified P_tar lower bound"],
    );
    fails_with(
        &[
            "strategy",
            s(&out),
            "--min-target",
            "0.5",
            "--confidence",
            "1.5",
        ],
        &["--confidence"],
    );
}
