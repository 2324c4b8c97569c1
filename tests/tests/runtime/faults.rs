//! Faults as part of the design (the semantics of faults: `launcher/src/lib.rs`):
//! a paused or slow process is waited for and degrades nothing; SIGTERM
//! stops a run like Ctrl-C (partial report, recording finished, no files
//! left); a killed supervisor's folder is removed by the next start; the
//! exact three-way count survives a CPU hog and two runs at once.

use super::{DELTA, assert_ledgers_match, num, serial};
use etp_tests::{
    CpuHog, EtpRun, kill, no_leftovers, processes_of_run, run_folder, signal_run, unique_run_id,
    wait_for_process,
};
use serde_json::Value;
use std::time::Duration;

fn winding(episodes: &str, seed: &str) -> Vec<String> {
    [
        "--scenario",
        "winding-2d",
        "--delta",
        DELTA,
        "--episodes",
        episodes,
        "--seed",
        seed,
        "--episode-details",
    ]
    .map(String::from)
    .to_vec()
}

fn spawn(id: &str, args: &[String]) -> EtpRun {
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    EtpRun::spawn(id, &a)
}

/// A clean run: exit 0, every episode, nothing degraded, no fault, every
/// ledger equal to what the agent received, and nothing left behind.
fn assert_clean(id: &str, run: EtpRun, episodes: f64) -> Value {
    let (ok, out, err) = run.finish();
    assert!(ok, "etp run failed: {err}\n{out}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("bad JSON ({e}): {out}"));
    assert_eq!(num(&v, "episodes"), episodes);
    assert_eq!(num(&v, "degraded"), 0.0, "{}", v["faults"]);
    assert_eq!(v["faults"].as_array().map(Vec::len), Some(0));
    assert_ledgers_match(&v, false);
    assert!(processes_of_run(id).is_empty());
    no_leftovers(id).expect("nothing left of the run");
    v
}

/// Pause `pids` for `pause`, `times` times.
fn pause(pids: &[u32], pause: Duration, times: usize) {
    for _ in 0..times {
        for p in pids {
            kill("-STOP", &p.to_string());
        }
        std::thread::sleep(pause);
        for p in pids {
            kill("-CONT", &p.to_string());
        }
        std::thread::sleep(Duration::from_millis(30));
    }
}

/// Pause one process of a run mid-run: a 3 s pause (longer than any former
/// deadline) then ten 50 ms ones; the run completes exactly.
fn paused_process_is_waited_for(tag: &str, binary: &str, flag: Option<(&str, &str)>) {
    let _serial = serial();
    let id = unique_run_id(tag);
    let run = spawn(&id, &winding("300", "5"));
    let pid = wait_for_process(&id, binary, flag);
    std::thread::sleep(Duration::from_millis(700));
    pause(&[pid], Duration::from_secs(3), 1);
    pause(&[pid], Duration::from_millis(50), 10);
    assert_clean(&id, run, 300.0);
}

#[test]
fn a_paused_sensor_is_waited_for_and_nothing_degrades() {
    paused_process_is_waited_for("stop-s", "etp-sensor-node", Some(("--sensor", "s1")));
}

#[test]
fn a_paused_agent_is_waited_for() {
    paused_process_is_waited_for("stop-a", "etp-agent", None);
}

#[test]
fn a_paused_coordinator_is_waited_for() {
    paused_process_is_waited_for("stop-c", "etp-coordinator", None);
}

#[test]
fn the_whole_run_paused_and_resumed_completes_exactly() {
    let _serial = serial();
    let id = unique_run_id("stop-all");
    let run = spawn(&id, &winding("300", "6"));
    wait_for_process(&id, "etp-coordinator", None);
    std::thread::sleep(Duration::from_millis(700));
    // Ctrl-Z + fg of everything: supervisor, coordinator, agent, sensors.
    let supervisor = run.pid();
    let all: Vec<u32> = processes_of_run(&id)
        .into_iter()
        .map(|(p, _)| p)
        .chain([supervisor])
        .collect();
    pause(&all, Duration::from_secs(1), 1);
    signal_run(&id, "-CONT", &[supervisor]);
    assert_clean(&id, run, 300.0);
}

#[test]
fn sigterm_stops_the_run_with_a_partial_report_a_finished_recording_and_no_files() {
    let _serial = serial();
    let id = unique_run_id("term");
    let file = std::env::temp_dir().join(format!("{id}.mcap"));
    let _ = std::fs::remove_file(&file);
    let mut args = winding("100000", "8");
    args.extend(["--record".into(), file.display().to_string()]);
    let run = spawn(&id, &args);
    wait_for_process(&id, "etp-coordinator", None);
    std::thread::sleep(Duration::from_millis(1500));
    kill("-TERM", &run.pid().to_string());
    let (code, stdout, stderr) = run.finish_code();
    assert_eq!(code, Some(130), "{stderr}");
    let v: Value =
        serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("bad JSON ({e}): {stdout}"));
    let episodes = num(&v, "episodes");
    assert!(episodes > 0.0 && episodes < 100000.0, "{episodes}");
    assert_eq!(num(&v, "degraded"), 0.0);
    assert_ledgers_match(&v, false);
    assert_eq!(
        v["recording"]["finished"].as_bool(),
        Some(true),
        "{}",
        v["recording"]
    );
    assert!(stderr.contains("interrupted"), "{stderr}");
    // The recording is a finished file (replay exits 0).
    let replay = std::process::Command::new(etp_tests::bin_dir().join("etp"))
        .args(["replay", &file.display().to_string(), "--json"])
        .output()
        .expect("etp replay");
    assert!(
        replay.status.success(),
        "{}",
        String::from_utf8_lossy(&replay.stderr)
    );
    let _ = std::fs::remove_file(&file);
    assert!(processes_of_run(&id).is_empty());
    no_leftovers(&id).expect("SIGTERM leaves nothing behind");
}

#[test]
fn a_killed_supervisor_leaves_a_folder_that_the_next_start_removes() {
    let _serial = serial();
    let id = unique_run_id("kill9");
    let run = spawn(&id, &winding("100000", "9"));
    wait_for_process(&id, "etp-coordinator", None);
    std::thread::sleep(Duration::from_millis(500));
    kill("-KILL", &run.pid().to_string());
    // The run's processes notice their supervisor is gone and exit.
    let t = std::time::Instant::now();
    while !processes_of_run(&id).is_empty() {
        assert!(
            t.elapsed() < Duration::from_secs(10),
            "{:?}",
            processes_of_run(&id)
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(run_folder(&id).exists(), "kill -9 cannot clean up");
    drop(run);
    // The next run removes the dead run's folder (and its iceoryx2 files).
    let next = unique_run_id("kill9-next");
    let r = spawn(&next, &winding("3", "1"));
    assert_clean(&next, r, 3.0);
    no_leftovers(&id).expect("the next start removed the dead run");
}

#[test]
fn a_run_id_in_use_is_refused_clearly_and_too_many_sensors_too() {
    let _serial = serial();
    let id = unique_run_id("dup");
    let first = spawn(&id, &winding("100000", "1"));
    wait_for_process(&id, "etp-coordinator", None);
    let second = EtpRun::spawn_binary(
        &format!("{id}-other"),
        "etp",
        &[
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            DELTA,
            "--episodes",
            "2",
            "--run-id",
            &id,
        ],
    );
    let (ok, _, err) = second.finish();
    assert!(!ok);
    assert!(err.contains("in use"), "{err}");
    drop(first);
    let many = EtpRun::spawn_binary(
        "t-many",
        "etp",
        &[
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            DELTA,
            "--clone-sensors",
            "512",
        ],
    );
    let (ok, _, err) = many.finish();
    assert!(!ok);
    assert!(
        err.contains("--clone-sensors") && err.contains("from 1 to 64"),
        "{err}"
    );
}

/// A process killed while creating a service leaves an empty, write-only
/// shared-memory file. iceoryx2 0.10, removing the dead node's resources as
/// root, then retries opening it forever: the next `etp run`'s sweep of stale
/// runs (and a test's own cleanup) hung on it, a CI run among them. The
/// half-made file is reproduced here on a killed run; the next run must
/// sweep it and finish.
#[test]
fn a_service_left_half_made_by_a_killed_process_does_not_hang_the_next_run() {
    use std::os::unix::fs::PermissionsExt;
    let _serial = serial();
    let id = unique_run_id("half");
    let mut first = spawn(&id, &winding("100000", "1"));
    wait_for_process(&id, "etp-agent", None);
    std::thread::sleep(Duration::from_millis(500));
    // kill -9 of everyone: the run's files stay for the next start.
    kill("-KILL", &first.pid().to_string());
    for (pid, _) in processes_of_run(&id) {
        kill("-KILL", &pid.to_string());
    }
    if let Some(mut c) = first.child.take() {
        let _ = c.wait();
    }
    for _ in 0..250 {
        if processes_of_run(&id).is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let run = etp_runtime::wire::RunId::new(&id).expect("id");
    let dynamic = etp_runtime::cleanup::shm_files(&run)
        .into_iter()
        .find(|f| f.extension().is_some_and(|e| e == "dynamic"))
        .expect("a dynamic service config of the killed run");
    // As its creator leaves it between creating and sizing it.
    let f = std::fs::File::options()
        .write(true)
        .open(&dynamic)
        .expect("open");
    f.set_len(0).expect("truncate");
    f.set_modified(std::time::SystemTime::now() - Duration::from_secs(60))
        .expect("mtime");
    std::fs::set_permissions(&dynamic, std::fs::Permissions::from_mode(0o200)).expect("mode");
    // A run's folder is swept only once older than `cleanup::YOUNG` (a
    // starting run's is never taken): this one is made as old as that.
    std::fs::File::open(run.root_dir())
        .and_then(|d| {
            d.set_modified(
                std::time::SystemTime::now() - etp_runtime::cleanup::YOUNG - Duration::from_secs(1),
            )
        })
        .expect("the killed run's folder's mtime");
    let next = unique_run_id("half-next");
    let r = spawn(&next, &winding("5", "2"));
    let pid = r.pid();
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let watchdog = {
        let done = done.clone();
        std::thread::spawn(move || {
            for _ in 0..1800 {
                if done.load(std::sync::atomic::Ordering::Relaxed) {
                    return false;
                }
                std::thread::sleep(Duration::from_millis(100));
            }
            kill("-KILL", &format!("-{pid}"));
            true
        })
    };
    assert_clean(&next, r, 5.0);
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    assert!(!watchdog.join().expect("watchdog"), "the next run hung");
    no_leftovers(&id).expect("the killed run was swept");
}

/// The soak test: both cores saturated by a hog, runs back to back and two
/// at once; every count exact, exit 0, nothing degraded, every time.
#[test]
fn soak_under_a_cpu_hog_counts_stay_exact() {
    let _serial = serial();
    let _hog = CpuHog::start(2);
    for round in 0..2 {
        let a = unique_run_id(&format!("soak-a{round}"));
        let b = unique_run_id(&format!("soak-b{round}"));
        let ra = spawn(&a, &winding("150", &format!("{}", 20 + round)));
        let rb = spawn(&b, &winding("150", &format!("{}", 40 + round)));
        assert_clean(&a, ra, 150.0);
        assert_clean(&b, rb, 150.0);
    }
    let c = unique_run_id("soak-c");
    let rc = spawn(&c, &winding("300", "60"));
    assert_clean(&c, rc, 300.0);
}
