//! `etp run --record` and `etp replay`: the recording against the run's
//! report and the independent Python `mcap` reader, a recorder killed by
//! SIGKILL, and determinism of the recorded payloads.

use super::{DELTA, num, serial};
use etp_runtime::recording;
use etp_tests::{EtpRun, bin_dir, kill, processes_of_run, unique_run_id, wait_for_process};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

pub(super) fn out_file(id: &str) -> PathBuf {
    std::env::temp_dir().join(format!("etp-test-{id}.mcap"))
}

/// Where a run records before its recording is moved onto `file`.
pub(super) fn partial_file(file: &Path, run_id: &str) -> PathBuf {
    let name = file.file_name().expect("file name").to_string_lossy();
    file.with_file_name(format!("{name}.{run_id}.partial"))
}

pub(super) fn record(id: &str, file: &Path, episodes: &str, seed: &str) -> Value {
    let (ok, out, err) = EtpRun::spawn(
        id,
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--episodes",
            episodes,
            "--seed",
            seed,
            "--record",
            &file.display().to_string(),
        ],
    )
    .finish();
    assert!(ok, "etp run --record failed: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("bad JSON ({e}): {out}"))
}

pub(super) fn replay(args: &[&str]) -> Value {
    let out = Command::new(bin_dir().join("etp"))
        .arg("replay")
        .args(args)
        .arg("--json")
        .output()
        .expect("etp replay");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "etp replay failed: {}\nits JSON: {text}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("bad JSON ({e}): {text}"))
}

/// Run a Python script on `file` (its `sys.argv[1]`); its stdout as JSON.
pub(super) fn python_json(script: &str, file: &Path) -> Value {
    let out = Command::new(etp_tests::pyenv::python())
        .args(["-c", script, &file.display().to_string()])
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "python mcap could not read {}: {}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("python JSON")
}

/// A recording that must be finished and whole.
pub(super) fn read_finished(file: &Path) -> recording::Contents {
    let buf = std::fs::read(file).expect("recording");
    let c = recording::read_lenient("rec", &buf).expect("readable");
    assert!(c.finished && c.truncated.is_none(), "{}", file.display());
    c
}

/// Messages per channel as the Python `mcap` reader (make_reader: summary,
/// footer and all) sees them; also the summary's message count.
fn python_counts(file: &Path) -> (BTreeMap<String, u64>, u64) {
    let script = r#"
import sys, json
from mcap.reader import make_reader
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    s = r.get_summary()
    counts = {c.topic: 0 for c in s.channels.values()}
    for schema, channel, message in r.iter_messages(log_time_order=False):
        counts[channel.topic] += 1
    print(json.dumps({"counts": counts, "total": s.statistics.message_count}))
"#;
    let v = python_json(script, file);
    (
        serde_json::from_value(v["counts"].clone()).expect("counts"),
        v["total"].as_u64().expect("total"),
    )
}

#[test]
fn recording_counts_equal_the_report_and_measurements_equal_ledgers_and_received() {
    let _serial = serial();
    let id = unique_run_id("rec");
    let file = out_file(&id);
    let v = record(&id, &file, "60", "4");
    let counts: BTreeMap<String, u64> =
        serde_json::from_value(v["recording"]["counts"].clone()).expect("recording.counts");
    assert_eq!(v["recording"]["finished"].as_bool(), Some(true));
    let transmitted: u64 = v["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .map(|s| s["transmissions"].as_u64().expect("transmissions"))
        .sum();
    let received: u64 = v["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .map(|s| s["received"].as_u64().expect("received"))
        .sum();
    assert_eq!(
        counts["measurement"], transmitted,
        "measurement messages == ledgers"
    );
    assert_eq!(transmitted, received, "ledgers == agent received");
    assert_eq!(counts["outcome"] as f64, num(&v, "episodes"));
    // The run record names the scenario's content hash, and it is that of
    // the recorded scenario (what `etp replay` checks).
    let c = read_finished(&file);
    let scenario = recording::check_metadata(&c)
        .expect("consistent metadata")
        .expect("a recorded scenario");
    assert_eq!(
        c.meta(recording::META_RUN, recording::META_RUN_SCENARIO_HASH),
        Some(scenario.content_hash.as_str())
    );
    // The file alone.
    let r = replay(&[&file.display().to_string()]);
    assert_eq!(r["finished"].as_bool(), Some(true));
    let rc: BTreeMap<String, u64> = serde_json::from_value(r["counts"].clone()).expect("counts");
    assert_eq!(rc, counts);
    assert_eq!(r["measurements"].as_u64(), Some(transmitted));
    assert_eq!(r["transmissions"].as_u64(), Some(transmitted));
    assert_eq!(r["received"].as_u64(), Some(received));
    assert_eq!(r["episodes"].as_f64(), Some(num(&v, "episodes")));
    // The same statistics and verdict, from the same function (no
    // zero-width interval, no second kind of 95 %).
    for k in [
        "p_target",
        "p_target_ci95",
        "p_collision",
        "p_collision_ci95",
        "p_free_ci95",
        "energy_mean",
        "energy_mean_ci95",
        "prediction_check",
    ] {
        assert_eq!(v[k], r[k], "`{k}` of the run and of its replay");
    }
    // The independent reader.
    {
        let (py, total) = python_counts(&file);
        assert_eq!(py, counts, "python mcap counts == run report");
        assert_eq!(total, counts.values().sum::<u64>());
    }
    let _ = std::fs::remove_file(&file);
}

#[test]
fn a_killed_recorder_leaves_a_readable_file_and_repair_finishes_it() {
    let _serial = serial();
    let id = unique_run_id("reckill");
    let file = out_file(&id);
    let repaired = std::env::temp_dir().join(format!("etp-test-{id}-repaired.mcap"));
    let run = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            "0",
            "--episodes",
            "150",
            "--seed",
            "1",
            "--record",
            &file.display().to_string(),
        ],
    );
    let victim = wait_for_process(&id, "etp-recorder", None);
    // Kill it mid-run: once the file holds a few episodes (a fixed delay
    // measured the machine's load, not the recorder). The run records
    // beside its target (moved there at the end).
    let partial = partial_file(&file, &id);
    let start = std::time::Instant::now();
    while std::fs::metadata(&partial).map_or(0, |m| m.len()) < 200 * 1024 {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "the recording never grew"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    kill("-KILL", &victim.to_string());
    let (code, out, err) = run.finish_code();
    // The run goes on without its recorder, reports, and fails: the
    // recording it was asked for did not finish.
    assert_eq!(code, Some(4), "{err}");
    assert!(err.contains("the recording did not finish"), "{err}");
    let v: Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["recording"]["finished"].as_bool(), Some(false));
    assert!(processes_of_run(&id).is_empty());

    // The file is unfinished (exit 3), not damaged: the open chunk's
    // placeholder length (u64::MAX) is the cut, not corruption.
    let plain = Command::new(bin_dir().join("etp"))
        .args(["replay", &file.display().to_string(), "--json"])
        .output()
        .expect("etp replay");
    let stderr = String::from_utf8_lossy(&plain.stderr);
    assert_eq!(plain.status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains("unfinished") && !stderr.contains("damaged"),
        "{stderr}"
    );

    let r = replay(&[
        "repair",
        &file.display().to_string(),
        &repaired.display().to_string(),
    ]);
    assert_eq!(r["finished"].as_bool(), Some(false));
    let messages = r["messages"].as_u64().expect("messages");
    assert!(messages > 1000, "{r}");
    assert!(r["episodes"].as_u64().expect("episodes") >= 1, "{r}");
    let rr = replay(&["verify", &repaired.display().to_string()]);
    assert_eq!(rr["finished"].as_bool(), Some(true));
    // Every complete episode of the cut file still re-runs bit for bit.
    assert_eq!(
        rr["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        rr["verify"]
    );
    // The cut costs only the episodes at the end of the file. The recorder
    // drains its streams at different moments, so more than one episode may
    // be open at the cut (three on an idle machine): the summary's partial
    // episodes are exactly the last ones, every earlier episode is whole,
    // and verify accounts for every episode the file holds, re-running at
    // least one to its recorded end.
    let complete = r["episodes"].as_u64().expect("episodes");
    let partial: Vec<u64> = r["partial"]["episodes"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_u64).collect())
        .unwrap_or_default();
    let trailing: Vec<u64> = (complete..complete + partial.len() as u64).collect();
    assert_eq!(partial, trailing, "{r}");
    let checked = rr["verify"]["episodes_checked"].as_u64().expect("checked");
    let incomplete = rr["verify"]["episodes_incomplete"]
        .as_u64()
        .expect("incomplete");
    assert!(checked >= 1, "{}", rr["verify"]);
    assert_eq!(
        checked + incomplete,
        complete + partial.len() as u64,
        "{}",
        rr["verify"]
    );
    assert_eq!(rr["counts"], r["counts"]);
    {
        let (py, total) = python_counts(&repaired);
        assert_eq!(total, messages);
        let rc: BTreeMap<String, u64> =
            serde_json::from_value(r["counts"].clone()).expect("counts");
        assert_eq!(py, rc);
    }
    let _ = std::fs::remove_file(&file);
    let _ = std::fs::remove_file(&repaired);
}

/// Two runs recording to one path at once (issue 24 item 1): each records
/// beside the path; the first to finish links its recording into place, the
/// other finds the path taken, does not overwrite it, keeps its recording at
/// its partial name and exits 4 naming the path. The winner's file is whole
/// and verifies.
#[test]
fn two_runs_recording_to_one_path_do_not_both_write() {
    let _serial = serial();
    let (a, b) = (unique_run_id("same-a"), unique_run_id("same-b"));
    let file = out_file(&a);
    let _ = std::fs::remove_file(&file);
    let path = file.display().to_string();
    let args = [
        "--scenario",
        "winding-2d",
        "--delta",
        DELTA,
        "--episodes",
        "20",
        "--seed",
        "5",
        "--predict-episodes",
        "50",
        "--record",
        &path,
    ];
    let (ra, rb) = (EtpRun::spawn(&a, &args), EtpRun::spawn(&b, &args));
    let (code_a, out_a, err_a) = ra.finish_code();
    let (code_b, out_b, err_b) = rb.finish_code();
    assert!(
        (code_a == Some(0)) != (code_b == Some(0)),
        "exactly one run may record to {path}: a {code_a:?} ({err_a}), b {code_b:?} ({err_b})"
    );
    let (winner, loser, out, loser_code, loser_err) = if code_a == Some(0) {
        (&a, &b, out_a, code_b, err_b)
    } else {
        (&b, &a, out_b, code_a, err_a)
    };
    assert_eq!(loser_code, Some(4), "{loser_err}");
    let kept = partial_file(&file, loser);
    assert!(
        loser_err.contains(&path)
            && loser_err.contains("already exists")
            && loser_err.contains(&kept.display().to_string()),
        "{loser_err}"
    );
    let v: Value = serde_json::from_str(&out).expect("report of the recording run");
    assert_eq!(v["recording"]["finished"].as_bool(), Some(true));
    let c = read_finished(&file);
    assert_eq!(c.meta(recording::META_RUN, "run_id"), Some(winner.as_str()));
    // The loser's recording is whole too, at its partial name.
    let k = read_finished(&kept);
    assert_eq!(k.meta(recording::META_RUN, "run_id"), Some(loser.as_str()));
    let r = replay(&["verify", &path]);
    assert_eq!(
        r["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        r["verify"]
    );
    assert_eq!(r["episodes"].as_u64(), Some(20));
    assert!(!partial_file(&file, winner).exists());
    let _ = std::fs::remove_file(&file);
    let _ = std::fs::remove_file(&kept);
}

/// Issue 24 item 1: `--force` destroys nothing before the run ran — a run
/// refused before it starts leaves the old file and no partial file — and
/// a run whose target another `--force` run replaced meanwhile does not
/// clobber it: it says so, keeps its own recording beside, and exits 4.
#[test]
fn force_replaces_a_recording_only_after_the_run_and_never_a_file_replaced_meanwhile() {
    let _serial = serial();
    let (a, b, c) = (
        unique_run_id("force-a"),
        unique_run_id("force-b"),
        unique_run_id("force-c"),
    );
    let file = out_file(&a);
    let path = file.display().to_string();
    std::fs::write(&file, b"precious").expect("write");
    let run = |id: &str, delta: &str, episodes: &str| {
        EtpRun::spawn(
            id,
            &[
                "--scenario",
                "winding-2d",
                "--delta",
                delta,
                "--episodes",
                episodes,
                "--predict-episodes",
                "50",
                "--record",
                &path,
                "--force",
            ],
        )
    };
    // Refused before it ran: the old file stays, nothing beside it.
    let (code, _, err) = run(&a, "9.99", "10").finish_code();
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("9.99"), "{err}");
    assert_eq!(std::fs::read(&file).expect("old file"), b"precious");
    assert!(!partial_file(&file, &a).exists());

    // A long run A is recording with --force; run B --force replaces the
    // file first. A must not clobber B's recording.
    let long = run(&a, DELTA, "3000");
    let partial_a = partial_file(&file, &a);
    wait_until_recorded(&partial_a);
    assert_eq!(std::fs::read(&file).expect("old file"), b"precious");
    let (ok_b, out_b, err_b) = run(&b, DELTA, "5").finish();
    assert!(ok_b, "{err_b}");
    let vb: Value = serde_json::from_str(&out_b).expect("JSON");
    assert_eq!(vb["recording"]["path"].as_str(), Some(path.as_str()));
    assert_eq!(
        read_finished(&file).meta(recording::META_RUN, "run_id"),
        Some(b.as_str())
    );
    kill("-TERM", &long.pid().to_string());
    let (code, out, err) = long.finish_code();
    assert_eq!(code, Some(130), "{err}");
    assert!(
        err.contains("was replaced or removed during this run")
            && err.contains(&partial_a.display().to_string()),
        "{err}"
    );
    let va: Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(
        va["recording"]["path"].as_str(),
        Some(partial_a.display().to_string().as_str())
    );
    // B's recording is still the file; A's is whole beside it.
    assert_eq!(
        read_finished(&file).meta(recording::META_RUN, "run_id"),
        Some(b.as_str())
    );
    assert_eq!(
        read_finished(&partial_a).meta(recording::META_RUN, "run_id"),
        Some(a.as_str())
    );

    // A run whose own partial file is removed under it says so (exit 4)
    // and leaves the target alone.
    let victim = run(&c, DELTA, "3000");
    let partial_c = partial_file(&file, &c);
    wait_until_recorded(&partial_c);
    std::fs::remove_file(&partial_c).expect("remove");
    kill("-TERM", &victim.pid().to_string());
    let (code, _, err) = victim.finish_code();
    assert_eq!(code, Some(130), "{err}");
    assert!(err.contains("was removed during the run"), "{err}");
    assert_eq!(
        read_finished(&file).meta(recording::META_RUN, "run_id"),
        Some(b.as_str())
    );
    for f in [&file, &partial_a, &partial_c] {
        let _ = std::fs::remove_file(f);
    }
}

/// Wait (up to 120 s) until a run's recording in progress holds 64 KiB.
fn wait_until_recorded(partial: &Path) {
    let start = std::time::Instant::now();
    while std::fs::metadata(partial).map_or(0, |m| m.len()) < 64 * 1024 {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "{} never grew",
            partial.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Issue 24 item 1: a remote join that fails (nobody joins in time) is a
/// run that never ran: `--force` leaves the old recording as it was and no
/// partial file beside it.
#[test]
fn a_failed_remote_join_leaves_the_old_recording_alone() {
    let _serial = serial();
    let id = unique_run_id("join-fail");
    let file = out_file(&id);
    std::fs::write(&file, b"precious").expect("write");
    let port = 20_000 + std::process::id() % 20_000;
    let (code, _, err) = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            "open-2d",
            "--delta",
            "1.0518",
            "--episodes",
            "5",
            "--listen",
            &format!("tcp/127.0.0.1:{port}"),
            "--insecure",
            "--remote",
            "s1",
            "--join-timeout",
            "1",
            "--record",
            &file.display().to_string(),
            "--force",
        ],
    )
    .finish_code();
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(
        std::fs::read(&file).expect("old file"),
        b"precious",
        "{err}"
    );
    assert!(!partial_file(&file, &id).exists(), "{err}");
    assert!(processes_of_run(&id).is_empty());
    let _ = std::fs::remove_file(&file);
}

/// The recorder itself: a second recorder on the file of a first one fails
/// at once (non-zero, naming the path) and leaves that file alone; a closed
/// stdout does not stop the first from finishing its file (no panic, exit
/// 0); `RUST_LOG=info` logs its start and finish on stderr.
#[test]
fn a_recorder_never_opens_an_existing_file_and_survives_a_closed_stdout() {
    use std::io::{BufRead, BufReader};
    let _serial = serial();
    let (a, b) = (unique_run_id("rec-one"), unique_run_id("rec-two"));
    let file = out_file(&a);
    let _ = std::fs::remove_file(&file);
    let path = file.display().to_string();
    let recorder = |id: &str| {
        Command::new(bin_dir().join("etp-recorder"))
            .args(["--run-id", id, "--scenario", "winding-2d", "--out", &path])
            .env("RUST_LOG", "info")
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("spawning etp-recorder")
    };
    let mut first = recorder(&a);
    let guard = KillOnDrop(first.id());
    let mut lines = BufReader::new(first.stdout.take().expect("stdout"));
    let mut ready = String::new();
    lines.read_line(&mut ready).expect("recorder output");
    assert_eq!(ready.trim(), "ready");
    let header = std::fs::read(&file).expect("the first recorder's file");

    let mut second = recorder(&b);
    let start = std::time::Instant::now();
    while second.try_wait().expect("second recorder").is_none() {
        if start.elapsed() > Duration::from_secs(30) {
            let _ = second.kill();
            panic!("a second recorder on {path} did not refuse it (still running after 30 s)");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let second = second.wait_with_output().expect("second recorder");
    let err = String::from_utf8_lossy(&second.stderr);
    assert!(!second.status.success(), "{err}");
    assert!(err.contains(&path) && err.contains("exists"), "{err}");
    assert!(second.stdout.is_empty(), "never ready");
    assert_eq!(std::fs::read(&file).expect("still there"), header);

    // Close the first recorder's stdout, then stop it: it finishes the file.
    drop(lines);
    kill("-TERM", &first.id().to_string());
    let out = first.wait_with_output().expect("first recorder");
    std::mem::forget(guard);
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {log}", out.status);
    assert!(!log.contains("panicked"), "{log}");
    assert!(
        log.contains("recording") && log.contains("recording finished"),
        "{log}"
    );
    let c = read_finished(&file);
    assert!(c.messages.is_empty());
    let _ = std::fs::remove_file(&file);
    for id in [&a, &b] {
        if let Ok(run) = etp_runtime::wire::RunId::new(id) {
            etp_runtime::cleanup::remove_run(&run);
        }
    }
}

/// Kills a process (by pid) if the test fails before it ended.
struct KillOnDrop(u32);
impl Drop for KillOnDrop {
    fn drop(&mut self) {
        kill("-KILL", &self.0.to_string());
    }
}

/// Sorted payloads per channel without the run tag (the header's `run`, a
/// hash of the run id, set to 0 and the payload encoded again); `hello`
/// carries pids and is left out.
fn payloads(file: &Path) -> BTreeMap<String, Vec<Vec<u8>>> {
    let c = read_finished(file);
    let mut out: BTreeMap<String, Vec<Vec<u8>>> = BTreeMap::new();
    for m in c.messages.iter().filter(|m| m.topic != "hello") {
        let rec = m.decode().expect("decodes");
        // The payload's JSON is exact for finite f64 (shortest round trip).
        let mut v = rec.to_json();
        v["header"]["run"] = Value::from(0);
        out.entry(m.topic.clone())
            .or_default()
            .push(v.to_string().into_bytes());
    }
    // Channels with several publishers (ledger, …) interleave them in the
    // order the recorder happened to drain: compare as sorted multisets
    // (each payload carries its episode, step, leg and sender).
    for v in out.values_mut() {
        v.sort();
    }
    out
}

#[test]
fn the_same_seed_records_identical_payloads() {
    let _serial = serial();
    let (a, b) = (unique_run_id("det-a"), unique_run_id("det-b"));
    let (fa, fb) = (out_file(&a), out_file(&b));
    record(&a, &fa, "40", "9");
    record(&b, &fb, "40", "9");
    let (pa, pb) = (payloads(&fa), payloads(&fb));
    assert!(pa["measurement"].len() > 100);
    assert_eq!(pa.keys().collect::<Vec<_>>(), pb.keys().collect::<Vec<_>>());
    for (topic, msgs) in &pa {
        let other = &pb[topic];
        let diff = msgs.iter().zip(other).position(|(x, y)| x != y);
        assert!(
            msgs == other,
            "channel {topic} differs between two runs of seed 9: {} vs {} messages, first difference at {diff:?}: {:?} vs {:?}",
            msgs.len(),
            other.len(),
            diff.and_then(|i| msgs.get(i)),
            diff.and_then(|i| other.get(i)),
        );
    }
    for f in [&fa, &fb] {
        let v = replay(&["verify", &f.display().to_string()]);
        assert_eq!(
            v["verify"]["passed"].as_bool(),
            Some(true),
            "{}",
            v["verify"]
        );
        assert_eq!(v["verify"]["episodes_checked"].as_u64(), Some(40));
        assert_eq!(
            v["verify"]["priors_checked"].as_u64(),
            v["counts"]["slot"].as_u64(),
            "every slot's prior is checked"
        );
    }
    verify_detects_tampering(&fa);
    let _ = std::fs::remove_file(&fa);
    let _ = std::fs::remove_file(&fb);
}

/// `--verify` is not vacuous: one ulp on one recorded measurement, or one
/// lost slot, is found at the step it affects.
fn verify_detects_tampering(file: &Path) {
    use etp_runtime::recording::Recorded;
    let buf = std::fs::read(file).expect("recording");
    let clean = recording::read_lenient("rec", &buf).expect("readable");
    assert!(recording::verify(&clean).expect("verify").passed());

    let (i, m) = clean
        .messages
        .iter()
        .enumerate()
        .find_map(|(i, raw)| match raw.decode() {
            Ok(Recorded::Measurement(m)) if m.header.step > 3 => Some((i, m)),
            _ => None,
        })
        .expect("a measurement");
    let mut bent = m;
    bent.y[0] = bent.y[0].next_up();
    let mut tampered = clean.clone();
    tampered.messages[i].data = recording::encode(&bent).expect("encode");
    let r = recording::verify(&tampered).expect("verify");
    assert!(!r.passed());
    assert_eq!(r.mismatch_count, 1, "{:?}", r.mismatches);
    let first = &r.mismatches[0];
    assert_eq!(first.episode, m.header.episode);
    assert!(
        first.step == m.header.step || first.step == m.header.step + 1,
        "{first:?} vs measurement at step {}",
        m.header.step
    );

    let j = clean
        .messages
        .iter()
        .position(|raw| raw.topic == "slot")
        .expect("a slot");
    let mut lost = clean.clone();
    let slot = lost.messages.remove(j);
    let r = recording::verify(&lost).expect("verify");
    assert!(!r.passed());
    let Ok(Recorded::Slot(s)) = slot.decode() else {
        panic!("not a slot");
    };
    assert_eq!(
        (r.mismatches[0].episode, r.mismatches[0].step),
        (s.header.episode, s.header.step)
    );
}

/// `verify` counts a step once its slot is re-run: the step a collision
/// ends has none, so steps = measurements + silent slots, and with the
/// episodes' own steps: steps = Σ outcome steps − collisions. The text
/// names the collision steps, so that its numbers add up to the summary's.
#[test]
fn verify_steps_add_up_when_an_episode_collides() {
    let _serial = serial();
    let id = unique_run_id("steps");
    let file = out_file(&id);
    // δ = 2.2365 on winding-2d collides in about one episode of five; this
    // seed's 20 episodes hold collisions (the same seed, the same episodes).
    let (ok, _, err) = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            "2.2365",
            "--episodes",
            "20",
            "--seed",
            "3",
            "--record",
            &file.display().to_string(),
        ],
    )
    .finish();
    assert!(ok, "etp run --record failed: {err}");
    let r = replay(&["verify", &file.display().to_string()]);
    let v = &r["verify"];
    assert_eq!(v["passed"].as_bool(), Some(true), "{v}");
    let collisions = r["collision"]
        .as_u64()
        .unwrap_or_else(|| panic!("collisions in {r}"));
    assert!(collisions > 0, "no collision: the test shows nothing ({r})");
    let n = |k: &str| v[k].as_u64().unwrap_or_else(|| panic!("{k} in {v}"));
    assert_eq!(
        n("steps"),
        n("explicit_updates") + n("implicit_updates"),
        "{v}"
    );
    assert_eq!(n("steps"), num(&r, "steps") as u64 - collisions, "{r}");
    assert_eq!(n("collision_steps"), collisions, "{v}");
    let out = Command::new(bin_dir().join("etp"))
        .args(["replay", "verify", &file.display().to_string()])
        .output()
        .expect("etp replay verify");
    let text = String::from_utf8_lossy(&out.stdout);
    let said = format!(
        "({} steps: {} with a measurement, {} silent, {collisions} ended by a collision",
        num(&r, "steps"),
        n("explicit_updates"),
        n("implicit_updates")
    );
    assert!(text.contains(&said), "{said:?} not in {text}");
    let _ = std::fs::remove_file(&file);
}
