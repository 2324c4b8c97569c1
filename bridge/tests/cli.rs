//! The `etp-bridge` binary (also makes `cargo test --workspace` build it
//! for the end-to-end tests of runs across hosts).

use std::process::Command;

fn bridge() -> Command {
    Command::new(env!("CARGO_BIN_EXE_etp-bridge"))
}

#[test]
fn a_sensor_host_with_no_agent_host_fails_naming_the_endpoint() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("bridge-cli-{}", std::process::id()));
    let out = bridge()
        .args([
            "sensor-host",
            "--connect",
            "tcp/127.0.0.1:9",
            "--insecure",
            "--dir",
            &dir.display().to_string(),
            "--join-timeout",
            "1",
        ])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no agent host answered at tcp/127.0.0.1:9"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_agent_host_refuses_a_missing_session_file() {
    let out = bridge()
        .args([
            "agent-host",
            "--session",
            "/nonexistent/session.json",
            "--listen",
            "tcp/127.0.0.1:0",
            "--insecure",
        ])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/session.json"));
}

#[test]
fn a_link_without_tls_or_insecure_is_refused_before_it_opens() {
    for (args, needle) in [
        (
            vec![
                "sensor-host",
                "--connect",
                "tcp/127.0.0.1:9",
                "--dir",
                "/nonexistent/d",
            ],
            "unauthenticated and unencrypted",
        ),
        (
            vec![
                "sensor-host",
                "--connect",
                "tls/127.0.0.1:9",
                "--dir",
                "/nonexistent/d",
                "--tls",
                "/nonexistent/keys",
            ],
            "/nonexistent/keys/ca.pem",
        ),
        (
            vec![
                "sensor-host",
                "--connect",
                "tls/127.0.0.1:9",
                "--dir",
                "/nonexistent/d",
                "--insecure",
            ],
            "--insecure carries plain `tcp/ADDR:PORT` only",
        ),
    ] {
        let out = bridge().args(&args).output().expect("runs");
        assert_eq!(out.status.code(), Some(1), "{args:?}: {out:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}
