//! Interrupted runs recorded as they happened: `etp run --record`, SIGINT at
//! a seeded random moment, then `etp replay summary --json` of the recording
//! must report exactly the run's episodes and per-sensor counts, with the
//! same statistics (the same function counts both) and the cut episode under
//! `partial`, never as an outcome. Local runs, and runs with one remote
//! sensor across network namespaces (`remote.rs`).

use super::remote::{NS_OUT, certs_init, hosts, scratch};
use super::serial;
use etp_shared::rng::stream_rng;
use etp_tests::{
    EtpRun, bin_dir, kill, no_leftovers, processes_of_run, unique_run_id, wait_for_process,
};
use rand::RngExt;
use serde_json::Value;
use std::time::Duration;

/// Interrupts of each kind (local, one remote sensor): 20 in all.
const EACH: u64 = 10;

/// The seeded moment of interrupt `k` of `kind`: 0.8 … 3 s after the
/// coordinator started (mid-run; on a loaded machine the earliest may come
/// before every process said hello).
fn moment(kind: u64, k: u64) -> Duration {
    let mut rng = stream_rng(52, kind, k);
    Duration::from_millis(rng.random_range(800..3000))
}

fn run_args(episodes: &str, seed: &str, record: &str) -> Vec<String> {
    [
        "--scenario",
        "winding-2d",
        "--delta",
        "1.4986",
        "--episodes",
        episodes,
        "--seed",
        seed,
        "--record",
        record,
    ]
    .map(String::from)
    .to_vec()
}

/// `etp run`'s pid: the parent of its coordinator.
fn launcher_of(coordinator: u32) -> u32 {
    let stat = std::fs::read_to_string(format!("/proc/{coordinator}/stat")).unwrap_or_default();
    // `pid (comm) state ppid …`: the fields after the last `)`.
    stat.rsplit(')')
        .next()
        .and_then(|rest| rest.split_whitespace().nth(1))
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("no parent of pid {coordinator}: {stat}"))
}

/// `etp replay summary FILE --json`: (exit code, summary).
fn replay_summary(file: &std::path::Path) -> (Option<i32>, Value) {
    let out = std::process::Command::new(bin_dir().join("etp"))
        .args(["replay", "summary"])
        .arg(file)
        .arg("--json")
        .output()
        .expect("etp replay summary");
    let text = String::from_utf8_lossy(&out.stdout);
    let v = serde_json::from_str(text.trim()).unwrap_or_else(|e| {
        panic!(
            "replay JSON ({e}): {text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (out.status.code(), v)
}

/// The run's report and the replay of its recording say the same: episodes,
/// per-sensor counts, the statistics and the verdict; the cut episode (if
/// any message of it was recorded) is the only partial one.
pub(crate) fn assert_replay_is_the_run(what: &str, run: &Value, file: &std::path::Path) {
    let (code, rep) = replay_summary(file);
    assert_eq!(code, Some(0), "{what}: replay exit; {rep}");
    for k in [
        "episodes",
        "p_target",
        "p_target_ci95",
        "p_collision",
        "p_collision_ci95",
        "p_free",
        "energy_mean",
        "energy_mean_ci95",
        "prediction_check",
        "transmissions",
        "delivered",
        "lost",
        "received",
    ] {
        assert_eq!(run[k], rep[k], "{what}: `{k}` of the run and of its replay");
    }
    assert_eq!(
        run["degraded"], rep["degraded_episodes"],
        "{what}: degraded episodes"
    );
    let sensors = |v: &Value| -> Vec<Value> {
        v["sensors"]
            .as_array()
            .expect("sensors")
            .iter()
            .map(|s| {
                serde_json::json!([
                    s["name"],
                    s["transmissions"],
                    s["delivered"],
                    s["lost"],
                    s["received"]
                ])
            })
            .collect()
    };
    assert_eq!(sensors(run), sensors(&rep), "{what}: per-sensor counts");
    let episodes = run["episodes"].as_u64().expect("episodes");
    let partial: Vec<u64> = rep["partial"]["episodes"]
        .as_array()
        .expect("partial")
        .iter()
        .filter_map(Value::as_u64)
        .collect();
    assert!(
        partial.iter().all(|&e| e == episodes),
        "{what}: partial {partial:?}, the run reported {episodes} episodes"
    );
}

#[test]
fn interrupted_local_runs_replay_exactly_as_reported() {
    let _serial = serial();
    let started = std::time::Instant::now();
    for k in 0..EACH {
        let id = unique_run_id(&format!("intr{k}"));
        let file = std::env::temp_dir().join(format!("{id}.mcap"));
        let _ = std::fs::remove_file(&file);
        let args = run_args("100000", &(40 + k).to_string(), &file.display().to_string());
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let run = EtpRun::spawn(&id, &args);
        wait_for_process(&id, "etp-coordinator", None);
        let at = moment(0, k);
        std::thread::sleep(at);
        kill("-INT", &run.pid().to_string());
        let (code, out, err) = run.finish_code();
        // Before every process said hello the run never started: an error,
        // no report, nothing to replay.
        if code == Some(1) && err.contains("before every process was ready") {
            eprintln!("local interrupt {k} at {at:?}: before the run started");
            assert!(processes_of_run(&id).is_empty());
            let _ = std::fs::remove_file(&file);
            continue;
        }
        assert_eq!(code, Some(130), "interrupt {k} at {at:?}: {err}");
        let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
        eprintln!("local interrupt {k} at {at:?}: {} episodes", v["episodes"]);
        assert_replay_is_the_run(&format!("local interrupt {k} at {at:?}"), &v, &file);
        let _ = std::fs::remove_file(&file);
        assert!(processes_of_run(&id).is_empty());
        no_leftovers(&id).expect("an interrupted run leaves nothing behind");
    }
    eprintln!(
        "{EACH} interrupted local runs: {:.1} s",
        started.elapsed().as_secs_f64()
    );
}

#[test]
fn interrupted_runs_with_a_remote_sensor_replay_exactly_as_reported() {
    let _serial = serial();
    let Some(h) = hosts("intr", 1) else { return };
    let started = std::time::Instant::now();
    let dir = scratch("intr");
    certs_init(&dir.join("keys"), &["b"]);
    let keys = format!("{NS_OUT}/keys");
    for k in 0..EACH {
        let id = unique_run_id(&format!("rintr{k}"));
        let name = format!("{id}.mcap");
        let _ = std::fs::remove_file(dir.join(&name));
        let mut args = run_args("100000", &(60 + k).to_string(), &format!("{NS_OUT}/{name}"));
        args.extend(
            [
                "--run-id",
                id.as_str(),
                "--listen",
                "tls/0.0.0.0:7463",
                "--tls",
                &keys,
                "--remote",
                "s1",
                "--json",
                "--join-timeout",
                "60",
            ]
            .map(String::from),
        );
        let mut all = vec!["run"];
        all.extend(args.iter().map(String::as_str));
        let run = h.spawn_out(&h.agent, &dir, &all);
        let host = h.spawn_out(
            &h.sensors[0],
            &dir,
            &[
                "sensor-host",
                "--connect",
                "tls/10.77.1.1:7463",
                "--tls",
                &format!("{keys}/b"),
                "--name",
                "b",
                "--join-timeout",
                "60",
            ],
        );
        let coordinator = wait_for_process(&id, "etp-coordinator", None);
        let at = moment(1, k);
        std::thread::sleep(at);
        kill("-INT", &launcher_of(coordinator).to_string());
        let (code, out, err) = run.finish();
        drop(host);
        assert_eq!(code, Some(130), "remote interrupt {k} at {at:?}: {err}");
        let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
        eprintln!("remote interrupt {k} at {at:?}: {} episodes", v["episodes"]);
        assert_replay_is_the_run(
            &format!("remote interrupt {k} at {at:?}"),
            &v,
            &dir.join(&name),
        );
        let _ = std::fs::remove_file(dir.join(&name));
    }
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "{EACH} interrupted runs with a remote sensor: {:.1} s",
        started.elapsed().as_secs_f64()
    );
}
