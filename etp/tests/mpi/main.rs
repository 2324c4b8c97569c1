//! `etp` on MPI ranks (feature `mpi`; `cargo test --release -p etp
//! --features mpi --test mpi`, run by `.ci/run`): the same bytes for any
//! number of ranks and threads (`bytes.rs`), and a killed rank fails the
//! job without leaving an output behind (`killed.rs`). Without `mpirun` on
//! the PATH every test fails and says what to install: never a silent skip.

mod bytes;
mod killed;
mod study;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const ETP: &str = env!("CARGO_BIN_EXE_etp");

/// Fails, saying how to get it, when Open MPI's launcher is missing.
fn require_mpirun() {
    let found = Command::new("mpirun")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        found,
        "`mpirun` is not on the PATH: the MPI tests need Open MPI \
         (Debian/Ubuntu: apt-get install -y openmpi-bin libopenmpi-dev libclang-dev clang)"
    );
}

/// A fresh scratch folder of this test binary.
fn scratch(name: &str) -> PathBuf {
    let d =
        Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("mpi-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch folder");
    d
}

/// `mpirun` with the options this machine needs (root in CI, 2 cores).
fn mpirun(ranks: u32) -> Command {
    let mut c = Command::new("mpirun");
    c.args([
        "--allow-run-as-root",
        "--oversubscribe",
        "-n",
        &ranks.to_string(),
        // Each rank's threads (Open MPI passes the named variable on).
        "-x",
        "RAYON_NUM_THREADS",
    ]);
    c
}

/// `etp ARGS` on `ranks` ranks (`None`: plain, no launcher) with `threads`
/// rayon threads per rank.
fn etp(ranks: Option<u32>, threads: u32, args: &[&str]) -> Output {
    let mut c = match ranks {
        None => Command::new(ETP),
        Some(n) => {
            let mut c = mpirun(n);
            c.arg(ETP);
            c
        }
    };
    c.args(args)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .expect("etp (or mpirun) starts")
}

/// The output of a command that must exit with one of `codes`.
fn expect(o: Output, codes: &[i32], what: &str) -> Vec<u8> {
    assert!(
        o.status.code().is_some_and(|c| codes.contains(&c)),
        "{what}: {:?} (expected exit {codes:?})\nstdout: {}\nstderr: {}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o.stdout
}
