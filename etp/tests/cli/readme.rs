//! Issue 24 item 8: every command of the README is run by a test. The
//! README's `sh` blocks run here, verbatim, as shell scripts in a scratch
//! folder (`etp` on the PATH, `python3` the pinned venv's), in the README's
//! order; the few commands that cannot run on one machine without extra
//! software are listed in [`ELSEWHERE`] with the test that covers them. A
//! new README command is run (or must be listed), and a listed command that
//! left the README fails the test too. The other Markdown files' commands
//! run in `docs.rs`, which also checks the `etp` subcommands and flags of
//! every file, the README's included.

use super::Scratch;
use super::docs::{commands, fenced_blocks, run_script, script_of, script_path};
use std::path::PathBuf;

/// Commands not run here, and why (each still exercised elsewhere).
const ELSEWHERE: &[(&str, &str)] = &[
    ("cargo test --release --workspace", "the test suite itself"),
    (
        "target/release/etp run --scenario winding-2d --delta 1.4986 --episodes 300 --listen tls/10.0.0.1:7447 --tls out/keys/agent-host --remote s0,s3 --record-default",
        "two hosts: tests/tests/runtime/remote.rs runs it between network namespaces",
    ),
    (
        "target/release/etp sensor-host --connect tls/10.0.0.1:7447 --tls out/keys/b --name b",
        "two hosts: tests/tests/runtime/remote.rs",
    ),
    (
        "apt-get install -y openmpi-bin libopenmpi-dev libclang-dev",
        "root and the network: .ci/run installs them when mpirun is missing",
    ),
    (
        "cargo build --release -p etp --features mpi",
        "the MPI build: .ci/run builds it for clippy and the MPI tests",
    ),
    (
        "mpirun -n 4 -x RAYON_NUM_THREADS=2 target/release/etp synthesize winding-2d --samples 2000 -o out/w",
        "Open MPI and the feature build: etp/tests/mpi/bytes.rs runs synthesize on 1, 2 and 4 ranks",
    ),
    (
        "cargo test --release -p etp --features mpi --test mpi",
        "the MPI tests: .ci/run runs them (with `--workspace --features etp/mpi`)",
    ),
    (
        "pip install ./python",
        "a Python venv and the package's build: python/ci.sh installs it that way into a fresh venv and runs its pytest suite",
    ),
    (
        "prism -importmodel out/winding-2d/prism/model.all -mdp out/winding-2d/prism/model.props",
        "PRISM is not installed here; synthesis/tests check the files it reads",
    ),
];

/// The README's `sh` blocks (not `sh no-run`): per block, its commands
/// (continuation lines joined, comments kept out).
fn sh_blocks(text: &str) -> Vec<Vec<String>> {
    let (blocks, _) = fenced_blocks(text);
    blocks
        .iter()
        .filter(|b| b.info == "sh")
        .map(|b| commands(&b.lines))
        .collect()
}

#[test]
fn every_command_of_the_readme_runs() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("README.md")).expect("README");
    let blocks = sh_blocks(&text);
    let all: Vec<String> = blocks.iter().flatten().cloned().collect();
    for (cmd, why) in ELSEWHERE {
        assert!(
            all.iter().any(|c| c == cmd),
            "listed as run elsewhere ({why}) but no longer in the README: {cmd}"
        );
    }
    let dir = Scratch::new("readme");
    // The README's study SPECs (`etp study studies/quick.toml`), as in a checkout.
    std::fs::create_dir_all(dir.path("studies")).expect("studies folder");
    for e in std::fs::read_dir(root.join("studies"))
        .expect("studies/")
        .flatten()
    {
        std::fs::copy(e.path(), dir.path("studies").join(e.file_name())).expect("copy a SPEC");
    }
    // `etp` the build's, `python3` the venv's.
    let path = script_path(true);
    // The README's placeholders: the recording of the example session, and
    // a run id of this test's own for the publish recipe.
    let leftovers = super::RunLeftovers::new("readme");
    let copy = leftovers.0.clone();
    let mut ran = 0;
    for block in &blocks {
        let mut script = Vec::new();
        for cmd in block {
            if ELSEWHERE.iter().any(|(c, _)| *c == cmd.as_str()) {
                continue;
            }
            // The binaries a build leaves in target/release are the ones on PATH.
            let cmd = cmd.strip_prefix("target/release/").unwrap_or(cmd);
            let first = cmd.split_whitespace().next().unwrap_or("");
            assert!(
                matches!(first, "etp" | "cargo" | "python3" | "kill"),
                "a README command this test does not know how to run: {cmd}"
            );
            let cmd = cmd
                .replace("cargo run --release -p etp -- ", "etp ")
                .replace("recordings/winding-2d-<run-id>.mcap", "out/w/run.mcap")
                .replace("--run-id copy", &format!("--run-id {copy}"));
            assert!(
                !cmd.contains('<'),
                "a placeholder this test cannot fill: {cmd}"
            );
            script.push(cmd);
        }
        if script.is_empty() {
            continue;
        }
        // A recipe's background process (`&`) is waited for.
        run_script(&script_of(&script), &dir.0, &path, "README block");
        ran += script.len();
    }
    // What the recipes promise is there.
    for f in [
        "out/w/strategy.json",
        "out/w/run.mcap",
        "out/w/run-report.png",
        "out/w/first50-replay.png",
        "out/w/tables/measurement.csv",
        "out/w/prism/model.tra",
        "out/winding-2d/mdp.bin",
        "copy.mcap",
        "winding-foxglove.mcap",
        "out/study-quick/study.csv",
    ] {
        assert!(dir.path(f).is_file(), "{f} missing");
    }
    assert!(
        ran + ELSEWHERE.len() == all.len(),
        "{ran} run of {}",
        all.len()
    );
}
