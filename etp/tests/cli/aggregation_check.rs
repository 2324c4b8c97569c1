//! The measured aggregation error of a strategy (docs/MODEL.md §7.3) through
//! the real binary: `etp strategy` simulates the chosen strategy and stores
//! cross-fitted − simulated; `--aggregation-check 0` leaves the file as it
//! was; `--cover-aggregation` widens the certified bounds by the rule of the
//! model; `etp validate` measures the error again from its own episodes.

use super::schemas::validate;
use super::{Scratch, fails_with, ok_json, s};
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
fn a_strategy_carries_its_measured_aggregation_error_and_can_be_covered_by_it() {
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
    let agg = &sel["predictions"]["aggregation"];
    assert_eq!(agg["episodes"].as_u64(), Some(4000), "{sel}");
    assert_eq!(agg["reference"], "cross-fitted");
    let file = read(&checked);
    // The error is the cross-fitted value minus the simulated one.
    for (q, e) in [
        ("p_target", "p_target"),
        ("p_collision", "p_collision"),
        ("energy_mean", "energy_mean"),
    ] {
        let want = num(&file, &["crossfit", q]) - num(&file, &["aggregation", "simulated", q]);
        assert!((num(agg, &["error", e]) - want).abs() < 1e-12, "{q}: {agg}");
    }
    let ci = num(&file, &["aggregation", "simulated", "p_target_ci95"]);
    assert!(ci > 0.0 && ci < 0.02, "4000 episodes: ±{ci}");
    assert!(file["certified"].get("covers_aggregation").is_none());

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

    // --cover-aggregation: the bounds at (1 + 0.95)/2 widened by the error.
    // A vertex is the same strategy whatever the flags, so its bounds at
    // 0.975 without the check are the ones the widening starts from.
    let covered = out.join("covered.json");
    let sel = ok_json(&[
        "strategy",
        s(&out),
        "--vertex",
        "2",
        "--cover-aggregation",
        "-o",
        s(&covered),
        "--json",
    ]);
    validate(&out, "strategy", &sel).expect("strategy --json matches its schema");
    let cert = &sel["predictions"]["certified"];
    assert_eq!(cert["covers_aggregation"], true, "{sel}");
    assert_eq!(cert["confidence"].as_f64(), Some(0.95));
    let at_split = out.join("at-split.json");
    ok_json(&[
        "strategy",
        s(&out),
        "--vertex",
        "2",
        "--confidence",
        "0.975",
        "--aggregation-check",
        "0",
        "-o",
        s(&at_split),
        "--json",
    ]);
    let (c, u) = (read(&covered), read(&at_split));
    assert_eq!(c["states"], u["states"], "the same strategy");
    let sim = |q: &str| num(&c, &["aggregation", "simulated", q]);
    let xf = |q: &str| num(&c, &["crossfit", q]);
    // The error's half-width: the simulation's and the cross-fitted value's
    // own (stored beside it), in quadrature.
    let half = |q: &str| {
        let own = num(&c, &["crossfit_ci95", q]);
        assert!(
            own > 0.0 || q == "p_collision",
            "{q}: the cross-fit has a spread"
        );
        assert_eq!(num(&c, &["aggregation", "reference_ci95", q]), own);
        sim(&format!("{q}_ci95")).hypot(own)
    };
    // Each part of a covered 0.95 bound is at 0.975, and the one-sided z at
    // 0.975 is the z of the 95 % half-widths: z σ = ci95.
    let widen_tar = (xf("p_target") - sim("p_target") + half("p_target")).max(0.0);
    let widen_coll = (sim("p_collision") - xf("p_collision") + half("p_collision")).max(0.0);
    let widen_e = (sim("energy_mean") - xf("energy_mean") + half("energy_mean")).max(0.0);
    let low = num(&u, &["certified", "p_target_low"]);
    let high = num(&u, &["certified", "p_collision_high"]);
    let e_high = num(&u, &["certified", "energy_high"]);
    assert!(
        (num(&c, &["certified", "p_target_low"]) - (low - widen_tar).max(0.0)).abs() < 1e-9,
        "{c} vs {u}"
    );
    assert!(
        (num(&c, &["certified", "p_collision_high"]) - (high + widen_coll).min(1.0)).abs() < 1e-9
    );
    assert!((num(&c, &["certified", "energy_high"]) - (e_high + widen_e)).abs() < 1e-9);

    // Covering needs the check; nothing is written.
    let refused = out.join("refused.json");
    fails_with(
        &[
            "strategy",
            s(&out),
            "--vertex",
            "2",
            "--cover-aggregation",
            "--aggregation-check",
            "0",
            "-o",
            s(&refused),
        ],
        &["--cover-aggregation", "--aggregation-check"],
    );
    assert!(!refused.exists());

    // validate measures it again from its own episodes (seed 0, not the
    // check's), against the same reference.
    let v = ok_json(&["validate", s(&checked), "--episodes", "2000", "--json"]);
    let m = &v["aggregation_error"];
    assert_eq!(m["episodes"].as_u64(), Some(2000), "{v}");
    assert_eq!(m["seed"].as_u64(), Some(0));
    assert_ne!(m["seed"], file["aggregation"]["seed"]);
    assert!(
        (num(m, &["error", "p_target"]) - (xf_of(&file, "p_target") - num(&v, &["p_target"])))
            .abs()
            < 1e-12,
        "{v}"
    );
    // Its interval joins validate's simulation and the cross-fit's own.
    let own = num(m, &["reference_ci95", "p_target"]);
    assert_eq!(own, num(&file, &["crossfit_ci95", "p_target"]));
    let both = num(&v, &["p_target_ci95"]).hypot(own);
    assert!(
        (num(m, &["error_ci95", "p_target"]) - both).abs() < 1e-12,
        "{v}"
    );
    assert_eq!(
        m["resolved"]["p_target"].as_bool(),
        Some(num(m, &["error", "p_target"]).abs() > both)
    );
}

fn xf_of(v: &Value, q: &str) -> f64 {
    num(v, &["crossfit", q])
}
