//! The pinned Python environment of the independent checks (the PyPI `mcap`
//! reader and its protobuf decoder, `jsonschema`, SciPy's HiGHS LP,
//! `eclipse-zenoh`, Storm's `stormpy`): a venv in
//! `target/pyenv`, made by the first test that needs it, under a file lock
//! so parallel tests (and test binaries) do not race. No test skips a
//! Python check: without `python3 -m venv` or PyPI the test fails and says
//! how to make the environment by hand.
//!
//! Shared by the `etp` CLI tests and `etp-tests` (`#[path]`-included, so
//! neither harness depends on the other).

use std::path::{Path, PathBuf};
use std::process::Command;

/// The pinned packages (`pip install` arguments).
pub const REQUIREMENTS: &[&str] = &[
    "mcap==1.6.0",
    "zstandard==0.25.0",
    "lz4==4.4.5",
    "jsonschema==4.26.0",
    "numpy==2.4.6",
    "scipy==1.17.1",
    "eclipse-zenoh==1.10.2",
    // Foxglove's protobuf decoder for MCAP (recording format 5), and the
    // protobuf runtime it resolves to.
    "mcap-protobuf-support==0.6.0",
    "protobuf==7.36.2",
    // Storm's Python API (manylinux wheels, the model checker included)
    // and its one dependency with its own.
    "stormpy==2.0.0",
    "Deprecated==1.3.1",
    "wrapt==2.5.2",
];

/// `target/` of the workspace (`CARGO_TARGET_DIR` if set).
fn target_dir() -> PathBuf {
    if let Some(t) = std::env::var_os("CARGO_TARGET_DIR") {
        return PathBuf::from(t);
    }
    // The test executable is `target/<profile>/deps/<name>-<hash>`.
    let exe = std::env::current_exe().expect("test executable path");
    exe.ancestors()
        .find(|p| p.file_name().is_some_and(|n| n == "target"))
        .map_or_else(|| PathBuf::from("target"), Path::to_path_buf)
}

fn how() -> String {
    format!(
        "make it by hand: python3 -m venv target/pyenv && target/pyenv/bin/pip install {} \
         && touch target/pyenv/{}",
        REQUIREMENTS.join(" "),
        stamp_name()
    )
}

/// The file that says the venv holds exactly [`REQUIREMENTS`].
fn stamp_name() -> String {
    let h = REQUIREMENTS
        .iter()
        .flat_map(|r| r.bytes().chain([0]))
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
        });
    format!("ready-{h:016x}")
}

/// The venv's `python`, the environment made first if needed.
pub fn python() -> PathBuf {
    let target = target_dir();
    let venv = target.join("pyenv");
    let py = venv.join("bin").join("python");
    let stamp = venv.join(stamp_name());
    if stamp.is_file() {
        return py;
    }
    std::fs::create_dir_all(&target).expect("create target/");
    let lock = std::fs::File::create(target.join("pyenv.lock")).expect("create target/pyenv.lock");
    lock.lock().expect("lock target/pyenv.lock");
    if stamp.is_file() {
        return py;
    }
    let run = |cmd: &mut Command, what: &str| {
        let out = cmd
            .output()
            .unwrap_or_else(|e| panic!("{what}: cannot start ({e}); {}", how()));
        assert!(
            out.status.success(),
            "{what} failed: {}\n{}",
            String::from_utf8_lossy(&out.stderr),
            how()
        );
    };
    if !py.is_file() {
        run(
            Command::new("python3").args(["-m", "venv"]).arg(&venv),
            "python3 -m venv target/pyenv",
        );
    }
    run(
        Command::new(&py)
            .args([
                "-m",
                "pip",
                "install",
                "--quiet",
                "--disable-pip-version-check",
            ])
            .args(REQUIREMENTS),
        "pip install of the pinned Python packages",
    );
    std::fs::write(&stamp, REQUIREMENTS.join("\n")).expect("write the pyenv stamp");
    py
}
