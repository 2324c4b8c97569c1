use super::*;
use crate::scenario::builtin_text;
use crate::scenario::raw::{RawRadio, RawSensor};

fn lossy(loss: f64, retries: u32, burst: Option<f64>, n: usize) -> Radio {
    Radio {
        estimator: Estimator::Aware,
        links: vec![
            Link {
                loss,
                retries,
                burst
            };
            n
        ],
    }
}

fn winding() -> ScenarioText {
    ScenarioText::parse(builtin_text("winding-2d").expect("built-in").to_string()).expect("valid")
}

#[test]
fn the_writers_keys_are_the_parsers() {
    let radio = toml::Table::try_from(RawRadio {
        loss: Some(0.1),
        retries: Some(1),
        burst: Some(2.0),
        estimator: Some("aware".into()),
    })
    .expect("a table");
    let mut names: Vec<_> = radio.keys().map(String::as_str).collect();
    names.sort_unstable();
    let mut expected = vec![keys::ESTIMATOR, keys::LOSS, keys::RETRIES, keys::BURST];
    expected.sort_unstable();
    assert_eq!(names, expected);
    let sensor = toml::Table::try_from(RawSensor {
        name: "s".into(),
        position: vec![0.0],
        h: vec![vec![1.0]],
        r: vec![vec![1.0]],
        cost: 1.0,
        loss: Some(0.1),
        retries: Some(1),
        burst: Some(2.0),
    })
    .expect("a table");
    for k in keys::LINK {
        assert!(sensor.contains_key(k), "{k}");
    }
    let text = builtin_text("winding-2d").expect("built-in");
    let v: toml::Table = toml::from_str(text).expect("toml");
    assert!(v.contains_key(keys::SENSOR));
}

#[test]
fn a_channel_is_appended_to_a_text_without_one_comments_kept() {
    let own = winding();
    let n = own.scenario.sensors.len();
    let wanted = lossy(0.3, 1, Some(3.0), n);
    let out = own.clone().with_channel(&wanted).expect("written");
    assert!(
        out.text.starts_with(own.text.trim_end()),
        "the text is kept as it was"
    );
    assert!(
        out.text.ends_with(
            "\n\n[radio]\nloss = 0.3\nretries = 1\nestimator = \"aware\"\nburst = 3.0\n"
        )
    );
    assert_eq!(out.scenario.radio, wanted);
    assert!(out.sets_a_channel().expect("toml") && !own.sets_a_channel().expect("toml"));
    // Its own channel: the text itself.
    assert_eq!(out.clone().with_channel(&wanted).expect("same"), out);
}

#[test]
fn a_texts_own_channel_is_replaced_link_by_link_and_ideal_restores_the_hash() {
    let ideal = winding();
    // A [radio] of its own and one sensor's override.
    let own = format!(
        "{}\n[radio]\nloss = 0.2\nestimator = \"naive\"\n",
        ideal
            .text
            .replacen("name = \"s1\"", "name = \"s1\"\nloss = 0.4\nretries = 2", 1)
    );
    let own = ScenarioText::parse(own).expect("valid");
    assert_eq!(own.scenario.radio.link(1).retries, 2, "the override took");
    let mut wanted = lossy(0.1, 0, None, ideal.scenario.sensors.len());
    wanted.links[3] = Link {
        loss: 0.25,
        retries: 3,
        burst: Some(2.0),
    };
    let out = own.clone().with_channel(&wanted).expect("rewritten");
    assert_eq!(out.scenario.radio, wanted);
    // The ideal channel written back: the scenario (and its hash) of the
    // text without a channel, so a strategy of it matches again.
    let back = own
        .clone()
        .with_channel(&Radio::ideal(ideal.scenario.sensors.len()))
        .expect("ideal");
    assert_eq!(back.scenario.radio, ideal.scenario.radio);
    assert_eq!(back.scenario.content_hash, ideal.scenario.content_hash);
    // No links at all means every link ideal.
    let none = Radio {
        estimator: Estimator::Aware,
        links: Vec::new(),
    };
    assert_eq!(
        own.with_channel(&none)
            .expect("ideal")
            .scenario
            .content_hash,
        ideal.scenario.content_hash
    );
}

#[test]
fn a_channel_for_another_number_of_sensors_is_refused() {
    let e = winding()
        .with_channel(&lossy(0.1, 0, None, 2))
        .expect_err("2 links");
    assert!(e.to_string().contains("2 links"), "{e}");
}
