//! `etp replay` on the committed fixture recording (a real 4-episode run of
//! open-2d) and on broken copies of it: exit codes, messages, and that no
//! existing file is ever overwritten.

use super::{Scratch, etp, fails_with, ok_json, s};
use std::path::PathBuf;

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/fixtures/open-2d-4-episodes.mcap")
}

#[test]
fn the_fixture_summarises_and_verifies() {
    let f = fixture();
    let v = ok_json(&["replay", s(&f), "--json", "--verify"]);
    assert_eq!(v["finished"].as_bool(), Some(true));
    assert_eq!(v["episodes"].as_u64(), Some(4));
    assert_eq!(v["scenario"].as_str(), Some("open-2d"));
    // The three-way count: sent = costed = received.
    assert!(v["measurements"].as_u64() > Some(0));
    assert_eq!(v["measurements"], v["ledger_transmissions"]);
    assert_eq!(v["measurements"], v["agent_received"]);
    assert_eq!(
        v["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        v["verify"]
    );
    assert_eq!(v["verify"]["episodes_checked"].as_u64(), Some(4));
}

#[test]
fn a_truncated_recording_is_summarised_with_exit_code_3() {
    let dir = Scratch::new("replay-trunc");
    let bytes = std::fs::read(fixture()).expect("fixture");
    let cut = dir.path("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).expect("write");
    let out = etp(&["replay", s(&cut), "--json"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("summary JSON");
    assert_eq!(v["finished"].as_bool(), Some(false));
    assert!(v["messages"].as_u64() > Some(100), "{v}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unfinished") && err.contains("--repair"),
        "{err}"
    );

    // --repair writes a finished copy holding every complete record.
    let fixed = dir.path("fixed.mcap");
    let r = ok_json(&["replay", s(&cut), "--repair", s(&fixed), "--json"]);
    let again = ok_json(&["replay", s(&fixed), "--json"]);
    assert_eq!(again["finished"].as_bool(), Some(true));
    assert_eq!(again["counts"], r["counts"]);
    // A cut header is not a recording at all.
    std::fs::write(&cut, &bytes[..5]).expect("write");
    fails_with(&["replay", s(&cut)], &["not an MCAP recording"]);
}

/// Byte ranges of the chunk records' bodies (MCAP: magic, then records of
/// opcode u8 + length u64 LE + body; chunks have opcode 0x06).
fn chunk_bodies(bytes: &[u8]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().expect("8 bytes")) as usize;
        let body = at + 9..at + 9 + len;
        if body.end > bytes.len() {
            break;
        }
        if bytes[at] == 0x06 {
            out.push(body.clone());
        }
        at = body.end;
    }
    out
}

#[test]
fn a_corrupted_recording_is_refused_unless_salvaged() {
    let dir = Scratch::new("replay-corrupt");
    let bytes = std::fs::read(fixture()).expect("fixture");
    let chunks = chunk_bodies(&bytes);
    assert!(chunks.len() >= 2, "the fixture has several chunks");
    // Damage inside the compressed data of the first and the last chunk.
    let targets = [&chunks[0], &chunks[chunks.len() - 1]].map(|c| (c.start + c.end) / 2);
    for at in targets {
        let mut bad = bytes.clone();
        for b in &mut bad[at..at + 16] {
            *b ^= 0x5a;
        }
        let f = dir.path(&format!("bad-{at}.mcap"));
        std::fs::write(&f, &bad).expect("write");
        fails_with(&["replay", s(&f)], &["is damaged", "--repair"]);
        let salvaged = dir.path(&format!("salvaged-{at}.mcap"));
        ok_json(&["replay", s(&f), "--repair", s(&salvaged), "--json"]);
        let v = ok_json(&["replay", s(&salvaged), "--json"]);
        assert_eq!(v["finished"].as_bool(), Some(true));
    }
    let garbage = dir.path("garbage.mcap");
    std::fs::write(&garbage, b"PK\x03\x04 not a recording").expect("write");
    fails_with(&["replay", s(&garbage)], &["not an MCAP recording"]);
    fails_with(
        &["replay", s(&dir.path("missing.mcap"))],
        &["reading", "missing.mcap"],
    );
}

#[test]
fn replay_never_overwrites_without_force() {
    let dir = Scratch::new("replay-force");
    let f = fixture();
    let taken = dir.path("taken.mcap");
    std::fs::write(&taken, b"precious").expect("write");
    fails_with(
        &["replay", s(&f), "--repair", s(&taken)],
        &["already exists", "--force"],
    );
    assert_eq!(std::fs::read(&taken).expect("read"), b"precious");
    // `etp run --record` onto an existing file is refused before anything starts.
    fails_with(
        &[
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            "0",
            "--record",
            s(&taken),
        ],
        &["already exists", "--force"],
    );
    assert_eq!(std::fs::read(&taken).expect("read"), b"precious");
    // The input itself is never an output, even with --force.
    let copy = dir.path("copy.mcap");
    std::fs::copy(&f, &copy).expect("copy");
    fails_with(
        &["replay", s(&copy), "--repair", s(&copy), "--force"],
        &["being read"],
    );
    assert_eq!(
        std::fs::read(&copy).expect("read"),
        std::fs::read(&f).expect("read")
    );
    ok_json(&["replay", s(&f), "--repair", s(&taken), "--force", "--json"]);
    assert_ne!(std::fs::read(&taken).expect("read"), b"precious");
}

#[test]
fn publish_options_are_checked() {
    let f = fixture();
    fails_with(
        &["replay", s(&f), "--publish", "--rate", "0"],
        &["rate must be > 0"],
    );
    fails_with(
        &["replay", s(&f), "--publish", "--rate", "fast"],
        &["not a number"],
    );
    fails_with(&["replay", s(&f), "--rate", "2"], &["--publish"]);
    fails_with(
        &["replay", s(&f), "--publish", "--run-id", "Bad_Id"],
        &["Bad_Id"],
    );
}

/// `etp` alone (no process binaries beside it, as after `cargo run -p etp` on
/// a fresh checkout) still runs a strategy as processes — it starts itself as
/// `etp process <name>` — and the recording verifies.
#[test]
fn etp_alone_runs_the_processes_itself() {
    let dir = Scratch::new("etp-alone");
    let lone = dir.path("etp");
    std::fs::copy(env!("CARGO_BIN_EXE_etp"), &lone).expect("copy etp");
    let rec = dir.path("alone.mcap");
    let run_id = format!("t{}-alone", std::process::id());
    let out = std::process::Command::new(&lone)
        .args([
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            "1.0518",
            "--episodes",
            "3",
            "--predict-episodes",
            "200",
            "--run-id",
            &run_id,
            "--record",
            s(&rec),
            "--json",
        ])
        .output()
        .expect("spawn etp");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    assert_eq!(v["episodes"].as_u64(), Some(3));
    for sensor in v["sensors"].as_array().expect("sensors") {
        assert_eq!(sensor["transmitted"], sensor["received"], "{sensor}");
    }
    let r = ok_json(&["replay", s(&rec), "--json", "--verify"]);
    assert_eq!(
        r["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        r["verify"]
    );
    let help = std::process::Command::new(&lone)
        .args(["process", "etp-agent", "--help"])
        .output()
        .expect("spawn etp");
    assert!(String::from_utf8_lossy(&help.stdout).contains("--run-id"));
}
