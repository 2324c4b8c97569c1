//! A strategy synthesized for a lossy channel carries it (docs/MODEL.md §8):
//! `validate` evaluates it under that channel by default and names both when
//! told another (a robustness study), `run` runs it under either (the
//! channel written into the run's scenario text), and `etp fronts` draws
//! what the channel costs.

use super::{Scratch, etp, fails_with, ok_json, s};

/// `etp validate … --json`: its report whether or not a check of the
/// (deliberately small) synthesis fails (exit 6 then); any other exit fails.
fn validated(args: &[&str]) -> Value {
    let out = etp(args);
    assert!(
        matches!(out.status.code(), Some(0 | 6)),
        "etp {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON value")
}
use serde_json::Value;

fn synthesize(dir: &std::path::Path, extra: &[&str]) {
    let mut args = vec![
        "synthesize",
        "open-2d",
        "--samples",
        "60",
        "--holdout-samples",
        "60",
        "--aggregation-episodes",
        "200",
        "--seed",
        "4",
        "-o",
        s(dir),
    ];
    args.extend_from_slice(extra);
    let out = etp(&args);
    assert!(
        out.status.success(),
        "etp {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn front_radio(dir: &std::path::Path) -> Value {
    let text = std::fs::read_to_string(dir.join("front.json")).expect("front.json");
    let v: Value = serde_json::from_str(&text).expect("front.json is JSON");
    v["radio"].clone()
}

#[test]
fn a_lossy_synthesis_is_recorded_validated_under_its_channel_and_drawn() {
    let tmp = Scratch::new("radio-synthesis");
    let (ideal, lossy) = (tmp.path("ideal"), tmp.path("lossy"));
    synthesize(&ideal, &[]);
    synthesize(&lossy, &["--loss", "0.3", "--retries", "1"]);
    // The ideal front says nothing (its file is as before); the lossy one
    // records its channel, one link per sensor.
    assert!(front_radio(&ideal).is_null());
    let r = front_radio(&lossy);
    let links = r["links"].as_array().expect("links");
    assert!(!links.is_empty());
    for l in links {
        assert_eq!(l["loss"], 0.3);
        assert_eq!(l["retries"], 1);
    }
    for d in [&ideal, &lossy] {
        let out = etp(&["strategy", s(d), "--min-target", "0.5"]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let strategy = lossy.join("strategy.json");
    let text = std::fs::read_to_string(&strategy).expect("strategy.json");
    let st: Value = serde_json::from_str(&text).expect("JSON");
    assert_eq!(st["radio"], r, "the strategy carries the front's channel");
    let ideal_st: Value = serde_json::from_str(
        &std::fs::read_to_string(ideal.join("strategy.json")).expect("strategy.json"),
    )
    .expect("JSON");
    assert!(ideal_st.get("radio").is_none());

    // Evaluated under its own channel by default…
    let base = ["validate", s(&strategy), "--episodes", "300", "--json"];
    let own = validated(&base);
    let said = own["radio"].as_str().expect("radio");
    assert!(said.contains("loss 0.3, retries 1"), "{said}");
    assert_eq!(own["radio_synthesized"], own["radio"]);
    assert!(own["lost"].as_u64().is_some_and(|x| x > 0));
    // …and under another when told, naming both.
    let mut args = base.to_vec();
    args.extend(["--loss", "0"]);
    let other = validated(&args);
    assert_eq!(other["radio"], "ideal");
    assert_eq!(other["radio_synthesized"], own["radio"]);
    assert_eq!(other["lost"], 0);
    let text_out = etp(&[
        "validate",
        s(&strategy),
        "--episodes",
        "100",
        "--loss",
        "0.1",
    ]);
    let stdout = String::from_utf8_lossy(&text_out.stdout);
    assert!(
        stdout.contains("the strategy was synthesized for loss 0.3, retries 1"),
        "{stdout}"
    );

    // A run takes the strategy's own channel (written into the run's copy of
    // the scenario text, which every process reads) or, under radio options,
    // another one (a robustness study, predicted by simulation under it);
    // the report names both and both identities hold exactly.
    for (extra, radio) in [
        (&[][..], "loss 0.3, retries 1"),
        (&["--loss", "0.1"][..], "loss 0.1, retries 1"),
    ] {
        let mut args = vec!["run", s(&strategy), "--episodes", "4", "--json"];
        args.extend_from_slice(extra);
        let v = ok_json(&args);
        assert!(
            v["radio"].as_str().is_some_and(|r| r.contains(radio)),
            "{v}"
        );
        assert_eq!(v["radio_synthesized"], own["radio"], "{v}");
        let robustness = !extra.is_empty();
        assert_eq!(
            v["predicted_energy_from"]
                .as_str()
                .is_some_and(|f| f.starts_with("in-process simulation")),
            robustness,
            "{v}"
        );
        let n = |k: &str| v[k].as_u64().unwrap_or_else(|| panic!("{k}: {v}"));
        assert_eq!(n("transmissions"), n("delivered") + n("lost"), "{v}");
        assert_eq!(n("received"), n("delivered"), "{v}");
        assert!(n("lost") > 0, "{v}");
        super::schemas::validate(&tmp.0, "run", &v)
            .unwrap_or_else(|e| panic!("etp run --json against schemas/run.json:\n{e}\n{v}"));
    }

    // The figure: one curve per synthesis; least energy never decreases in P_tar.
    let stem = tmp.path("fronts");
    let v = ok_json(&["fronts", s(&ideal), s(&lossy), "-o", s(&stem), "--json"]);
    let panels = v["panels"].as_array().expect("panels");
    assert_eq!(panels.len(), 1, "no bound: one panel");
    assert!(panels[0]["max_collision"].is_null());
    let fronts = panels[0]["fronts"].as_array().expect("fronts");
    assert_eq!(fronts.len(), 2);
    assert_eq!(fronts[0]["radio"], "ideal");
    // One family: the curves are labelled by their channel.
    assert_eq!(fronts[0]["label"], "ideal");
    assert_eq!(fronts[1]["trigger"], "box");
    for f in fronts {
        let pts = f["points"].as_array().expect("points");
        assert!(pts.len() >= 2, "{f}");
        for w in pts.windows(2) {
            let (t0, t1) = (w[0]["p_target"].as_f64(), w[1]["p_target"].as_f64());
            let (e0, e1) = (w[0]["energy"].as_f64(), w[1]["energy"].as_f64());
            assert!(t0 < t1 && e0 <= e1.map(|e| e + 1e-9), "{w:?}");
        }
    }
    assert!(stem.with_extension("png").exists() && stem.with_extension("svg").exists());
    super::schemas::validate(&tmp.0, "fronts", &v)
        .unwrap_or_else(|e| panic!("etp fronts --json against schemas/fronts.json:\n{e}\n{v}"));
    // Fronts of two scenarios are refused.
    let other_scenario = tmp.path("winding");
    let out = etp(&[
        "synthesize",
        "winding-2d",
        "--samples",
        "30",
        "--holdout-samples",
        "30",
        "--aggregation-episodes",
        "100",
        "-o",
        s(&other_scenario),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    fails_with(
        &[
            "fronts",
            s(&ideal),
            s(&other_scenario),
            "-o",
            s(&tmp.path("x")),
        ],
        &["one scenario"],
    );
}
