//! Issue 24 item 10: the processes' logs, as a file or pipe receives them.

use std::process::Command;

/// Agent and coordinator both log an episode's outcome by name
/// (`outcome="target"`, never the code `outcome=1`), and a log that is not
/// a terminal holds no ANSI colour codes.
#[test]
fn the_logs_name_outcomes_and_hold_no_colour_codes_off_a_terminal() {
    let id = format!("t{}-logs", std::process::id());
    let out = Command::new(env!("CARGO_BIN_EXE_etp"))
        .args([
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            "1.0518",
            "--episodes",
            "3",
            "--seed",
            "2",
            "--predict-episodes",
            "50",
            "--run-id",
            &id,
            "--json",
        ])
        .env("RUST_LOG", "debug")
        .output()
        .expect("etp run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(!err.contains('\u{1b}'), "ANSI codes in a piped log");
    let ends: Vec<&str> = err.lines().filter(|l| l.contains("episode end")).collect();
    // Three episodes, each logged by the agent and by the coordinator.
    assert!(ends.len() >= 6, "{err}");
    for l in &ends {
        let named = ["\"target\"", "\"collision\"", "\"free\""]
            .iter()
            .any(|o| l.contains(&format!("outcome={o}")));
        assert!(named, "an outcome not named: {l}");
    }
}
