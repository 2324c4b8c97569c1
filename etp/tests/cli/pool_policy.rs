//! On-policy pools (docs/MODEL.md §7.3) through the real binary: `etp
//! synthesize --pool-policy STRATEGY.json` rebuilds on the strategy's bins,
//! deterministically, and a strategy selected on it carries those bins; the
//! flag is refused, naming it and writing nothing, with splitting or with a
//! strategy of another scenario. `--no-carry-state` builds as
//! deterministically and is refused without `--pool-policy`. `etp strategy --evaluate` predicts the
//! conditioning strategy itself on those pools. By default the rebuild
//! simulates only the strategy's own thresholds: fewer segments, the same
//! prediction of the strategy to the bit as the rebuild with
//! `--all-actions`, and selecting another strategy on it is refused.

use super::{Scratch, fails_with, ok_json, s};
use serde_json::Value;

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

/// `etp strategy DIR --min-target 0.9 --on-policy --replicates R -o OUT
/// --json`, its output checked against the schema.
fn on_policy_strategy(dir: &std::path::Path, replicates: &str, out: &std::path::Path) -> Value {
    let v = ok_json(&[
        "strategy",
        s(dir),
        "--min-target",
        "0.9",
        "--on-policy",
        "--replicates",
        replicates,
        "--aggregation-check",
        "0",
        "-o",
        s(out),
        "--json",
    ]);
    super::schemas::validate(dir, "strategy", &v).expect("strategy --json matches its schema");
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
    // --no-carry-state: segments draw their true state from N(x̂, P) instead
    // of starting from the one their particle arrived with; as
    // deterministic, and not the same build.
    let (ca, cb) = (dir.path("carry-a"), dir.path("carry-b"));
    on_policy(&policy, &ca, &["--no-carry-state"]);
    on_policy(&policy, &cb, &["--no-carry-state"]);
    assert_eq!(bytes(&ca), bytes(&cb), "two carried-state builds differ");
    assert_ne!(bytes(&ca), bytes(&a), "the carried state changed nothing");
    let lone = dir.path("carry-alone");
    fails_with(
        &["synthesize", "open-2d", "--no-carry-state", "-o", s(&lone)],
        &["--pool-policy"],
    );
    assert!(!lone.join("mdp.bin").exists());

    // Only the strategy's thresholds (the default): its front is not the
    // scenario's, so selecting on it is refused, naming the way out.
    refused(
        &a,
        &["--min-target", "0.9"],
        &["--evaluate", "--all-actions"],
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

    // --evaluate: the conditioning strategy itself, predicted on its own
    // pools: the same ω and states (it behaves exactly as before), new
    // predictions with the cross-fit's own sampling error.
    let evaluated = a.join("evaluated.json");
    let v = ok_json(&[
        "strategy",
        s(&a),
        "--evaluate",
        s(&policy),
        "--aggregation-check",
        "0",
        "-o",
        s(&evaluated),
        "--json",
    ]);
    super::schemas::validate(&a, "strategy", &v).expect("strategy --json matches its schema");
    let (e, p) = (read(&evaluated), read(&policy));
    for field in ["states", "discretization", "deltas", "scenario_hash"] {
        assert_eq!(e[field], p[field], "{field}");
    }
    assert!(
        e["label"].as_str().unwrap_or("").contains("evaluated on"),
        "{e}"
    );
    assert_ne!(e["crossfit"], p["crossfit"], "predicted on the other MDP");
    assert!(e["crossfit_ci95"]["p_target"].as_f64().unwrap_or(0.0) > 0.0);
    // The same strategy on the rebuild with every threshold: states are
    // keyed by region, so its own thresholds drew the same segments there,
    // and the selection-time prediction is the same to the bit (the
    // others' arrivals only add states the strategy does not reach).
    let on_full = full.join("evaluated.json");
    ok_json(&[
        "strategy",
        s(&full),
        "--evaluate",
        s(&policy),
        "--aggregation-check",
        "0",
        "-o",
        s(&on_full),
        "--json",
    ]);
    assert_eq!(e["predicted"], read(&on_full)["predicted"]);

    // `strategy --on-policy`: the selection and the rebuild in one command,
    // with DIR's settings and seed: the numbers of the two-step way (up to
    // the last bit of ω through the file).
    let one = base.join("on-policy.json");
    let v = on_policy_strategy(&base, "1", &one);
    assert!(v["on_policy"]["segments"].as_u64().unwrap_or(0) > 0, "{v}");
    let o = read(&one);
    for (field, key) in [
        ("predicted", "p_target"),
        ("crossfit", "p_target"),
        ("crossfit", "p_collision"),
        ("crossfit_ci95", "p_target"),
        ("certified", "p_target_low"),
    ] {
        let (x, y) = (o[field][key].as_f64(), e[field][key].as_f64());
        assert!(
            matches!((x, y), (Some(x), Some(y)) if (x - y).abs() < 1e-12),
            "{field}.{key}: {x:?} vs {y:?}"
        );
    }
    assert!(o["label"].as_str().unwrap_or("").contains("own pools"));

    // --replicates 3: rebuilds with seeds 3, 4, 5 (DIR's + r); the first is
    // the rebuild above, the cross-fitted value their mean, its ± Student's
    // t on 2 degrees of freedom over their spread.
    let three = base.join("on-policy-3.json");
    let v = on_policy_strategy(&base, "3", &three);
    let reps = v["on_policy"]["replicates"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    let seeds: Vec<u64> = reps.iter().filter_map(|r| r["seed"].as_u64()).collect();
    assert_eq!(seeds, [3, 4, 5], "{v}");
    let tar: Vec<f64> = reps
        .iter()
        .filter_map(|r| r["crossfit"]["p_target"].as_f64())
        .collect();
    assert_eq!(tar.len(), 3, "{v}");
    let close = |x: Option<f64>, y: f64| x.is_some_and(|x| (x - y).abs() < 1e-12);
    assert!(close(o["crossfit"]["p_target"].as_f64(), tar[0]));
    let mean = tar.iter().sum::<f64>() / 3.0;
    let sd = (tar.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / 2.0).sqrt();
    let r3 = read(&three);
    assert!(close(r3["crossfit"]["p_target"].as_f64(), mean), "{r3}");
    let half = r3["crossfit_ci95"]["p_target"].as_f64().unwrap_or(-1.0);
    assert!(
        (half - 4.302_653 * sd / 3f64.sqrt()).abs() < 1e-6 * sd.max(1e-9),
        "{half} vs sd {sd}"
    );
    // The seeds differ: so do the replicates (a spread to measure).
    assert!(sd > 0.0, "{tar:?}");
    refused(
        &base,
        &["--min-target", "0.9", "--replicates", "3"],
        &["--on-policy"],
    );
    refused(
        &base,
        &["--min-target", "0.9", "--confidence", "0.95", "--on-policy"],
        &["--on-policy", "--confidence"],
    );
    let sim = |f: &std::path::Path| {
        ok_json(&["validate", s(f), "--episodes", "300", "--json"])["p_target"].clone()
    };
    assert_eq!(
        sim(&evaluated),
        sim(&policy),
        "the same strategy, the same episodes"
    );
    let not_a_strategy = a.join("mdp.bin");
    refused(&a, &["--evaluate", s(&not_a_strategy)], &["--evaluate"]);
    refused(
        &a,
        &["--evaluate", s(&policy), "--min-target", "0.9"],
        &["--evaluate", "--min-target"],
    );

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
