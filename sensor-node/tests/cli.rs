//! The `etp-sensor-node` binary starts and parses its command line. (This integration
//! test also makes `cargo test --workspace` build the binary, which the
//! end-to-end tests in `etp-tests` spawn.)

use std::process::Command;

#[test]
fn help_works_and_bad_arguments_fail() {
    let bin = env!("CARGO_BIN_EXE_etp-sensor-node");
    let out = Command::new(bin).arg("--help").output().expect("spawn");
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("--run-id"));
    let out = Command::new(bin)
        .arg("--no-such-flag")
        .output()
        .expect("spawn");
    assert!(!out.status.success());
}

#[test]
fn an_invalid_run_id_is_refused() {
    let bin = env!("CARGO_BIN_EXE_etp-sensor-node");
    let out = Command::new(bin)
        .args([
            "--run-id",
            "Bad_Id",
            "--scenario",
            "winding-2d",
            "--sensor",
            "s0",
        ])
        .output()
        .expect("spawn");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("run id"));
}
