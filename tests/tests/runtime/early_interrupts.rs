//! An interrupt before the first episode: while `etp run` prepares, while
//! its processes start, while it waits for a remote host to join. It ends
//! the command with exit 130 and leaves nothing: no process of the run, no
//! iceoryx2 file, no run folder, and no recording (nothing ran). An
//! interrupt that lands once the episodes started gives the report of the
//! complete ones (exit 130), as `interrupts.rs` checks in depth.

use super::recording::partial_file;
use super::serial;
use etp_tests::{EtpRun, kill, no_leftovers, processes_of_run, run_folder, unique_run_id};
use serde_json::Value;
use std::time::Duration;

/// The words of an interrupt that came before any episode.
const NOTHING_RAN: &str = "before any episode: nothing ran";

fn assert_nothing_left(what: &str, id: &str, file: &std::path::Path) {
    assert!(
        processes_of_run(id).is_empty(),
        "{what}: processes left: {:?}",
        processes_of_run(id)
    );
    if let Err(e) = no_leftovers(id) {
        panic!("{what}: {e}");
    }
    assert!(
        !file.exists(),
        "{what}: a recording of a run that never ran"
    );
    assert!(
        !partial_file(file, id).exists(),
        "{what}: its partial recording was left"
    );
}

/// Until `pid` catches SIGINT (`SigCgt` in /proc): before that, in its
/// first milliseconds, a signal ends it by the default action, having
/// claimed nothing.
fn wait_until_it_listens(pid: u32) {
    let start = std::time::Instant::now();
    loop {
        let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
        let caught = status
            .lines()
            .find_map(|l| l.strip_prefix("SigCgt:"))
            .and_then(|h| u64::from_str_radix(h.trim(), 16).ok())
            .unwrap_or(0);
        // SIGINT is signal 2: bit 1.
        if caught & 0b10 != 0 {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "etp run never listened for SIGINT"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// `etp run` on winding-2d with `extra`, recorded to a file of its own.
fn recorded_run(id: &str, extra: &[&str]) -> (EtpRun, std::path::PathBuf) {
    let file = std::env::temp_dir().join(format!("etp-test-{id}.mcap"));
    let record = file.display().to_string();
    let mut args = vec!["--scenario", "winding-2d", "--delta", "1.4986"];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--record", &record]);
    (EtpRun::spawn(id, &args), file)
}

#[test]
fn an_interrupt_before_any_episode_ends_the_run_with_130_and_leaves_nothing() {
    let _serial = serial();
    // From the moment it listens (before it claims anything) to its
    // processes' start; SIGINT and SIGTERM alike. On an idle machine the
    // first episode starts about 0.3 s after the spawn.
    let mut before = 0;
    for (k, (ms, sig)) in [
        (30, "-INT"),
        (60, "-TERM"),
        (120, "-INT"),
        (200, "-TERM"),
        (300, "-INT"),
    ]
    .into_iter()
    .enumerate()
    {
        let id = unique_run_id(&format!("early{k}"));
        let (run, file) = recorded_run(&id, &["--episodes", "100000"]);
        wait_until_it_listens(run.pid());
        std::thread::sleep(Duration::from_millis(ms));
        kill(sig, &run.pid().to_string());
        let (code, out, err) = run.finish_code();
        let what = format!("{sig} at {ms} ms");
        assert_eq!(code, Some(130), "{what}: {err}");
        if err.contains(NOTHING_RAN) {
            before += 1;
            assert!(out.trim().is_empty(), "{what}: a report of nothing: {out}");
            assert_nothing_left(&what, &id, &file);
        } else {
            // The episodes had started: the report of the complete ones.
            let v: Value =
                serde_json::from_str(&out).unwrap_or_else(|e| panic!("{what}: {e}: {err}"));
            assert!(v["aborted"].is_string(), "{what}: {v}");
            assert!(processes_of_run(&id).is_empty(), "{what}");
            if let Err(e) = no_leftovers(&id) {
                panic!("{what}: {e}");
            }
            let _ = std::fs::remove_file(&file);
        }
    }
    assert!(before >= 1, "no interrupt came before the first episode");

    // Waiting for a remote host that never joins (plain TCP on loopback).
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port();
    let id = unique_run_id("earlyjoin");
    let listen = format!("tcp/127.0.0.1:{port}");
    let (run, file) = recorded_run(
        &id,
        &[
            "--episodes",
            "100",
            "--listen",
            &listen,
            "--insecure",
            "--remote",
            "s1",
        ],
    );
    // The session is written just before the bridge starts and the run
    // waits for s1's host.
    let session = run_folder(&id).join("session.json");
    let waiting = std::time::Instant::now();
    while !session.exists() {
        assert!(
            waiting.elapsed() < Duration::from_secs(60),
            "the run never started its bridge"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(500));
    kill("-INT", &run.pid().to_string());
    let started = std::time::Instant::now();
    let (code, out, err) = run.finish_code();
    assert_eq!(code, Some(130), "{err}");
    assert!(
        err.contains("while waiting for the remote sensors to join") && err.contains(NOTHING_RAN),
        "{err}"
    );
    assert!(out.trim().is_empty(), "{out}");
    // Well within the join timeout (the bridge is stopped, not waited for).
    assert!(started.elapsed() < Duration::from_secs(10), "{err}");
    assert_nothing_left("SIGINT while waiting to join", &id, &file);
}
