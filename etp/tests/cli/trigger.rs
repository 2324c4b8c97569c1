//! Trigger families in-process (docs/MODEL.md §9, issue 40): `--trigger`
//! and `[triggering] family` on `etp simulate`; the measured rate of the
//! stochastic family at its closed form; box output as before; the processes
//! refuse a family they do not implement, by name.

use super::{Scratch, etp, fails_with, ok_json, s};

fn simulate(family: &str, delta: &str) -> serde_json::Value {
    ok_json(&[
        "simulate",
        "winding-2d",
        "--delta",
        delta,
        "--episodes",
        "300",
        "--seed",
        "5",
        "--trigger",
        family,
        "--json",
    ])
}

#[test]
fn the_stochastic_family_sends_at_its_closed_form_rate_and_stays_consistent() {
    // winding-2d's sensors measure m = 2: rate 1/(1 + δ²).
    for (delta, rate) in [("0.5", 0.8), ("1.0", 0.5), ("2.0", 0.2)] {
        let v = simulate("stochastic", delta);
        assert_eq!(v["trigger"], "stochastic");
        let measured = v["trigger_rate"].as_f64().expect("rate");
        let hw = v["trigger_rate_ci95"].as_f64().expect("ci");
        let expected = v["trigger_rate_expected"].as_f64().expect("expected");
        assert!((expected - rate).abs() < 1e-12, "δ={delta}: {expected}");
        // Twice the 95 % half-width: a slot's decisions within an episode
        // are not independent draws, the interval is per episode.
        assert!(
            (measured - rate).abs() <= 2.0 * hw,
            "δ={delta}: measured {measured} ± {hw} vs {rate}"
        );
        // The silence update is exact: NEES/n = 1 within 0.03.
        let nees = v["nees"].as_f64().expect("nees");
        assert!((nees - 1.0).abs() < 0.03, "δ={delta}: NEES/n {nees}");
    }
}

#[test]
fn box_said_aloud_is_the_default_and_its_output_names_no_family() {
    let plain = ok_json(&[
        "simulate",
        "winding-2d",
        "--delta",
        "1.0",
        "--episodes",
        "100",
        "--seed",
        "2",
        "--json",
    ]);
    let said = simulate("box", "1.0");
    assert!(plain.get("trigger").is_none(), "{plain}");
    for key in ["p_target", "energy_mean", "trigger_rate", "nees"] {
        assert_eq!(
            plain[key],
            ok_json(&[
                "simulate",
                "winding-2d",
                "--delta",
                "1.0",
                "--episodes",
                "100",
                "--seed",
                "2",
                "--trigger",
                "box",
                "--json",
            ])[key],
            "{key}"
        );
    }
    assert!(said.get("trigger").is_none());
    // The deterministic families count their decisions: expected = measured.
    for family in ["variance", "periodic", "send-on-delta"] {
        let v = simulate(family, "2.5");
        assert_eq!(v["trigger"], family);
        assert_eq!(v["trigger_rate"], v["trigger_rate_expected"], "{family}");
    }
}

#[test]
fn a_family_is_read_from_the_scenario_named_when_unknown_and_a_strategys_family_kept_by_run() {
    let tmp = Scratch::new("trigger-family");
    let text = etp_shared::scenario::builtin_text("open-2d").expect("built-in");
    let with = |family: &str| {
        let t = text.replacen(
            "[triggering]",
            &format!("[triggering]\nfamily = \"{family}\""),
            1,
        );
        assert_ne!(t, text, "open-2d has a [triggering] table");
        let path = tmp.path(&format!("{family}.toml"));
        std::fs::write(&path, t).expect("write scenario");
        path
    };
    let stochastic = with("stochastic");
    let v = ok_json(&[
        "simulate",
        s(&stochastic),
        "--delta",
        "1.0",
        "--episodes",
        "50",
        "--json",
    ]);
    assert_eq!(v["trigger"], "stochastic");
    let bad = with("sometimes");
    fails_with(
        &["simulate", s(&bad), "--delta", "1.0"],
        &["triggering.family", "sometimes", "send-on-delta"],
    );
    fails_with(
        &[
            "simulate",
            "open-2d",
            "--delta",
            "1.0",
            "--trigger",
            "sometimes",
        ],
        &["sometimes", "stochastic"],
    );
    // A strategy is tied to its scenario's family: --trigger cannot change it.
    let dir = tmp.path("open");
    let out = etp(&["synthesize", "open-2d", "--samples", "40", "-o", s(&dir)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let strategy = dir.join("strategy.json");
    let out = etp(&[
        "strategy",
        s(&dir),
        "--vertex",
        "0",
        "--quick",
        "-o",
        s(&strategy),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    fails_with(
        &[
            "run",
            s(&strategy),
            "--trigger",
            "stochastic",
            "--episodes",
            "2",
        ],
        &[
            "--trigger stochastic",
            "the strategy was made for trigger family `box`",
        ],
    );
    // validate likewise: --trigger confirms the strategy's family (a
    // validation as usual), another is refused by name.
    fails_with(
        &["validate", s(&strategy), "--trigger", "periodic"],
        &[
            "--trigger periodic",
            "the strategy was made for trigger family `box`",
        ],
    );
    let same = ok_json(&[
        "validate",
        s(&strategy),
        "--trigger",
        "box",
        "--episodes",
        "20",
        "--json",
    ]);
    let plain = ok_json(&["validate", s(&strategy), "--episodes", "20", "--json"]);
    assert_eq!(
        same, plain,
        "--trigger box on a box strategy changes nothing"
    );
    let out = etp(&["check", s(&stochastic)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
