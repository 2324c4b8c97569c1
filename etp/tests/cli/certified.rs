//! Predictions that hold (docs/MODEL.md §4.1, §7.4) through the real binary:
//! front.json carries the certified front; `strategy --confidence` returns a
//! strategy whose bounds, certified on its own on-policy rebuild, meet the
//! request; strategy.json and `validate` carry the prediction etp stands by
//! and, under `diagnostics`, the selection MDP's values.

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
    super::schemas::validate(&out, "strategy", &sel).expect("strategy --json matches its schema");
    assert_eq!(sel["verdict"], "met", "{sel}");
    // The bounds are the rebuild's, and they meet the request.
    let cert = &sel["certified"];
    assert_eq!(cert["covers_aggregation"], true, "{sel}");
    assert!(
        cert["p_target_low"].as_f64().unwrap_or(0.0) >= request,
        "{sel}"
    );
    assert!(sel["predicted"]["p_target"].as_f64().is_some());
    assert!(sel["predicted_ci95"]["p_target"].as_f64().unwrap_or(0.0) > 0.0);
    assert!(
        sel["diagnostics"]["crossfit"]["p_target"]
            .as_f64()
            .is_some()
    );
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&strategy).expect("strategy")).expect("json");
    assert_eq!(file["format_version"], 2);
    assert_eq!(file["certified"]["confidence"].as_f64(), Some(0.95));
    assert!(
        file.get("crossfit").is_none(),
        "one home: under diagnostics"
    );
    assert!(
        file["diagnostics"]["selection"]["crossfit"]["p_target"]
            .as_f64()
            .is_some()
    );

    let v = ok_json(&["validate", s(&strategy), "--episodes", "500", "--json"]);
    let checks = v["checks"].as_array().expect("checks");
    // predicted P_tar, P_coll, energy; certified P_tar, P_coll, energy.
    assert_eq!(checks.len(), 6, "{v}");
    assert!(
        checks.iter().any(|c| c["check"] == "predicted energy"),
        "{v}"
    );
    assert!(
        v["diagnostics"]["optimizer_bias"]["p_target"]
            .as_f64()
            .is_some()
    );

    // Beyond what any strategy reaches: out of reach (exit 7), the closest
    // strategy written with its prediction, stderr saying by how much.
    for extra in [&[][..], &["--confidence", "0.95"][..]] {
        let far = out.join("far.json");
        let mut args = vec!["strategy", s(&out), "--min-target", "0.999"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", s(&far), "--force", "--json"]);
        let o = super::etp(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(7), "{extra:?}: {err}");
        assert!(
            err.contains("out of reach") && err.contains("against P_tar ≥ 0.999"),
            "{err}"
        );
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("the report first");
        assert!(
            matches!(v["verdict"].as_str(), Some("out-of-reach" | "rounds-spent")),
            "{v}"
        );
        let file: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&far).expect("written")).expect("json");
        assert!(
            file["label"]
                .as_str()
                .unwrap_or("")
                .contains("OUT OF REACH")
        );
        assert!(file["predicted"]["p_target"].as_f64().unwrap_or(1.0) < 0.999);
        if !extra.is_empty() {
            assert!(err.contains("certified P_tar ≥"), "{err}");
        }
    }
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
    // --quick: no prediction stored, its biased values under diagnostics.
    let quick = out.join("quick.json");
    let q = ok_json(&[
        "strategy",
        s(&out),
        "--min-target",
        "0.9",
        "--quick",
        "-o",
        s(&quick),
        "--json",
    ]);
    super::schemas::validate(&out, "strategy", &q).expect("quick --json matches its schema");
    assert!(q["predicted"].is_null(), "{q}");
    assert_eq!(q["verdict"], "quick");
    assert!(
        q["diagnostics"]["selection_time"]["p_target"]
            .as_f64()
            .is_some()
    );
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&quick).expect("quick")).expect("json");
    assert!(file["predicted"].is_null());
    // Combinations one parser refuses, writing nothing.
    for bad in [
        vec!["--quick", "--replicates", "3"],
        vec!["--max-collision", "0.1"],
        vec!["--replicates", "1"],
    ] {
        let refused = out.join("refused.json");
        let mut args = vec!["strategy", s(&out), "--min-target", "0.9"];
        if bad[0] == "--max-collision" {
            args.truncate(2);
        }
        args.extend_from_slice(&bad);
        args.extend_from_slice(&["-o", s(&refused)]);
        let o = super::etp(&args);
        assert_eq!(o.status.code(), Some(2), "{bad:?} is a command-line error");
        assert!(!refused.exists());
    }
}
