//! On-policy pools (docs/MODEL.md §7.3) through the real binary: `etp
//! synthesize --pool-policy STRATEGY.json` rebuilds on the strategy's bins,
//! deterministically, and a strategy selected on it carries those bins; the
//! flag is refused, naming it and writing nothing, with splitting or with a
//! strategy of another scenario. By default the rebuild simulates only the
//! strategy's own thresholds (fewer segments) and selecting another strategy
//! on it is refused. `etp strategy evaluate` predicts a strategy from such
//! rebuilds, the same bits as the default `etp strategy`'s prediction of it.

use super::{Scratch, fails_with, ok_json, s};
use serde_json::Value;

/// The same JSON, numbers equal within 1e-12 (relative above 1).
fn close_json(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => (x - y).abs() <= 1e-12 * x.abs().max(1.0),
            _ => x == y,
        },
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| close_json(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| close_json(v, w)))
        }
        _ => a == b,
    }
}

fn read(path: &std::path::Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read")).expect("json")
}

/// `etp strategy DIR ARGS -o DIR/refused.json` fails naming `needles`, and
/// writes nothing.
fn refused(dir: &std::path::Path, args: &[&str], needles: &[&str]) {
    let out = dir.join("refused.json");
    let mut all = vec!["strategy", s(dir)];
    all.extend_from_slice(args);
    all.extend_from_slice(&["-o", s(&out)]);
    fails_with(&all, needles);
    assert!(!out.exists(), "{args:?} wrote {}", out.display());
}

/// `etp strategy evaluate POLICY DIR --replicates R -o OUT --json`, its
/// output checked against the schema.
fn evaluate(
    policy: &std::path::Path,
    dir: &std::path::Path,
    replicates: &str,
    out: &std::path::Path,
) -> Value {
    let v = ok_json(&[
        "strategy",
        "evaluate",
        s(policy),
        s(dir),
        "--replicates",
        replicates,
        "--aggregation-check",
        "0",
        "-o",
        s(out),
        "--json",
    ]);
    super::schemas::validate(dir, "strategy", &v)
        .expect("strategy evaluate --json matches its schema");
    v
}

/// `etp synthesize open-2d --pool-policy POLICY … -o OUT EXTRA…` (small, fixed seed).
fn on_policy_args<'a>(
    policy: &'a std::path::Path,
    out: &'a std::path::Path,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec![
        "synthesize",
        "open-2d",
        "--pool-policy",
        s(policy),
        "--samples",
        "1000",
        "--holdout-samples",
        "1000",
        "--seed",
        "3",
        "--no-kf-baseline",
        "--aggregation-episodes",
        "0",
        "-o",
        s(out),
    ];
    args.extend_from_slice(extra);
    args
}

/// [`on_policy_args`] with `--json`: its report.
fn on_policy(policy: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> Value {
    let mut args = on_policy_args(policy, out, extra);
    args.push("--json");
    ok_json(&args)
}

#[test]
fn pools_drawn_on_policy_rebuild_on_the_strategys_bins_and_refuse_what_does_not_fit() {
    let dir = Scratch::new("pool-policy");
    let base = dir.path("open");
    super::certified::synthesize_open(&base);
    let policy = base.join("policy.json");
    ok_json(&[
        "strategy",
        s(&base),
        "--min-target",
        "0.9",
        "--aggregation-check",
        "0",
        "-o",
        s(&policy),
        "--json",
    ]);

    let (a, b) = (dir.path("op-a"), dir.path("op-b"));
    let report = on_policy(&policy, &a, &[]);
    assert!(
        report["mdp"]["states"].as_u64().unwrap_or(0) > 0,
        "{report}"
    );
    on_policy(&policy, &b, &[]);
    // Weighted reservoirs do not depend on threads or order: the same bits.
    let bytes = |d: &std::path::Path| std::fs::read(d.join("mdp.bin")).expect("mdp.bin");
    assert_eq!(bytes(&a), bytes(&b), "two on-policy builds differ");
    // The pools moved: not the unweighted build of the same bins.
    assert_ne!(bytes(&a), bytes(&base), "the policy changed nothing");
    // The text report: the front is not the scenario's, and what was written.
    let text = dir.path("op-text");
    let out = super::etp(&on_policy_args(&policy, &text, &[]));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(
        stdout.contains("this front is not the scenario's"),
        "{stdout}"
    );
    assert!(
        stdout.contains(&format!("wrote {}", text.join("front.json").display())),
        "{stdout}"
    );
    // Only the strategy's thresholds (the default): its front is not the
    // scenario's, so selecting on it is refused, naming the way out.
    refused(
        &a,
        &["--min-target", "0.9"],
        &["strategy evaluate", "--all-actions"],
    );
    // With every threshold the same pools serve a new selection, which
    // classifies with the conditioning strategy's bins.
    let full = dir.path("op-full");
    let full_report = on_policy(&policy, &full, &["--all-actions"]);
    let mdp_n = |r: &Value, k: &str| r["mdp"][k].as_u64().unwrap_or(0);
    assert!(
        mdp_n(&report, "segments") * 2 < mdp_n(&full_report, "segments"),
        "{report} {full_report}"
    );
    assert!(mdp_n(&report, "choices") < mdp_n(&full_report, "choices"));
    let again = full.join("s.json");
    ok_json(&[
        "strategy",
        s(&full),
        "--min-target",
        "0.9",
        "--quick",
        "--aggregation-check",
        "0",
        "-o",
        s(&again),
        "--json",
    ]);
    assert_eq!(
        read(&again)["discretization"],
        read(&policy)["discretization"]
    );

    // `etp strategy evaluate`: the strategy itself (same ω, states, bins)
    // predicted on DIR's settings and seeds; the default `etp strategy`
    // made the same rebuilds of it, so the prediction is the same to the bit.
    let evaluated = base.join("evaluated.json");
    let v = evaluate(&policy, &base, "4", &evaluated);
    assert_eq!(v["verdict"], "evaluated", "{v}");
    let (e, p) = (read(&evaluated), read(&policy));
    for field in ["states", "discretization", "deltas", "scenario_hash"] {
        assert_eq!(e[field], p[field], "{field}");
    }
    assert!(
        e["label"].as_str().unwrap_or("").contains("predicted on"),
        "{e}"
    );
    // ω goes through the file's decimal text, so equal up to rounding.
    for field in ["predicted", "predicted_ci95", "certified"] {
        assert!(
            close_json(&e[field], &p[field]),
            "{field}: {} vs {}",
            e[field],
            p[field]
        );
    }
    assert!(close_json(
        &e["diagnostics"]["rebuilds"],
        &p["diagnostics"]["rebuilds"]
    ));

    // --replicates 3: rebuilds with seeds 3, 4, 5 (DIR's + r); the
    // prediction is their mean cross-fitted value, its ± Student's t on 2
    // degrees of freedom over their spread.
    let three = base.join("evaluated-3.json");
    evaluate(&policy, &base, "3", &three);
    let r3 = read(&three);
    let reps = r3["diagnostics"]["rebuilds"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    let seeds: Vec<u64> = reps.iter().filter_map(|r| r["seed"].as_u64()).collect();
    assert_eq!(seeds, [3, 4, 5], "{r3}");
    let tar: Vec<f64> = reps
        .iter()
        .filter_map(|r| r["crossfit"]["p_target"].as_f64())
        .collect();
    assert_eq!(tar.len(), 3, "{r3}");
    // The first rebuild is `synthesize --pool-policy`'s build (same settings
    // and seed): as many states; and replicate r does not depend on R.
    assert_eq!(
        v["diagnostics"]["rebuild"]["states"], report["mdp"]["states"],
        "{v}"
    );
    assert_eq!(reps[0], e["diagnostics"]["rebuilds"][0]);
    let close = |x: Option<f64>, y: f64| x.is_some_and(|x| (x - y).abs() < 1e-12);
    let mean = tar.iter().sum::<f64>() / 3.0;
    let sd = (tar.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / 2.0).sqrt();
    assert!(close(r3["predicted"]["p_target"].as_f64(), mean), "{r3}");
    let half = r3["predicted_ci95"]["p_target"].as_f64().unwrap_or(-1.0);
    assert!(
        (half - 4.302_653 * sd / 3f64.sqrt()).abs() < 1e-6 * sd.max(1e-9),
        "{half} vs sd {sd}"
    );
    // The seeds differ: so do the replicates (a spread to measure).
    assert!(sd > 0.0, "{tar:?}");
    // One rebuild is no prediction: refused by the parser, nothing written.
    let one = base.join("one.json");
    let o = super::etp(&[
        "strategy",
        "evaluate",
        s(&policy),
        s(&base),
        "--replicates",
        "1",
        "-o",
        s(&one),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!one.exists());
    let sim = |f: &std::path::Path| {
        ok_json(&["validate", s(f), "--episodes", "300", "--json"])["p_target"].clone()
    };
    assert_eq!(
        sim(&evaluated),
        sim(&policy),
        "the same strategy, the same episodes"
    );
    let not_a_strategy = a.join("mdp.bin");
    let x = base.join("x.json");
    fails_with(
        &[
            "strategy",
            "evaluate",
            s(&not_a_strategy),
            s(&base),
            "-o",
            s(&x),
        ],
        &["etp strategy evaluate", "mdp.bin"],
    );
    assert!(!x.exists());

    // Refused, naming the flag, nothing written.
    let split = dir.path("op-split");
    fails_with(
        &[
            "synthesize",
            "open-2d",
            "--pool-policy",
            s(&policy),
            "--split-budget",
            "10",
            "-o",
            s(&split),
        ],
        &["--pool-policy", "--split-budget"],
    );
    assert!(!split.join("mdp.bin").exists());
    let other = dir.path("op-other");
    fails_with(
        &[
            "synthesize",
            "winding-2d",
            "--pool-policy",
            s(&policy),
            "-o",
            s(&other),
        ],
        &["--pool-policy", "not a strategy of winding-2d"],
    );
    assert!(!other.join("mdp.bin").exists());
}
