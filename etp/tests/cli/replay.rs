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
    let v = ok_json(&["replay", "verify", s(&f), "--json"]);
    assert_eq!(v["finished"].as_bool(), Some(true));
    assert_eq!(v["episodes"].as_u64(), Some(4));
    assert_eq!(v["scenario"].as_str(), Some("open-2d"));
    // The three-way count: sent = costed = received.
    assert!(v["measurements"].as_u64() > Some(0));
    assert_eq!(v["measurements"], v["transmissions"]);
    assert_eq!(v["measurements"], v["received"]);
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
        err.contains("unfinished") && err.contains("replay repair"),
        "{err}"
    );

    // `repair` writes a finished copy holding every complete record.
    let fixed = dir.path("fixed.mcap");
    let r = ok_json(&["replay", "repair", s(&cut), s(&fixed), "--json"]);
    let again = ok_json(&["replay", s(&fixed), "--json"]);
    assert_eq!(again["finished"].as_bool(), Some(true));
    assert_eq!(again["counts"], r["counts"]);
    // A cut header is not a recording at all.
    std::fs::write(&cut, &bytes[..5]).expect("write");
    fails_with(&["replay", s(&cut)], &["not an MCAP recording"]);
}

/// The top-level records of a whole MCAP file: (opcode, start of the
/// record, range of its body). MCAP: magic, then records of opcode u8 +
/// length u64 LE + body; chunks have opcode 0x06, the data end 0x0F.
fn records(bytes: &[u8]) -> Vec<(u8, usize, std::ops::Range<usize>)> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().expect("8 bytes")) as usize;
        let body = at + 9..at + 9 + len;
        if body.end > bytes.len() {
            break;
        }
        out.push((bytes[at], at, body.clone()));
        at = body.end;
    }
    out
}

/// Byte ranges of the chunk records' bodies.
fn chunk_bodies(bytes: &[u8]) -> Vec<std::ops::Range<usize>> {
    records(bytes)
        .into_iter()
        .filter(|(op, ..)| *op == 0x06)
        .map(|(_, _, body)| body)
        .collect()
}

/// `etp replay` of `file`: (exit code, stdout, stderr).
fn replay_code(file: &std::path::Path) -> (Option<i32>, String, String) {
    let out = etp(&["replay", s(file), "--json"]);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A cut file, however it was cut, is unfinished (exit 3), never damaged;
/// `--repair` makes a finished copy that passes `--verify`. The cuts: inside
/// a record header, inside a chunk, inside the metadata, at a record
/// boundary, in the summary, in the end magic — and the file a killed
/// recorder leaves: the chunk the mcap writer had open, whose length is
/// still its placeholder u64::MAX.
#[test]
fn every_cut_of_a_recording_is_unfinished_and_repairs_to_a_verifying_copy() {
    let dir = Scratch::new("replay-cuts");
    let bytes = std::fs::read(fixture()).expect("fixture");
    let recs = records(&bytes);
    let chunks: Vec<_> = recs.iter().filter(|(op, ..)| *op == 0x06).collect();
    let (_, data_end, _) = recs
        .iter()
        .find(|(op, ..)| *op == 0x0F)
        .expect("a data end record");
    let mid = |r: &std::ops::Range<usize>| (r.start + r.end) / 2;
    let mut cuts = vec![
        ("in the first record header", recs[0].1 + 5),
        ("in the metadata", mid(&recs[1].2)),
        ("in the first chunk header", chunks[0].2.start + 10),
        ("in the first chunk's data", mid(&chunks[0].2)),
        ("at a chunk boundary", chunks[1].1),
        ("in the last chunk's data", mid(&chunks[chunks.len() - 1].2)),
        ("in the data end record", data_end + 4),
        ("in the summary", (data_end + bytes.len()) / 2),
        ("in the end magic", bytes.len() - 3),
    ];
    // 20 more, evenly spread.
    for i in 1..=20 {
        cuts.push(("spread", i * bytes.len() / 21));
    }
    let mut last_messages = 0;
    for (what, at) in cuts.iter().copied() {
        let cut = dir.path(&format!("cut-{at}.mcap"));
        std::fs::write(&cut, &bytes[..at]).expect("write");
        let (code, out, err) = replay_code(&cut);
        assert_eq!(code, Some(3), "cut {what} at {at}: {err}");
        assert!(err.contains("unfinished"), "cut {what} at {at}: {err}");
        let v: serde_json::Value = serde_json::from_str(&out).expect("summary JSON");
        assert_eq!(v["finished"].as_bool(), Some(false));
        if what == "spread" {
            // A longer prefix never holds fewer complete messages.
            let n = v["messages"].as_u64().expect("messages");
            assert!(n >= last_messages, "cut at {at}: {n} < {last_messages}");
            last_messages = n;
        }
    }

    // What `kill -9` of the recorder leaves: complete chunks, then the open
    // chunk: its placeholder header (length, sizes and CRC all ones) and
    // the part of its compressed data that reached the file.
    let (_, last_start, last_body) = chunks[chunks.len() - 1].clone();
    let mut killed = bytes[..last_start].to_vec();
    killed.push(0x06);
    killed.extend_from_slice(&u64::MAX.to_le_bytes());
    killed.extend_from_slice(&0u64.to_le_bytes()); // message start time
    killed.extend_from_slice(&0u64.to_le_bytes()); // message end time
    killed.extend_from_slice(&u64::MAX.to_le_bytes()); // uncompressed size
    killed.extend_from_slice(&u32::MAX.to_le_bytes()); // uncompressed CRC
    killed.extend_from_slice(&4u32.to_le_bytes());
    killed.extend_from_slice(b"zstd");
    killed.extend_from_slice(&u64::MAX.to_le_bytes()); // compressed size
    let data_start = last_body.start + 8 + 8 + 8 + 4 + 4 + 4 + 8;
    killed.extend_from_slice(&bytes[data_start..data_start + 1000]);
    let file = dir.path("killed.mcap");
    std::fs::write(&file, &killed).expect("write");
    let (code, out, err) = replay_code(&file);
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("unfinished"), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("summary JSON");
    assert!(
        v["truncated"]
            .as_str()
            .is_some_and(|t| t.contains("placeholder")),
        "{v}"
    );
    assert!(v["episodes"].as_u64() >= Some(1), "{v}");

    // --repair: a finished copy of every complete record, which verifies.
    for (name, src) in [
        ("killed", file),
        (
            "in-chunk",
            dir.path(&format!("cut-{}.mcap", mid(&chunks[chunks.len() - 1].2))),
        ),
        (
            "in-summary",
            dir.path(&format!("cut-{}.mcap", (data_end + bytes.len()) / 2)),
        ),
    ] {
        let fixed = dir.path(&format!("fixed-{name}.mcap"));
        let r = ok_json(&["replay", "repair", s(&src), s(&fixed), "--json"]);
        let v = ok_json(&["replay", "verify", s(&fixed), "--json"]);
        assert_eq!(v["finished"].as_bool(), Some(true), "{name}");
        assert_eq!(v["counts"], r["counts"], "{name}");
        assert_eq!(
            v["verify"]["passed"].as_bool(),
            Some(true),
            "{name}: {}",
            v["verify"]
        );
    }
}

/// 40 single-bit flips at deterministic positions across the data section
/// (magic to data end record, metadata and chunks included) of a finished
/// recording: every one is refused as damaged (exit 1) with a message.
#[test]
fn forty_bit_flips_in_the_data_section_are_all_refused() {
    let dir = Scratch::new("replay-flips");
    let bytes = std::fs::read(fixture()).expect("fixture");
    let (_, data_end, body) = records(&bytes)
        .into_iter()
        .find(|(op, ..)| *op == 0x0F)
        .expect("a data end record");
    let end = body.end;
    assert!(data_end > bytes.len() / 2);
    let mut codes = std::collections::BTreeMap::new();
    for i in 0..40usize {
        let at = 8 + i * (end - 9) / 39;
        let mut bad = bytes.clone();
        bad[at] ^= 1 << (i % 8);
        let f = dir.path(&format!("flip-{i}.mcap"));
        std::fs::write(&f, &bad).expect("write");
        let (code, _, err) = replay_code(&f);
        assert_eq!(code, Some(1), "bit {} of byte {at} flipped: {err}", i % 8);
        assert!(err.contains("damaged"), "byte {at}: {err}");
        *codes
            .entry(err.lines().next().map(str::to_string))
            .or_insert(0) += 1;
    }
    assert!(codes.len() > 1, "{codes:?}");
}

/// Metadata edited (a sensor's cost 1.0 → 9.0 in the recorded scenario, or
/// a δ of the recorded strategy): refused with exit 1 — by the data-section
/// CRC in a finished file, by the scenario hashes in an unfinished one (no
/// CRC there).
#[test]
fn edited_metadata_is_refused() {
    let dir = Scratch::new("replay-meta");
    let bytes = std::fs::read(fixture()).expect("fixture");
    let first_chunk = chunk_bodies(&bytes)[0].start;
    let edit = |from: &[u8], to: &[u8]| {
        assert_eq!(from.len(), to.len());
        let at = bytes[..first_chunk]
            .windows(from.len())
            .position(|w| w == from)
            .expect("text in the metadata");
        let mut b = bytes.clone();
        b[at..at + to.len()].copy_from_slice(to);
        b
    };
    for (name, edited, needle) in [
        (
            "cost",
            edit(b"cost = 1.0", b"cost = 9.0"),
            "scenario hash mismatch",
        ),
        (
            // The recorded strategy's Δ: its seal (`content_sha256`) no
            // longer matches.
            "delta",
            edit(b"\n    1.0518,\n", b"\n    3.5000,\n"),
            "was changed after it was written",
        ),
    ] {
        let whole = dir.path(&format!("{name}.mcap"));
        std::fs::write(&whole, &edited).expect("write");
        let (code, _, err) = replay_code(&whole);
        assert_eq!(code, Some(1), "{name}: {err}");
        assert!(
            err.contains("damaged") && err.contains("Data section CRC"),
            "{name}: {err}"
        );
        let cut = dir.path(&format!("{name}-cut.mcap"));
        std::fs::write(&cut, &edited[..edited.len() * 6 / 10]).expect("write");
        let (code, _, err) = replay_code(&cut);
        assert_eq!(code, Some(1), "{name}: {err}");
        assert!(
            err.contains("damaged") && err.contains(needle),
            "{name}: {err}"
        );
        // `repair` still copies the records (with a warning).
        let fixed = dir.path(&format!("{name}-fixed.mcap"));
        let out = etp(&["replay", "repair", s(&cut), s(&fixed), "--json"]);
        assert!(out.status.success(), "{out:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(needle));
    }
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
        fails_with(&["replay", s(&f)], &["is damaged", "replay repair"]);
        let salvaged = dir.path(&format!("salvaged-{at}.mcap"));
        ok_json(&["replay", "repair", s(&f), s(&salvaged), "--json"]);
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
        &["replay", "repair", s(&f), s(&taken)],
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
        &["replay", "repair", s(&copy), s(&copy), "--force"],
        &["being read"],
    );
    assert_eq!(
        std::fs::read(&copy).expect("read"),
        std::fs::read(&f).expect("read")
    );
    ok_json(&["replay", "repair", s(&f), s(&taken), "--force", "--json"]);
    assert_ne!(std::fs::read(&taken).expect("read"), b"precious");
}

#[test]
fn publish_options_are_checked() {
    let f = fixture();
    fails_with(
        &["replay", "publish", s(&f), "--rate", "0"],
        &["rate must be > 0"],
    );
    fails_with(
        &["replay", "publish", s(&f), "--rate", "fast"],
        &["not a number"],
    );
    fails_with(&["replay", s(&f), "--rate", "2"], &["--rate"]);
    fails_with(
        &["replay", "publish", s(&f), "--run-id", "Bad_Id"],
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
    // Another test forking while the copy was open for writing leaves the
    // new file busy in that child for a moment (ETXTBSY): retry.
    let spawn = |args: &[&str]| {
        for _ in 0..50 {
            match std::process::Command::new(&lone).args(args).output() {
                Err(e) if e.kind() == std::io::ErrorKind::ExecutableFileBusy => {
                    std::thread::sleep(std::time::Duration::from_millis(100));
                }
                r => return r.expect("spawn etp"),
            }
        }
        panic!("{} stayed busy for 5 s", lone.display());
    };
    let out = spawn(&[
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
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    assert_eq!(v["episodes"].as_u64(), Some(3));
    for sensor in v["sensors"].as_array().expect("sensors") {
        assert_eq!(sensor["transmissions"], sensor["received"], "{sensor}");
    }
    let r = ok_json(&["replay", "verify", s(&rec), "--json"]);
    assert_eq!(
        r["verify"]["passed"].as_bool(),
        Some(true),
        "{}",
        r["verify"]
    );
    let help = spawn(&["process", "etp-agent", "--help"]);
    assert!(String::from_utf8_lossy(&help.stdout).contains("--run-id"));
}
