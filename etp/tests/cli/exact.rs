//! Exact strategies and a reproducible front, through the real binary:
//! * `strategy`'s predicted energy agrees with an independent solution of the
//!   same constrained query — our own parser of the PRISM export and SciPy's
//!   HiGHS (`occupation_lp.py`) — to 1e-8 relative, on every built-in scenario;
//! * `front.json`, the front plots and `strategy.json` are byte-identical on 1
//!   and 2 threads.
//!
//! The properties hold for any sample count, so the MDPs are small.

use super::{Scratch, etp_threads, s};
use serde_json::Value;
use std::path::Path;
use std::process::Command;

fn run_ok(args: &[&str], threads: &str) -> Vec<u8> {
    let out = etp_threads(args, threads);
    assert!(
        out.status.success(),
        "etp {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// The least energy of each query by the independent solver (None: infeasible).
fn independent(prism: &Path, queries: &[String]) -> Vec<Option<f64>> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/cli/occupation_lp.py");
    let out = Command::new(crate::pyenv::python())
        .arg(script)
        .arg(prism)
        .args(queries)
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "occupation_lp.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Vec<Option<f64>> = serde_json::from_slice(&out.stdout).expect("a JSON list");
    assert_eq!(v.len(), queries.len());
    v
}

#[test]
fn strategy_energy_agrees_with_an_independent_lp_on_every_scenario() {
    let scratch = Scratch::new("exact-parity");
    for name in ["winding-2d", "open-2d", "superg-3d"] {
        let dir = scratch.path(name);
        run_ok(
            &[
                "synthesize",
                name,
                "--samples",
                "150",
                "--seed",
                "5",
                "--no-kf-baseline",
                "-o",
                s(&dir),
            ],
            "2",
        );
        let prism = dir.join("prism");
        run_ok(&["export-prism", s(&dir), s(&prism)], "2");
        let front: Value =
            serde_json::from_slice(&std::fs::read(dir.join("front.json")).expect("front.json"))
                .expect("json");
        let targets: Vec<f64> = front["vertices"]
            .as_array()
            .expect("vertices")
            .iter()
            .filter_map(|v| v["objectives"]["p_target"].as_f64())
            .collect();
        let (lo, hi) = targets
            .iter()
            .fold((1.0_f64, 0.0_f64), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        // Targets across the front, each alone and with a collision bound
        // between the least-energy strategy's P_coll and a tighter one.
        let mut queries = Vec::new();
        let mut ours = Vec::new();
        for frac in [0.2, 0.6, 0.9, 0.99] {
            let p = lo + frac * (hi - lo);
            let out = dir.join("s.json");
            let free: Value = serde_json::from_slice(&run_ok(
                &[
                    "strategy",
                    s(&dir),
                    "--min-target",
                    &p.to_string(),
                    "--quick",
                    "-o",
                    s(&out),
                    "--force",
                    "--json",
                ],
                "2",
            ))
            .expect("json");
            // The LP's optimum on this MDP: the exact value `--quick` keeps
            // under diagnostics (the default path predicts on rebuilds).
            let exact = &free["diagnostics"]["selection_time"];
            let p_coll = exact["p_collision"].as_f64().expect("p_coll");
            queries.push(p.to_string());
            ours.push(exact["energy_mean"].as_f64());
            let c = 0.97 * p_coll;
            let run = etp_threads(
                &[
                    "strategy",
                    s(&dir),
                    "--min-target",
                    &p.to_string(),
                    "--max-collision",
                    &c.to_string(),
                    "--quick",
                    "-o",
                    s(&out),
                    "--force",
                    "--json",
                ],
                "2",
            );
            queries.push(format!("{p},{c}"));
            ours.push(if run.status.success() {
                let v: Value = serde_json::from_slice(&run.stdout).expect("json");
                let pred = &v["diagnostics"]["selection_time"];
                // Constraints hold in the strategy's own exact evaluation.
                assert!(pred["p_target"].as_f64().unwrap_or(0.0) >= p, "{v}");
                assert!(pred["p_collision"].as_f64().unwrap_or(1.0) <= c, "{v}");
                pred["energy_mean"].as_f64()
            } else {
                let err = String::from_utf8_lossy(&run.stderr);
                assert!(err.contains("infeasible"), "{err}");
                None
            });
        }
        let theirs = independent(&prism, &queries);
        let mut feasible = 0;
        for ((q, a), b) in queries.iter().zip(&ours).zip(&theirs) {
            match (a, b) {
                (Some(a), Some(b)) => {
                    feasible += 1;
                    assert!(
                        (a - b).abs() <= 1e-8 * b.abs().max(1.0),
                        "{name} {q}: etp {a} vs independent LP {b} (rel {:e})",
                        (a - b).abs() / b.abs().max(1.0)
                    );
                }
                (None, None) => {}
                _ => panic!("{name} {q}: feasibility differs: etp {a:?}, independent {b:?}"),
            }
        }
        assert!(feasible >= 5, "{name}: only {feasible} feasible queries");
    }
    // export-prism refuses a front.json of another scenario.
    let (a, b) = (scratch.path("winding-2d"), scratch.path("open-2d"));
    std::fs::copy(a.join("front.json"), b.join("front.json")).expect("copy");
    let out = etp_threads(&["export-prism", s(&b), s(&b.join("p2"))], "2");
    assert!(!out.status.success(), "a foreign front.json was accepted");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("front.json"), "{err}");
}

#[test]
fn front_and_strategy_are_byte_identical_on_one_and_two_threads() {
    let scratch = Scratch::new("exact-determinism");
    let mut outputs: Vec<Vec<Vec<u8>>> = Vec::new();
    for threads in ["1", "2"] {
        let dir = scratch.path(&format!("t{threads}"));
        run_ok(
            &[
                "synthesize",
                "winding-2d",
                "--samples",
                "200",
                "--seed",
                "2",
                "-o",
                s(&dir),
            ],
            threads,
        );
        run_ok(
            &[
                "strategy",
                s(&dir),
                "--min-target",
                "0.9",
                "--max-collision",
                "0.06",
            ],
            threads,
        );
        outputs.push(
            ["front.json", "front.svg", "front.png", "strategy.json"]
                .iter()
                .map(|f| std::fs::read(dir.join(f)).expect("output file"))
                .collect(),
        );
    }
    for (k, f) in ["front.json", "front.svg", "front.png", "strategy.json"]
        .iter()
        .enumerate()
    {
        assert!(
            outputs[0][k] == outputs[1][k],
            "{f} differs between 1 and 2 threads"
        );
    }
}
