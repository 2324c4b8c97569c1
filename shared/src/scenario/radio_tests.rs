//! `[radio]` and the per-sensor link fields (docs/MODEL.md §8): parsed,
//! resolved per sensor, refused with the field's name, and absent from the
//! content hash when not written.

use super::*;
use crate::radio::{Estimator, Link};

fn winding() -> String {
    builtin_text("winding-2d").expect("built-in").to_string()
}

fn with_radio(table: &str) -> String {
    format!("{}\n[radio]\n{table}\n", winding())
}

/// winding-2d with `fields` added to its sensor "s1".
fn with_s1(fields: &str) -> String {
    let text = winding();
    let at = "name = \"s1\"\n";
    assert!(text.contains(at));
    text.replacen(at, &format!("{at}{fields}\n"), 1)
}

fn refused(text: &str, field: &str, reason: &str) {
    match Scenario::from_toml(text) {
        Err(ScenarioError::Invalid {
            field: f,
            reason: r,
        }) => {
            assert_eq!(f, field, "reason: {r}");
            assert!(r.contains(reason), "reason `{r}` should contain `{reason}`");
        }
        other => panic!("expected Invalid({field}), got {other:?}"),
    }
}

#[test]
fn builtin_hashes_are_those_before_the_radio() {
    // The hashes of main before §8 (etp check --json): strategies, MDPs and
    // recordings made before still match.
    for (name, hash) in [
        (
            "winding-2d",
            "3f3dccac134829083a2401e5c280f3e3be9bb7a3991c4eaef13a9ca4f05d8045",
        ),
        (
            "open-2d",
            "80ceb511e9141c1b40364ccfc6f505d9943c4b251ad0c41a113391ef99c27267",
        ),
        (
            "superg-3d",
            "e53f5e6435f93b3faa8bdb2036bc451ff5afbf0beb7fb624dab11e94e2d44e9b",
        ),
        (
            "inertia-2d",
            "76328cc2fb98c200c775003f03f7fc97ba5e2a39a38f262d7eba8e9eeaf4e854",
        ),
        (
            "inertia-3d",
            "65c0e317d8db4361f48ec6d4e6f5d5e291d8db26e22076ec039b3484726a135a",
        ),
    ] {
        let s = Scenario::builtin(name).expect("valid");
        assert_eq!(s.content_hash, hash, "{name}");
        assert!(s.radio.is_ideal(), "{name}");
        assert_eq!(s.radio.links.len(), s.sensors.len());
    }
}

#[test]
fn radio_table_and_sensor_overrides_resolve_per_link() {
    let text = with_radio("loss = 0.2\nretries = 1\nestimator = \"naive\"");
    let s = Scenario::from_toml(&text).expect("valid");
    assert_eq!(s.radio.estimator, Estimator::Naive);
    assert!(s.radio.links.iter().all(|l| *l
        == Link {
            loss: 0.2,
            retries: 1,
            burst: None
        }));
    assert_ne!(
        s.content_hash,
        Scenario::builtin("winding-2d").expect("valid").content_hash
    );
    let text = format!(
        "{}\n[radio]\nloss = 0.1\nburst = 3.0\n",
        with_s1("loss = 0.4\nretries = 2")
    );
    let s = Scenario::from_toml(&text).expect("valid");
    assert_eq!(s.radio.estimator, Estimator::Aware);
    assert_eq!(
        s.radio.links[1],
        Link {
            loss: 0.4,
            retries: 2,
            burst: Some(3.0)
        }
    );
    assert_eq!(
        s.radio.links[0],
        Link {
            loss: 0.1,
            retries: 0,
            burst: Some(3.0)
        }
    );
    // A sensor alone may be lossy.
    let s = Scenario::from_toml(&with_s1("loss = 0.3")).expect("valid");
    assert!(!s.radio.is_ideal() && s.radio.links[0].is_ideal());
    // loss = 0 is the ideal radio.
    let s = Scenario::from_toml(&with_radio("loss = 0.0")).expect("valid");
    assert!(s.radio.is_ideal());
}

#[test]
fn radio_errors_name_the_field() {
    refused(&with_radio("loss = 1.0"), "radio.loss", "[0, 1)");
    refused(&with_radio("loss = -0.1"), "radio.loss", "[0, 1)");
    refused(
        &with_radio("loss = 0.2\nretries = -1"),
        "radio.retries",
        "whole number",
    );
    refused(
        &with_radio("loss = 0.2\nburst = 0.5"),
        "radio.burst",
        ">= 1",
    );
    refused(
        &with_radio("loss = 0.7\nburst = 2.0"),
        "radio.burst",
        "B/(1+B)",
    );
    refused(
        &with_radio("estimator = \"smart\""),
        "radio.estimator",
        "\"aware\" or \"naive\"",
    );
    refused(&with_s1("loss = 1.5"), "sensor[1] \"s1\".loss", "[0, 1)");
    refused(
        &with_s1("retries = -2"),
        "sensor[1] \"s1\".retries",
        "whole number",
    );
    refused(
        &with_s1("loss = 0.9\nburst = 2.0"),
        "sensor[1] \"s1\".burst",
        "B/(1+B)",
    );
    // An unknown key in [radio] is a parse error naming it.
    match Scenario::from_toml(&with_radio("los = 0.2")) {
        Err(ScenarioError::Parse(m)) => assert!(m.contains("los"), "{m}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn command_line_overrides_keep_the_hash_and_name_the_option() {
    use crate::radio::RadioOverride;
    let w = Scenario::builtin("winding-2d").expect("valid");
    let o = RadioOverride {
        loss: Some(0.3),
        retries: Some(1),
        burst: None,
        estimator: Some(Estimator::Naive),
    };
    let lossy = w.clone().with_radio_override(&o).expect("valid");
    assert_eq!(lossy.content_hash, w.content_hash);
    assert_eq!(lossy.radio.links[3].loss, 0.3);
    assert_eq!(lossy.radio.estimator, Estimator::Naive);
    let same = w
        .clone()
        .with_radio_override(&RadioOverride::default())
        .expect("valid");
    assert_eq!(same, w);
    let bad = RadioOverride {
        loss: Some(1.2),
        ..RadioOverride::default()
    };
    match w.with_radio_override(&bad) {
        Err(ScenarioError::Invalid { field, .. }) => assert_eq!(field, "--loss"),
        other => panic!("{other:?}"),
    }
}
