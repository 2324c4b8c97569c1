//! Files a command reads are checked, and names cannot escape: an `mdp.bin`
//! with any flipped bit, a `strategy.json` whose Δ was edited, a scenario
//! named `../../escape`.

use super::{Scratch, etp, fails_with, ok_json, s};
use etp_shared::strategy::Strategy;

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
        fails_with(&["export", s(&broken), s(&dir.path("prism"))], &[needle]);
    }
    assert!(!dir.path("prism").exists());

    // A strategy whose δ were edited (still well-formed JSON, still a
    // distribution over its thresholds): refused by every reader of
    // strategy files before anything runs — its seal no longer matches.
    let strategy = out.join("strategy.json");
    let text = std::fs::read_to_string(&strategy).expect("strategy");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    v["deltas"][1] = serde_json::json!(3.5);
    let bent = dir.path("bent.json");
    std::fs::write(&bent, serde_json::to_string_pretty(&v).expect("JSON")).expect("write");
    fails_with(
        &["validate", s(&bent), "--episodes", "5"],
        &["changed after it was written", "etp strategy"],
    );
    let rec = dir.path("bent.mcap");
    fails_with(
        &["run", s(&bent), "--episodes", "2", "--record", s(&rec)],
        &["changed after it was written"],
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
    // (looked up among the built-ins): `etp run --scenario` path too. A
    // file re-sealed after the edit (forged) still meets the Δ check.
    let dir = Scratch::new("integrity-builtin");
    let out = synthesize(&dir);
    let text = std::fs::read_to_string(out.join("strategy.json")).expect("strategy");
    let mut st = Strategy::from_sealed_json(&text).expect("sealed");
    st.policy.scenario_toml = None;
    let n = st.policy.deltas.len();
    st.policy.deltas[n - 1] = 3.5;
    let bent = dir.path("bent.json");
    std::fs::write(&bent, st.to_json()).expect("write");
    fails_with(&["validate", s(&bent)], &["`deltas`"]);
    fails_with(
        &["run", s(&bent), "--scenario", "open-2d", "--episodes", "1"],
        &["`deltas`"],
    );
}

/// Issue 24 item 4: every field of `strategy.json` is covered by its seal
/// (`scenario_name`, `predicted`, `leg_energy`, …: exit 1 naming what to
/// do); a file without the seal is refused the same way; and `etp validate`
/// exits 6 when a check FAILS, after printing the report.
#[test]
fn every_field_of_a_strategy_is_sealed_and_a_failing_check_exits_6() {
    let dir = Scratch::new("integrity-seal");
    let out = synthesize(&dir);
    let path = out.join("strategy.json");
    let text = std::fs::read_to_string(&path).expect("strategy");
    let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    let p_target = v["predicted"]["p_target"].to_string();
    let first_leg = v["leg_energy"][0].to_string();
    for (from, to) in [
        (
            "\"scenario_name\": \"open-2d\"".to_string(),
            "\"scenario_name\": \"winding-2d\"".to_string(),
        ),
        (
            format!("\"p_target\": {p_target}"),
            "\"p_target\": 0.5".to_string(),
        ),
        (
            format!("\"leg_energy\": [\n    {first_leg}"),
            "\"leg_energy\": [\n    0.0".to_string(),
        ),
    ] {
        assert!(text.contains(&from), "{from}");
        let edited = dir.path("edited.json");
        std::fs::write(&edited, text.replacen(&from, &to, 1)).expect("write");
        let o = etp(&["validate", s(&edited), "--episodes", "5"]);
        assert_eq!(o.status.code(), Some(1), "{from}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("changed after it was written") && err.contains("etp strategy"),
            "{from}: {err}"
        );
    }
    // Written before the seal: refused, saying what to do.
    let unsealed = dir.path("unsealed.json");
    let old = text[..text.rfind(",\n  \"content_sha256\"").expect("seal")].to_string() + "\n}";
    std::fs::write(&unsealed, old).expect("write");
    fails_with(
        &["validate", s(&unsealed), "--episodes", "5"],
        &["no `content_sha256`", "etp strategy"],
    );
    // A sealed strategy whose prediction is far from what it does: the
    // report is printed, then exit 6 naming the failing check.
    let mut st = Strategy::from_sealed_json(&text).expect("sealed");
    if let Some(p) = st.predictions.predicted.as_mut() {
        p.p_target = if p.p_target > 0.5 { 0.05 } else { 0.95 };
    }
    let wrong = dir.path("wrong.json");
    std::fs::write(&wrong, st.to_json()).expect("write");
    let o = etp(&["validate", s(&wrong), "--episodes", "300", "--json"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(6), "{err}");
    assert!(err.contains("predicted P_tar"), "{err}");
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).expect("report first");
    assert!(
        report["checks"]
            .as_array()
            .expect("checks")
            .iter()
            .any(|c| c["holds"] == false)
    );
    let help = String::from_utf8_lossy(&etp(&["validate", "--help"]).stdout).into_owned();
    assert!(
        help.contains("Exit codes") && help.contains("6 a check FAILS"),
        "{help}"
    );
    let help = String::from_utf8_lossy(&etp(&["run", "--help"]).stdout).into_owned();
    assert!(
        help.contains("Exit codes") && help.contains("4 an accounting"),
        "{help}"
    );
}
