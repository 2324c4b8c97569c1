//! Makes `cargo test --workspace` build the `etp-recorder` binary (the
//! runtime tests spawn it through `etp run --record`).

#[test]
fn recorder_binary_runs() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_etp-recorder"))
        .arg("--help")
        .output()
        .expect("running etp-recorder --help");
    assert!(out.status.success());
}
