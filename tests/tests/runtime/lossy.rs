//! The lossy, acknowledged radio (docs/MODEL.md §8) in the multi-process
//! runtime: a scenario with a `[radio]`, run by the real processes and
//! recorded; every count identity per leg and per sensor, the recording's
//! attempts against the ledgers, and `replay verify` re-drawing every loss.

use super::recording::{out_file, python_json, replay};
use super::{DELTA, assert_ledgers_match, serial};
use etp_tests::{EtpRun, unique_run_id};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// winding-2d with every link lossy: loss 0.3, one retry, aware estimator.
fn lossy_scenario(id: &str) -> PathBuf {
    let text = etp_shared::scenario::builtin_text("winding-2d").expect("built-in");
    let path = std::env::temp_dir().join(format!("etp-test-{id}.toml"));
    std::fs::write(
        &path,
        format!("{text}\n[radio]\nloss = 0.3\nretries = 1\nestimator = \"aware\"\n"),
    )
    .expect("write scenario");
    path
}

fn sum(v: &Value, k: &str) -> u64 {
    v["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .map(|s| s[k].as_u64().unwrap_or_else(|| panic!("no `{k}` in {s}")))
        .sum()
}

/// Per-channel message counts of a recording, by the Python `mcap` reader,
/// and the sum of `slot.attempts` decoded from the payload by Foxglove's
/// protobuf decoder with the schema the file carries.
fn python_attempts(file: &Path) -> Value {
    let script = r#"
import sys, json
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
with open(sys.argv[1], "rb") as f:
    r = make_reader(f, decoder_factories=[DecoderFactory()])
    counts, attempts, delivered = {}, 0, 0
    for schema, channel, message, m in r.iter_decoded_messages():
        counts[channel.topic] = counts.get(channel.topic, 0) + 1
        if channel.topic == "slot":
            attempts += m.attempts
            delivered += m.delivered
    print(json.dumps({"counts": counts, "attempts": attempts, "delivered": delivered}))
"#;
    python_json(script, file)
}

#[test]
fn a_lossy_run_counts_attempts_delivered_and_lost_and_replay_redraws_every_loss() {
    let _serial = serial();
    let id = unique_run_id("lossy");
    let scenario = lossy_scenario(&id);
    let file = out_file(&id);
    let (ok, out, err) = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            &scenario.display().to_string(),
            "--delta",
            DELTA,
            "--episodes",
            "40",
            "--seed",
            "5",
            "--record",
            &file.display().to_string(),
            "--episode-details",
        ],
    )
    .finish();
    assert!(ok, "etp run of a lossy scenario failed: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("bad JSON ({e}): {out}"));
    assert_ledgers_match(&v, false);
    let (attempts, delivered, lost) = (
        sum(&v, "transmissions"),
        sum(&v, "delivered"),
        sum(&v, "lost"),
    );
    assert_eq!(attempts, delivered + lost);
    assert_eq!(sum(&v, "received"), delivered);
    // loss 0.3 per attempt: between 20 % and 40 % of attempts lost (a
    // binomial with thousands of attempts; ±6σ).
    let rate = lost as f64 / attempts as f64;
    assert!(attempts > 1000, "{attempts} attempts");
    assert!((0.2..0.4).contains(&rate), "loss rate {rate}");
    assert!(
        v["radio"].as_str().is_some_and(|r| r.contains("loss 0.3")),
        "{}",
        v["radio"]
    );
    // One ACK per delivered measurement went down the radio.
    let acks: u64 = v["recording"]["counts"]
        .as_object()
        .expect("counts")
        .iter()
        .filter(|(t, _)| t.ends_with("/ack"))
        .map(|(_, n)| n.as_u64().expect("count"))
        .sum();
    assert_eq!(acks, delivered, "ACKs recorded");
    // The file alone: four counts per sensor and both identities.
    let r = replay(&["verify", &file.display().to_string()]);
    assert_eq!(r["identities_hold"].as_bool(), Some(true), "{r}");
    assert_eq!(r["transmissions"].as_u64(), Some(attempts));
    assert_eq!(r["delivered"].as_u64(), Some(delivered));
    assert_eq!(r["lost"].as_u64(), Some(lost));
    assert_eq!(r["measurements"].as_u64(), Some(delivered));
    for s in r["sensors"].as_array().expect("sensors") {
        assert_eq!(s["attempts_recorded"], s["transmissions"], "{s}");
    }
    // Every loss re-drawn, every belief reproduced with the aware update.
    let verify = &r["verify"];
    assert_eq!(verify["passed"].as_bool(), Some(true), "{verify}");
    assert_eq!(verify["attempts_redrawn"].as_u64(), Some(attempts));
    assert_eq!(verify["lost_redrawn"].as_u64(), Some(lost));
    // The independent reader decodes the attempts from the schema's layout.
    let py = python_attempts(&file);
    assert_eq!(py["attempts"].as_u64(), Some(attempts));
    assert_eq!(py["delivered"].as_u64(), Some(delivered));
    let _ = std::fs::remove_file(&file);
    let _ = std::fs::remove_file(&scenario);
}

/// `etp run --channel-schedule`: the links change where the radio is, on the
/// sensor side, from each change's episode on; the agent's model stays the
/// scenario's (ideal) channel. Every count identity holds, the losses fall
/// only on the changed sensors in their changed episodes, and `replay
/// verify` re-draws every attempt on the link in force (the schedule is in
/// the recording).
#[test]
fn a_channel_schedule_changes_links_mid_run_with_exact_counts_and_verify_redraws_them() {
    let _serial = serial();
    let id = unique_run_id("schedule");
    let file = out_file(&id);
    let schedule = std::env::temp_dir().join(format!("etp-test-{id}-schedule.toml"));
    std::fs::write(
        &schedule,
        "[[change]]\nsensor = \"s1\"\nepisode = 5\nloss = 0.3\nretries = 1\n\n\
         [[change]]\nsensor = \"s2\"\nepisode = 3\nloss = 0.5\n",
    )
    .expect("write schedule");
    let (ok, out, err) = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--episodes",
            "10",
            "--seed",
            "4",
            "--channel-schedule",
            &schedule.display().to_string(),
            "--record",
            &file.display().to_string(),
            "--episode-details",
        ],
    )
    .finish();
    assert!(ok, "etp run with a channel schedule failed: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("bad JSON ({e}): {out}"));
    assert_ledgers_match(&v, false);
    assert_eq!(v["radio"], "ideal", "the agent's model: {v}");
    assert_eq!(v["channel_schedule"][0]["sensor"], "s2", "{v}");
    assert_eq!(v["channel_schedule"][1]["retries"], 1, "{v}");
    let (attempts, delivered, lost) = (
        sum(&v, "transmissions"),
        sum(&v, "delivered"),
        sum(&v, "lost"),
    );
    assert_eq!(attempts, delivered + lost);
    assert_eq!(sum(&v, "received"), delivered);
    // Per leg: a loss only where a change holds, and there plenty of them.
    let mut changed = (0u64, 0u64);
    for e in v["episode_results"].as_array().expect("episodes") {
        let episode = e["episode"].as_u64().expect("episode");
        for leg in e["legs"].as_array().expect("legs") {
            let sensor = leg["sensor"].as_u64().expect("sensor");
            let lossy = (sensor == 1 && episode >= 5) || (sensor == 2 && episode >= 3);
            let (t, l) = (
                leg["transmissions"].as_u64().expect("tx"),
                leg["lost"].as_u64().expect("lost"),
            );
            assert_eq!(
                t,
                leg["delivered"].as_u64().expect("delivered") + l,
                "{leg}"
            );
            if lossy {
                changed = (changed.0 + t, changed.1 + l);
            } else {
                assert_eq!(
                    l, 0,
                    "episode {episode}: a loss on an unchanged link: {leg}"
                );
            }
        }
    }
    assert!(
        changed.0 > 200 && changed.1 * 5 > changed.0,
        "changed links: {changed:?}"
    );
    let r = replay(&["verify", &file.display().to_string()]);
    assert_eq!(r["identities_hold"].as_bool(), Some(true), "{r}");
    let verify = &r["verify"];
    assert_eq!(verify["passed"].as_bool(), Some(true), "{verify}");
    assert_eq!(verify["attempts_redrawn"].as_u64(), Some(attempts));
    assert_eq!(verify["lost_redrawn"].as_u64(), Some(lost));
    // The channel monitor's model is the run's ideal radio: a lost attempt
    // is what it cannot produce, flagged at once (statistic ∞, JSON null):
    // s2's loss (from episode 3) and s1's (from 5), each once. The losses,
    // read as silence by the ideal estimator, may also make a changed
    // sensor trigger more often than the model (docs/MODEL.md §11.1); an
    // unchanged sensor is never flagged. The recording holds the same
    // flags and verify raises them again.
    let drift = v["drift"].as_array().expect("drift[]");
    let flagged: Vec<(&str, &str, u64)> = drift
        .iter()
        .map(|d| {
            (
                d["sensor"].as_str().expect("sensor"),
                d["quantity"].as_str().expect("quantity"),
                d["episode"].as_u64().expect("episode"),
            )
        })
        .collect();
    let losses: Vec<_> = drift.iter().filter(|d| d["quantity"] == "loss").collect();
    assert_eq!(losses.len(), 2, "{drift:?}");
    for d in &losses {
        assert!(d["statistic"].is_null(), "{d}");
        assert!(d["estimate"].as_f64().is_some_and(|e| e > 0.0), "{d}");
    }
    for (sensor, quantity, episode) in &flagged {
        let from = match *sensor {
            "s1" => 5,
            "s2" => 3,
            _ => panic!("an unchanged sensor flagged {quantity}: {drift:?}"),
        };
        assert!(
            *episode >= from,
            "{sensor} {quantity} before its change: {drift:?}"
        );
        assert_ne!(*quantity, "fewer_triggers", "{drift:?}");
    }
    assert!(
        flagged.iter().any(|f| f.0 == "s1" && f.1 == "loss"),
        "{drift:?}"
    );
    assert!(
        flagged.iter().any(|f| f.0 == "s2" && f.1 == "loss"),
        "{drift:?}"
    );
    assert_eq!(r["drift"], v["drift"], "the recording's flags");
    assert_eq!(
        verify["drift_flags_reproduced"].as_u64(),
        Some(drift.len() as u64),
        "{verify}"
    );
    // `--on-drift stop`: the run ends after the first flag's episode, exit 6,
    // its report covering the episodes run.
    let (code, out, err) = EtpRun::spawn(
        &unique_run_id("schedule-stop"),
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--episodes",
            "10",
            "--seed",
            "4",
            "--channel-schedule",
            &schedule.display().to_string(),
            "--on-drift",
            "stop",
        ],
    )
    .finish_code();
    assert_eq!(code, Some(6), "{err}");
    let stopped: Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("bad JSON ({e}): {out}"));
    let first = flagged.iter().map(|f| f.2).min().expect("a flag");
    assert_eq!(stopped["episodes"].as_u64(), Some(first + 1), "{stopped}");
    assert!(
        stopped["aborted"]
            .as_str()
            .is_some_and(|a| a.contains("--on-drift stop")),
        "{stopped}"
    );
    assert!(err.contains("stopped on channel drift"), "{err}");
    // A schedule naming no sensor of the run is refused by its key, before
    // anything runs.
    std::fs::write(&schedule, "[[change]]\nsensor = \"s9\"\nepisode = 1\n").expect("write");
    let (ok, _, err) = EtpRun::spawn(
        &unique_run_id("schedule-bad"),
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--episodes",
            "2",
            "--channel-schedule",
            &schedule.display().to_string(),
        ],
    )
    .finish();
    assert!(!ok);
    assert!(
        err.contains("change[0].sensor") && err.contains("s9"),
        "{err}"
    );
    let _ = std::fs::remove_file(&file);
    let _ = std::fs::remove_file(&schedule);
}
