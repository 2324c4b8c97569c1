//! `etp synthesize` and `etp export` through the real binary: files
//! written, refusal to overwrite, byte-identical output for a seed on 1 and 2
//! threads.

use super::{etp_threads as etp, s};
use std::path::PathBuf;

fn fresh_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("etp-synth-cli-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn synthesize_writes_refuses_overwrite_and_exports_prism() {
    let dir = fresh_dir("a");
    let args = [
        "synthesize",
        "open-2d",
        "--samples",
        "40",
        "--seed",
        "3",
        "-o",
        s(&dir),
    ];
    let first = etp(&args, "2");
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let mdp = dir.join("mdp.bin");
    let bytes = std::fs::read(&mdp).expect("mdp.bin written");

    // No --force: refused, non-zero, file untouched.
    let again = etp(&args, "2");
    assert!(!again.status.success());
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(
        err.contains("already exists") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(std::fs::read(&mdp).expect("still there"), bytes);

    // Same seed on one thread, with --force: the same bytes.
    let mut forced = args.to_vec();
    forced.push("--force");
    let one = etp(&forced, "1");
    assert!(
        one.status.success(),
        "{}",
        String::from_utf8_lossy(&one.stderr)
    );
    assert!(
        std::fs::read(&mdp).expect("rewritten") == bytes,
        "1 vs 2 threads differ"
    );

    // PRISM export.
    let out = dir.join("prism");
    let e = etp(&["export", s(&dir), s(&out), "--format", "prism"], "2");
    assert!(e.status.success(), "{}", String::from_utf8_lossy(&e.stderr));
    for f in [
        "model.tra",
        "model.sta",
        "model.lab",
        "model.trew",
        "model.props",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let tra = std::fs::read_to_string(out.join("model.tra")).expect("tra");
    assert_eq!(tra.lines().next().map(|l| l.split(' ').count()), Some(3));
    let refused = etp(&["export", s(&dir), s(&out), "--format", "prism"], "2");
    assert!(!refused.status.success());

    // Issue 24 item 10: a strategy and a PRISM export of the old MDP do not
    // stay beside a front that --force replaced: they are moved (not
    // deleted) into stale-<secs>/, and the command says so.
    let st = etp(&["strategy", s(&dir), "--vertex", "0"], "1");
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let old_strategy = std::fs::read(dir.join("strategy.json")).expect("strategy.json");
    let again = etp(&forced, "2");
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(
        err.contains("strategy.json, prism") && err.contains("stale-"),
        "{err}"
    );
    assert!(!dir.join("strategy.json").exists() && !out.exists());
    let stale: Vec<_> = std::fs::read_dir(&dir)
        .expect("dir")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("stale-"))
        })
        .collect();
    assert_eq!(stale.len(), 1, "{stale:?}");
    assert_eq!(
        std::fs::read(stale[0].join("strategy.json")).expect("moved"),
        old_strategy
    );
    assert!(stale[0].join("prism/model.tra").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_arguments_fail_cleanly() {
    let dir = fresh_dir("b");
    let zero = etp(
        &["synthesize", "open-2d", "--samples", "0", "-o", s(&dir)],
        "1",
    );
    assert!(!zero.status.success());
    assert!(!dir.join("mdp.bin").exists());
    let missing = etp(&["export", s(&dir), s(&dir.join("p"))], "1");
    assert!(!missing.status.success());
    let unknown = etp(&["synthesize", "no-such-scenario", "-o", s(&dir)], "1");
    assert!(!unknown.status.success());
}

#[test]
fn merge_lumps_states_and_the_strategy_keeps_every_region() {
    let dir = fresh_dir("m");
    let out = etp(
        &[
            "synthesize",
            "open-2d",
            "--samples",
            "100",
            "--holdout-samples",
            "0",
            "--merge",
            "0.05",
            "--json",
            "-o",
            s(&dir),
        ],
        "2",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let before = v["mdp"]["merge"]["states_before"]
        .as_u64()
        .expect("states_before");
    let after = v["mdp"]["states"].as_u64().expect("states");
    assert!(after < before, "{after} states after lumping {before}");
    // Every region of the unlumped MDP is still in the strategy, with its lump's ω.
    let st = etp(&["strategy", s(&dir), "--vertex", "0", "--json"], "2");
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let text = std::fs::read_to_string(dir.join("strategy.json")).expect("strategy.json");
    let strategy: serde_json::Value = serde_json::from_str(&text).expect("strategy json");
    let rows = strategy["states"].as_array().expect("states").len() as u64;
    assert_eq!(rows, before);
    // A level outside (0, 1) is refused, naming the flag, writing nothing.
    let bad_dir = fresh_dir("m-bad");
    let bad = etp(
        &[
            "synthesize",
            "open-2d",
            "--samples",
            "20",
            "--merge",
            "1.5",
            "-o",
            s(&bad_dir),
        ],
        "1",
    );
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("--merge") && err.contains("(0, 1)"), "{err}");
    assert!(!bad_dir.join("mdp.bin").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
