//! Scenarios that cannot work (docs/MODEL.md §1.1) are refused by every
//! command that loads them, naming the field, with the exit code of every
//! other scenario error; every scenario that loads simulates without a
//! quantity that is not a number.

use super::{Scratch, etp, s};
use serde_json::Value;

fn winding() -> String {
    etp_shared::scenario::builtin_text("winding-2d")
        .expect("built-in")
        .to_string()
}

fn edited(from: &str, to: &str) -> String {
    let w = winding();
    assert!(w.contains(from), "winding-2d lacks {from:?}");
    w.replace(from, to)
}

/// The exit code and stderr of `etp ARGS`.
fn refusal(args: &[&str]) -> (Option<i32>, String) {
    let out = etp(args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn the_scenarios_that_cannot_work_are_refused_by_every_command_naming_the_field() {
    let dir = Scratch::new("unworkable");
    let cases = [
        (
            "growth",
            edited(
                "F = [[1.0, 0.0], [0.0, 1.0]]",
                "F = [[1e6, 0.0], [0.0, 1.0]]",
            ),
            "`model.F`",
        ),
        (
            "unobserved",
            // Every sensor measures x only.
            edited("H = [[1.0, 0.0], [0.0, 1.0]]", "H = [[1.0, 0.0]]")
                .replace("R = [[0.0009, 0.0], [0.0, 0.0009]]", "R = [[0.0009]]"),
            "`sensor[0] \"s0\".H, sensor[1] \"s1\".H",
        ),
        (
            "still",
            edited("u_max = 0.05", "u_max = 1e-12"),
            "`controller.u_max`",
        ),
        (
            "singular-noise",
            edited(
                "Q = [[0.0049, 0.0], [0.0, 0.0049]]",
                "Q = [[0.0049, 0.0], [0.0, 1e-20]]",
            ),
            "`model.Q`",
        ),
        // Any other scenario error, for its exit code.
        (
            "unknown-sensor",
            edited("sensor = \"s0\"", "sensor = \"s9\""),
            "`leg[0].sensor`",
        ),
    ];
    for (name, text, field) in &cases {
        let file = dir.path(&format!("{name}.toml"));
        std::fs::write(&file, text).expect("write scenario");
        let path = s(&file);
        let out = dir.path(&format!("{name}-out"));
        for args in [
            vec!["check", path],
            vec!["check", path, "--json"],
            vec!["simulate", path, "--delta", "1.0", "--episodes", "10"],
            vec!["synthesize", path, "--samples", "20", "-o", s(&out)],
            vec!["bench", path],
            vec![
                "run",
                "--scenario",
                path,
                "--delta",
                "1.0",
                "--episodes",
                "1",
            ],
        ] {
            let (code, err) = refusal(&args);
            assert_eq!(code, Some(1), "etp {args:?}: {err}");
            assert!(
                err.contains(&format!("scenario field {field}")),
                "etp {args:?} should name {field}: {err}"
            );
            assert!(!err.contains("panicked"), "{err}");
        }
        assert!(!out.exists(), "{name}: nothing written");
    }
}

/// The numbers of a `simulate --json` that must be numbers (a NaN would be
/// JSON `null`).
fn assert_numbers(v: &Value, what: &str) {
    for k in [
        "p_target",
        "p_collision",
        "energy_mean",
        "trigger_rate",
        "trigger_rate_expected",
        "nees",
    ] {
        for key in [k.to_string(), format!("{k}_ci95")] {
            let x = v[&key].as_f64();
            assert!(x.is_some_and(f64::is_finite), "{what}: {key} = {}", v[&key]);
        }
    }
    let nees = v["nees"].as_f64().unwrap_or(f64::NAN);
    assert!(nees > 0.2 && nees < 5.0, "{what}: NEES/n {nees}");
}

#[test]
fn every_builtin_random_and_partly_observing_scenario_loads_and_simulates_without_a_nan() {
    let dir = Scratch::new("workable");
    let mut scenarios: Vec<(String, String)> = [
        "winding-2d",
        "open-2d",
        "superg-3d",
        "inertia-2d",
        "inertia-3d",
    ]
    .iter()
    .map(|n| (n.to_string(), n.to_string()))
    .collect();
    for n in ["2", "3", "4", "6"] {
        for seed in ["11", "12", "13"] {
            let file = dir.path(&format!("random-{n}-{seed}.toml"));
            let out = etp(&[
                "scenario",
                "random",
                "--dim-agent",
                n,
                "--seed",
                seed,
                "-o",
                s(&file),
            ]);
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            scenarios.push((format!("random n = {n} seed {seed}"), s(&file).to_string()));
        }
    }
    // s0 measures x only and every other sensor both: the missing direction
    // is observed by the others (and s0 serves the first leg).
    let partial = dir.path("partial.toml");
    std::fs::write(
        &partial,
        winding()
            .replacen("H = [[1.0, 0.0], [0.0, 1.0]]", "H = [[1.0, 0.0]]", 1)
            .replacen("R = [[0.0009, 0.0], [0.0, 0.0009]]", "R = [[0.0009]]", 1),
    )
    .expect("write scenario");
    scenarios.push(("rank-deficient s0".into(), s(&partial).to_string()));
    for (what, arg) in &scenarios {
        let c = etp(&["check", arg, "--json"]);
        assert!(
            c.status.success(),
            "{what}: {}",
            String::from_utf8_lossy(&c.stderr)
        );
        let c: Value = serde_json::from_slice(&c.stdout).expect("check JSON");
        assert_eq!(
            c["warnings"].as_array().map(Vec::len),
            Some(0),
            "{what}: {c}"
        );
        let out = etp(&[
            "simulate",
            arg,
            "--delta",
            "1.0",
            "--episodes",
            "20",
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{what}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).expect("simulate JSON");
        assert_numbers(&v, what);
        let text = etp(&["simulate", arg, "--delta", "1.0", "--episodes", "20"]);
        let text = String::from_utf8_lossy(&text.stdout);
        let not_a_number = text
            .split_whitespace()
            .any(|w| w.parse::<f64>().is_ok_and(|x| !x.is_finite()));
        assert!(!not_a_number, "{what}: {text}");
    }
}
