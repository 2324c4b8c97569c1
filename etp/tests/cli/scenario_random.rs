//! `etp scenario random`: the random scenario family end to end.

use super::{Scratch, etp, fails_with, ok_json};

#[test]
fn random_scenarios_are_reproducible_and_pass_check() {
    let dir = Scratch::new("scenario-random");
    for (n, seed) in [("2", "3"), ("3", "4"), ("4", "5"), ("6", "6")] {
        let a = etp(&["scenario", "random", "--dim-agent", n, "--seed", seed]);
        assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
        let b = etp(&["scenario", "random", "--dim-agent", n, "--seed", seed]);
        assert_eq!(a.stdout, b.stdout, "same seed, same text");
        let file = dir.path(&format!("n{n}.toml"));
        let path = file.to_str().expect("utf-8 path");
        let w = etp(&[
            "scenario",
            "random",
            "--dim-agent",
            n,
            "--seed",
            seed,
            "-o",
            path,
        ]);
        assert!(w.status.success(), "{}", String::from_utf8_lossy(&w.stderr));
        assert_eq!(std::fs::read(&file).expect("written"), a.stdout);
        let c = ok_json(&["check", path, "--json"]);
        assert_eq!(c["dim"].as_u64(), Some(n.parse().expect("n")));
        assert_eq!(c["warnings"].as_array().map(Vec::len), Some(0));
        // never overwritten without --force
        fails_with(
            &[
                "scenario",
                "random",
                "--dim-agent",
                n,
                "--seed",
                "99",
                "-o",
                path,
            ],
            &["already exists"],
        );
        assert_eq!(std::fs::read(&file).expect("kept"), a.stdout);
    }
    fails_with(
        &["scenario", "random", "--dim-agent", "5", "--seed", "1"],
        &["--dim-agent"],
    );
}

/// A small synthesis of a random double integrator reports the aggregation
/// check in its JSON (and can switch it off).
#[test]
fn synthesize_reports_the_aggregation_check() {
    let dir = Scratch::new("aggregation-check");
    let file = dir.path("s.toml");
    let path = file.to_str().expect("utf-8 path");
    let w = etp(&[
        "scenario",
        "random",
        "--dim-agent",
        "4",
        "--seed",
        "1",
        "-o",
        path,
    ]);
    assert!(w.status.success(), "{}", String::from_utf8_lossy(&w.stderr));
    let out = dir.path("out");
    let out = out.to_str().expect("utf-8 path");
    let v = ok_json(&[
        "synthesize",
        path,
        "--samples",
        "300",
        "--holdout-samples",
        "0",
        "--no-kf-baseline",
        "--aggregation-episodes",
        "3000",
        "-o",
        out,
        "--json",
    ]);
    let a = &v["aggregation"];
    assert_eq!(a["episodes"].as_u64(), Some(3000));
    assert!(a["groups_tested"].as_u64().is_some_and(|g| g > 0), "{a}");
    assert!(
        a["flags"].is_array() && a["flagged_states"].is_array(),
        "{a}"
    );
    fails_with(
        &[
            "synthesize",
            path,
            "--aggregation-alpha",
            "1.5",
            "-o",
            out,
            "--force",
        ],
        &["--aggregation-alpha"],
    );
}
