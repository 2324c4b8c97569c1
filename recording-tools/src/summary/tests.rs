//! The summary's episode rules on hand-made recordings: which episodes are
//! counted, which degraded, which partial — as `etp run` counts them.

use super::summarize;
use etp_runtime::recording::{self, Contents, Encoding, RawMessage};
use etp_runtime::wire::agent_to_coordinator::{Outcome, Waypoint};
use etp_runtime::wire::sensor_to_agent::Measurement;
use etp_runtime::wire::sensor_to_coordinator::Ledger;
use etp_runtime::wire::{Header, Message};
use etp_shared::scenario::Scenario;
use serde_json::Value;

const SCENARIO: &str = include_str!("../../../scenarios/open-2d.toml");

/// A recording of `episodes` with the four channels the summary counts on.
struct Recording {
    contents: Contents,
    scenario: Scenario,
}

impl Recording {
    fn new() -> Self {
        let scenario = Scenario::from_toml(SCENARIO).expect("open-2d");
        let mut contents = Contents {
            finished: true,
            ..Contents::default()
        };
        contents.metadata.insert(
            recording::META_SCENARIO.to_string(),
            [("toml".to_string(), SCENARIO.to_string())].into(),
        );
        for topic in ["outcome", "ledger", "measurement", "waypoint"] {
            contents.channels.insert(topic.into(), topic.into());
            contents
                .encodings
                .insert(topic.into(), Encoding::Protobuf.name().into());
        }
        Self { contents, scenario }
    }

    fn push<T: Message>(&mut self, topic: &str, payload: &T) {
        let data = Encoding::Protobuf.encode(payload).expect("encode");
        let log_time = self.contents.messages.len() as u64;
        self.contents.messages.push(RawMessage {
            topic: topic.into(),
            sequence: 0,
            log_time,
            publish_time: log_time,
            data,
            encoding: Some(Encoding::Protobuf),
        });
    }

    fn sensor_of(&self, leg: usize) -> u32 {
        self.scenario.legs[leg].sensor as u32
    }

    /// One episode: one measurement on every leg (none from the `dead`
    /// sensor), the waypoints, a ledger for each leg not
    /// in `without_ledger`, then its outcome (`dead`: the sensor whose link
    /// the agent found dead in it).
    fn episode(&mut self, episode: u64, without_ledger: &[usize], dead: Option<u32>) {
        let last = self.scenario.legs.len() - 1;
        let header = |leg: usize, sender: u32| Header {
            episode,
            leg: leg as u32,
            sender,
            ..Header::default()
        };
        for leg in 0..=last {
            if leg > 0 {
                let before = u32::from(dead != Some(self.sensor_of(leg - 1)));
                self.push(
                    "waypoint",
                    &Waypoint {
                        header: header(leg, etp_runtime::wire::SENDER_AGENT),
                        prev_received: before,
                        ..Waypoint::default()
                    },
                );
            }
            let sensor = self.sensor_of(leg);
            let delivered = u32::from(dead != Some(sensor));
            if delivered == 1 {
                self.push(
                    "measurement",
                    &Measurement {
                        header: header(leg, sensor),
                        ..Measurement::default()
                    },
                );
            }
            if !without_ledger.contains(&leg) {
                self.push(
                    "ledger",
                    &Ledger {
                        header: header(leg, sensor),
                        slots: 1,
                        triggers: delivered,
                        transmissions: delivered,
                        delivered,
                        energy: f64::from(delivered),
                        ..Ledger::default()
                    },
                );
            }
        }
        self.push(
            "outcome",
            &Outcome {
                header: header(last, etp_runtime::wire::SENDER_AGENT),
                outcome: Outcome::TARGET,
                degraded: u32::from(dead.is_some()),
                received: (0..=last)
                    .filter(|l| dead != Some(self.sensor_of(*l)))
                    .count() as u32,
                last_received: u32::from(dead != Some(self.sensor_of(last))),
                dead_sensor: dead.unwrap_or(u32::MAX),
                ..Outcome::default()
            },
        );
    }

    fn summary(&self) -> Value {
        summarize(&self.contents).expect("summary")
    }
}

fn partial(v: &Value) -> Vec<u64> {
    serde_json::from_value(v["partial"]["episodes"].clone()).expect("partial episodes")
}

#[test]
fn a_complete_run_counts_every_episode_and_none_degraded() {
    let mut r = Recording::new();
    for e in 0..3 {
        r.episode(e, &[], None);
    }
    let v = r.summary();
    assert_eq!(v["episodes"], 3);
    assert_eq!(v["degraded_episodes"], 0);
    assert!(partial(&v).is_empty(), "{v}");
    assert_eq!(v["identities_hold"], true, "{v}");
}

/// A sensor stopped after its leg closed and before its ledger, then found
/// dead in the next episode: `etp run` counts the first episode too (its leg
/// without a ledger excused, the episode degraded); so does the summary.
#[test]
fn a_ledger_lost_to_a_sensor_found_dead_later_is_excused_and_the_episode_degraded() {
    let mut r = Recording::new();
    let leg = 1;
    let sensor = r.sensor_of(leg);
    let its_legs: Vec<usize> = (0..r.scenario.legs.len())
        .filter(|l| r.sensor_of(*l) == sensor)
        .collect();
    r.episode(0, &[], None);
    r.episode(1, &[leg], None);
    r.episode(2, &its_legs, Some(sensor));
    let v = r.summary();
    assert!(partial(&v).is_empty(), "{}", v["partial"]);
    assert_eq!(v["episodes"], 3);
    assert_eq!(v["degraded_episodes"], 2);
    assert_eq!(v["identities_hold"], true, "{}", v["identity_failures"]);
    // `received` covers the legs the ledgers cover, as `etp run`'s does.
    let sensors = v["sensors"].as_array().expect("sensors");
    let on_ledgered_legs: u64 = sensors.iter().filter_map(|s| s["received"].as_u64()).sum();
    assert_eq!(v["received"].as_u64(), Some(on_ledgered_legs), "{v}");
    assert_eq!(v["received"], v["delivered"], "{v}");
    let s = &v["sensors"][sensor as usize];
    assert_eq!(
        s["measurements_without_ledger"], 1,
        "episode 1's measurement on the excused leg: {s}"
    );
}

/// The same missing ledger from a sensor never found dead is a cut (the
/// episode partial, not counted), never silently excused.
#[test]
fn a_ledger_missing_from_a_sensor_never_found_dead_leaves_the_episode_partial() {
    let mut r = Recording::new();
    r.episode(0, &[], None);
    r.episode(1, &[1], None);
    let v = r.summary();
    assert_eq!(partial(&v), vec![1]);
    assert_eq!(v["episodes"], 1);
    assert_eq!(v["degraded_episodes"], 0);
}
