//! The run's child processes: where their binaries are, how one is started
//! (its own process group) and signalled, and how its end is described.
//! Used by the supervisor and by the recorder's owner alike.

use crate::error::{Context, Error, Result};
use std::path::PathBuf;
use std::process::Stdio;
use tokio::process::{Child, Command};

/// The processes `etp` can run as `etp process <name>`.
pub const NAMES: [&str; 4] = [
    "etp-agent",
    "etp-sensor-node",
    "etp-coordinator",
    "etp-recorder",
];

/// Can `etp process` run `name`?
pub fn known(name: &str) -> bool {
    NAMES.contains(&name)
}

/// The environment variable naming the folder of the run's process
/// binaries, for a front end that is not `etp` ([`sibling_binary`]).
pub const PROCESS_DIR_VAR: &str = "ETP_PROCESS_DIR";

/// How one process ended.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ProcessExit {
    pub name: String,
    pub pid: u32,
    /// "exit 0", "exit 1", "signal 9", or "killed by supervisor".
    pub status: String,
}

/// How to start one of the run's processes.
#[derive(Debug, Clone)]
pub struct Launcher {
    pub program: PathBuf,
    /// Arguments before the process's own (`process <name>` when `etp`
    /// runs the process itself).
    pub prefix: Vec<String>,
}

impl Launcher {
    /// A command for this process with `args`.
    pub fn command(&self, args: &[String]) -> Command {
        let mut c = Command::new(&self.program);
        c.args(&self.prefix).args(args);
        c
    }

    pub fn display(&self) -> String {
        self.program.display().to_string()
    }
}

/// The process binary `name` (`etp-agent`, …): the sibling of the running
/// executable (`target/<profile>/etp-agent` next to `target/<profile>/etp`,
/// or the same folder after `cargo install`), else `etp` itself as
/// `etp process <name>` — the same library entry point in its own process,
/// so `cargo run -p etp -- demo` works before the workspace is built.
///
/// A front end that is not `etp` (the Python package `etpareto`, whose
/// executable is Python's) names the folder in [`PROCESS_DIR_VAR`]: `name`
/// there, else that folder's `etp` as `etp process <name>`.
pub fn sibling_binary(name: &str) -> Result<Launcher> {
    if let Some(dir) = std::env::var_os(PROCESS_DIR_VAR) {
        let dir = PathBuf::from(dir);
        let (own, etp) = (dir.join(name), dir.join("etp"));
        if own.is_file() {
            return Ok(Launcher {
                program: own,
                prefix: Vec::new(),
            });
        }
        if known(name) && etp.is_file() {
            return Ok(Launcher {
                program: etp,
                prefix: vec!["process".into(), name.into()],
            });
        }
        return Err(Error::binary(format!(
            "neither `{name}` nor `etp` in {PROCESS_DIR_VAR}={} (build the workspace: \
             cargo build --release --workspace, and name its target/release)",
            dir.display()
        )));
    }
    let exe = std::env::current_exe().map_err(|e| Error::Binary {
        what: "locating the etp executable".into(),
        source: Some(e),
    })?;
    let dir = exe
        .parent()
        .ok_or_else(|| Error::binary("etp executable has no folder"))?;
    // Test harnesses run from target/<profile>/deps: look one level up too.
    for d in [Some(dir), dir.parent()].into_iter().flatten() {
        let p = d.join(name);
        if p.is_file() {
            return Ok(Launcher {
                program: p,
                prefix: Vec::new(),
            });
        }
    }
    if known(name) && exe.file_stem().is_some_and(|s| s == "etp") {
        return Ok(Launcher {
            program: exe,
            prefix: vec!["process".into(), name.into()],
        });
    }
    Err(Error::binary(format!(
        "`{name}` not found next to {} (build the workspace: cargo build --release --workspace)",
        exe.display()
    )))
}

pub fn status_text(s: &std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (s.code(), s.signal()) {
        (Some(c), _) => format!("exit {c}"),
        (None, Some(sig)) => format!("signal {sig}"),
        _ => "unknown".into(),
    }
}

/// Spawn one of the run's processes in a process group of its own: a
/// terminal's Ctrl-C (or Ctrl-Z) reaches `etp run` only, which stops the run
/// gracefully through the coordinator instead of every process dying at once.
pub fn spawn(bin: &Launcher, args: &[String], stdout: bool) -> Result<Child> {
    spawn_env(bin, args, stdout, &[])
}

/// [`spawn`] with extra environment variables.
pub fn spawn_env(
    bin: &Launcher,
    args: &[String],
    stdout: bool,
    env: &[(&str, &str)],
) -> Result<Child> {
    let mut c = bin.command(args);
    c.envs(env.iter().copied());
    c.process_group(0);
    c.stdin(Stdio::null())
        .stdout(if stdout {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stderr(Stdio::inherit())
        .kill_on_drop(true);
    c.spawn()
        .in_process(|| format!("spawning {}", bin.display()))
}

/// Send a signal by pid with the system `kill` (keeps this crate free of unsafe).
pub fn signal(pid: u32, sig: &str) {
    let _ = std::process::Command::new("kill")
        .args([sig, &pid.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
}
