//! Files a command reads are checked, and names cannot escape: an `mdp.bin`
//! with any flipped bit, a `strategy.json` whose Δ was edited, a scenario
//! named `../../escape`.

use super::{Scratch, fails_with, ok_json, s};

/// A small synthesis of open-2d (`DIR/mdp.bin`, `DIR/strategy.json`).
fn synthesize(dir: &Scratch) -> std::path::PathBuf {
    let out = dir.path("open");
    ok_json(&[
        "synthesize",
        "open-2d",
        "--samples",
        "40",
        "--seed",
        "3",
        "-o",
        s(&out),
        "--json",
    ]);
    ok_json(&["strategy", s(&out), "--vertex", "0", "--json"]);
    out
}

#[test]
fn flipped_bits_in_mdp_bin_and_edited_deltas_are_refused() {
    let dir = Scratch::new("integrity");
    let out = synthesize(&dir);
    let mdp = std::fs::read(out.join("mdp.bin")).expect("mdp.bin");

    // 16 single-bit flips spread over the file (header, body, checksum):
    // every one refused with a message saying what is wrong.
    let broken = dir.path("broken");
    std::fs::create_dir_all(&broken).expect("dir");
    for i in 0..16usize {
        let at = 12 + i * (mdp.len() - 13) / 15;
        let mut flipped = mdp.clone();
        flipped[at] ^= 1 << (i % 8);
        std::fs::write(broken.join("mdp.bin"), &flipped).expect("write");
        fails_with(
            &[
                "strategy",
                s(&broken),
                "--vertex",
                "0",
                "-o",
                s(&dir.path("x.json")),
            ],
            &["mdp.bin is corrupted: checksum mismatch"],
        );
        assert!(!dir.path("x.json").exists());
    }
    for (at, needle) in [(3, "not an etp MDP file"), (9, "format version")] {
        let mut flipped = mdp.clone();
        flipped[at] ^= 0x10;
        std::fs::write(broken.join("mdp.bin"), &flipped).expect("write");
        fails_with(
            &["export-prism", s(&broken), s(&dir.path("prism"))],
            &[needle],
        );
    }
    assert!(!dir.path("prism").exists());

    // A strategy whose δ were edited (still well-formed JSON, still a
    // distribution over its thresholds): refused by every reader of
    // strategies, naming the field, before anything runs.
    let strategy = out.join("strategy.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&strategy).expect("strategy")).expect("JSON");
    v["deltas"][1] = serde_json::json!(3.5);
    let bent = dir.path("bent.json");
    std::fs::write(&bent, v.to_string()).expect("write");
    fails_with(
        &["validate", s(&bent), "--episodes", "5"],
        &["`deltas`", "3.5"],
    );
    let rec = dir.path("bent.mcap");
    fails_with(
        &["run", s(&bent), "--episodes", "2", "--record", s(&rec)],
        &["`deltas`", "3.5"],
    );
    assert!(!rec.exists(), "nothing was started");
    // The unedited strategy still validates.
    ok_json(&["validate", s(&strategy), "--episodes", "5", "--json"]);
}

#[test]
fn a_scenario_name_cannot_escape_the_output_folder() {
    let dir = Scratch::new("escape");
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/open-2d.toml"),
    )
    .expect("open-2d.toml");
    let evil = text.replacen("name = \"open-2d\"", "name = \"../../escape\"", 1);
    assert_ne!(evil, text);
    let work = dir.path("work");
    std::fs::create_dir_all(&work).expect("dir");
    let file = work.join("evil.toml");
    std::fs::write(&file, evil).expect("write");
    fails_with(&["check", s(&file)], &["field `name`", "../../escape"]);
    // `synthesize` without -o would write out/<name>/: refused, nothing written.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_etp"))
        .args(["synthesize", s(&file), "--samples", "10"])
        .current_dir(&work)
        .output()
        .expect("spawn etp");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("field `name`"), "{err}");
    let written: Vec<_> = walk(dir.path(""));
    assert_eq!(
        written,
        vec![file.clone()],
        "synthesize wrote files: {written:?}"
    );
    // Nothing escaped either (`work/out/../../escape` is the scratch root's `escape`).
    assert!(!dir.path("escape").exists());
}

/// Every file under `root`.
fn walk(root: std::path::PathBuf) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![root];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d)
            .expect("read_dir")
            .filter_map(Result::ok)
        {
            let p = e.path();
            if p.is_dir() {
                todo.push(p);
            } else {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn an_edited_strategy_is_refused_by_etp_run_and_validate_with_a_builtin() {
    // The same refusal for a strategy without an embedded scenario text
    // (looked up among the built-ins): `etp run --scenario` path too.
    let dir = Scratch::new("integrity-builtin");
    let out = synthesize(&dir);
    let mut v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("strategy.json")).expect("strategy"),
    )
    .expect("JSON");
    v["scenario_toml"] = serde_json::Value::Null;
    let n = v["deltas"].as_array().map_or(0, Vec::len);
    v["deltas"][n - 1] = serde_json::json!(3.5);
    let bent = dir.path("bent.json");
    std::fs::write(&bent, v.to_string()).expect("write");
    fails_with(&["validate", s(&bent)], &["`deltas`"]);
    fails_with(
        &["run", s(&bent), "--scenario", "open-2d", "--episodes", "1"],
        &["`deltas`"],
    );
}
