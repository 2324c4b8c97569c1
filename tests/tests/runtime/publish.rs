//! `etp replay publish`: the traffic back on iceoryx2, re-recorded by a
//! recorder of the replay's run id (same payloads; the metadata handed over
//! when the recorder has no `--meta`).

use super::recording::{out_file, read_finished, record, replay};
use super::serial;
use etp_runtime::recording;
use etp_tests::{EtpRun, kill, unique_run_id};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

/// Per-channel payload sequences, in file order (the run tag included).
fn channel_payloads(file: &Path) -> BTreeMap<String, Vec<Vec<u8>>> {
    let c = read_finished(file);
    let mut out: BTreeMap<String, Vec<Vec<u8>>> = BTreeMap::new();
    for m in c.messages {
        out.entry(m.topic).or_default().push(m.data);
    }
    out
}

/// `etp replay publish` puts the traffic back on iceoryx2: a recorder on the
/// replay's run id writes the same payloads, channel by channel, in the same
/// order (replay(A) == A), and `--rate` slows it to the recorded timing.
#[test]
fn publish_replays_every_message_and_a_recorder_gets_the_same_file() {
    use std::io::{BufRead, BufReader, Read};
    let _serial = serial();
    let (a, b) = (unique_run_id("pub-a"), unique_run_id("pub-b"));
    let (fa, fb) = (out_file(&a), out_file(&b));
    record(&a, &fa, "30", "4");
    // The recorder of the replay gets the original's metadata (scenario…).
    let meta = std::env::temp_dir().join(format!("etp-test-{b}-meta.json"));
    let original = recording::read_lenient("a", &std::fs::read(&fa).expect("a")).expect("a");
    std::fs::write(
        &meta,
        serde_json::to_string(&original.metadata).expect("json"),
    )
    .expect("meta");

    let mut rec = EtpRun::spawn_binary(
        &b,
        "etp-recorder",
        &[
            "--run-id",
            &b,
            "--scenario",
            "winding-2d",
            "--out",
            &fb.display().to_string(),
            "--meta",
            &meta.display().to_string(),
        ],
    );
    let stdout = rec
        .child
        .as_mut()
        .and_then(|c| c.stdout.take())
        .expect("recorder stdout");
    let mut lines = BufReader::new(stdout);
    let mut ready = String::new();
    lines.read_line(&mut ready).expect("recorder output");
    assert_eq!(ready.trim(), "ready");

    let rate = 8.0;
    let p = replay(&[
        "publish",
        &fa.display().to_string(),
        "--rate",
        &rate.to_string(),
        "--run-id",
        &b,
    ]);
    let published = &p["published"];
    assert_eq!(published["messages"], p["messages"], "{published}");
    assert_eq!(published["undelivered"].as_u64(), Some(0), "{published}");
    let recorded = published["recorded_seconds"].as_f64().expect("span");
    let wall = published["wall_seconds"].as_f64().expect("wall");
    // Never ahead of the scaled recorded timing (behind is allowed: load).
    assert!(
        wall >= 0.95 * recorded / rate,
        "{wall} s for a {recorded} s recording at rate {rate}"
    );

    kill("-TERM", &rec.pid().to_string());
    let (ok, _, err) = rec.finish();
    assert!(ok, "recorder: {err}");
    let mut summary = String::new();
    lines
        .read_to_string(&mut summary)
        .expect("recorder summary");
    let rs: Value = serde_json::from_str(summary.trim()).expect("recorder JSON");
    assert_eq!(rs["messages"], p["messages"], "{rs}");

    let (pa, pb) = (channel_payloads(&fa), channel_payloads(&fb));
    assert_eq!(pa.keys().collect::<Vec<_>>(), pb.keys().collect::<Vec<_>>());
    for (topic, msgs) in &pa {
        assert!(
            msgs == &pb[topic],
            "channel {topic}: {} messages recorded, {} re-recorded, first difference at {:?}",
            msgs.len(),
            pb[topic].len(),
            msgs.iter().zip(&pb[topic]).position(|(x, y)| x != y)
        );
    }
    // The re-recorded file is a run of its own: it verifies too.
    let v = replay(&["verify", &fb.display().to_string()]);
    assert_eq!(
        v["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        v["verify"]
    );
    for f in [&fa, &fb, &meta] {
        let _ = std::fs::remove_file(f);
    }
}

/// An `etp-recorder` of run `run` (scenario open-2d, no `--meta`) writing
/// `out`, once it has said `ready`.
fn ready_recorder(run: &str, out: &Path) -> EtpRun {
    use std::io::{BufRead, BufReader};
    let mut rec = EtpRun::spawn_binary(
        run,
        "etp-recorder",
        &[
            "--run-id",
            run,
            "--scenario",
            "open-2d",
            "--out",
            &out.display().to_string(),
        ],
    );
    let stdout = rec
        .child
        .as_mut()
        .and_then(|c| c.stdout.take())
        .expect("recorder stdout");
    let mut ready = String::new();
    BufReader::new(stdout)
        .read_line(&mut ready)
        .expect("recorder output");
    assert_eq!(ready.trim(), "ready");
    rec
}

/// A recorder started by hand without `--meta` on the run id of a
/// `etp replay publish` gets the recording's metadata from the replay
/// (`recording::handover_path`): its copy names the run and scenario and
/// passes `--verify`, like the original.
#[test]
fn a_copy_recorded_from_publish_without_meta_verifies() {
    let _serial = serial();
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../recordings/fixtures/open-2d-4-episodes.mcap");
    let b = unique_run_id("pub-nometa");
    let fb = out_file(&b);
    let rec = ready_recorder(&b, &fb);
    let p = replay(&[
        "publish",
        &fixture.display().to_string(),
        "--rate",
        "inf",
        "--run-id",
        &b,
    ]);
    assert_eq!(p["published"]["undelivered"].as_u64(), Some(0), "{p}");
    kill("-TERM", &rec.pid().to_string());
    let (ok, _, err) = rec.finish();
    assert!(ok, "recorder: {err}");
    let original = replay(&[&fixture.display().to_string()]);
    let copy = replay(&["verify", &fb.display().to_string()]);
    assert_eq!(
        copy["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        copy["verify"]
    );
    for k in ["run_id", "scenario", "seed", "strategy", "transmissions"] {
        assert_eq!(copy[k], original[k], "{k}");
    }
    assert_eq!(messages(&copy), messages(&original), "counts");
    let _ = std::fs::remove_file(&fb);
}

/// A replay that ends before its recorder looks loses nothing: the recorder
/// is paused (SIGSTOP) before the replay starts, so it cannot attach to the
/// replay's publishers while they send. The replay waits at the attach
/// barrier (`recording::observers`) until the recorder, resumed, has
/// attached; the copy then has every message of every channel. Without the
/// barrier the replay ends in milliseconds and the paused recorder's copy
/// misses whole channels.
#[test]
fn a_replay_waits_for_a_paused_recorder_and_its_copy_misses_nothing() {
    use std::process::{Command, Stdio};
    let _serial = serial();
    let b = unique_run_id("pub-paused");
    let fb = out_file(&b);
    // One episode: every channel fits in its subscriber's buffer, so the
    // replay never stalls on a full buffer and, unless it waits, ends at once.
    let fixture = std::env::temp_dir().join(format!("etp-test-{b}-one-episode.mcap"));
    replay(&[
        "filter",
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../recordings/fixtures/open-2d-4-episodes.mcap")
            .display()
            .to_string(),
        &fixture.display().to_string(),
        "--episodes",
        "0",
    ]);
    let rec = ready_recorder(&b, &fb);
    kill("-STOP", &rec.pid().to_string());
    let mut publish = Command::new(etp_tests::bin_dir().join("etp"))
        .args(["replay", "publish"])
        .arg(&fixture)
        .args(["--rate", "inf", "--run-id", &b, "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("etp replay publish");
    // Long enough for the whole replay to end had it not waited.
    std::thread::sleep(std::time::Duration::from_secs(2));
    let waiting = publish.try_wait().expect("replay status").is_none();
    kill("-CONT", &rec.pid().to_string());
    let out = publish.wait_with_output().expect("replay output");
    assert!(
        out.status.success(),
        "replay: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(waiting, "the replay ended while its recorder was paused");
    kill("-TERM", &rec.pid().to_string());
    let (ok, _, err) = rec.finish();
    assert!(ok, "recorder: {err}");
    let original = replay(&[&fixture.display().to_string()]);
    let copy = replay(&[&fb.display().to_string()]);
    assert_eq!(messages(&copy), messages(&original), "counts");
    for f in [&fb, &fixture] {
        let _ = std::fs::remove_file(f);
    }
}

/// A summary's messages per channel, channels without a message left out:
/// the copy's recorder opens every channel this build records (`drift`
/// too), the fixture's had the channels of its own build.
fn messages(summary: &Value) -> BTreeMap<String, u64> {
    summary["counts"]
        .as_object()
        .expect("counts")
        .iter()
        .filter_map(|(k, v)| v.as_u64().filter(|n| *n > 0).map(|n| (k.clone(), n)))
        .collect()
}
