//! Helpers of the end-to-end tests (`tests/tests/*.rs`), which spawn the real
//! binaries.
//!
//! * [`bin_dir`] — where the binaries are: the `target/<profile>/` folder of
//!   the running test executable (`target/<profile>/deps/runtime-…`).
//!   `cargo test --workspace` builds them there: `etp`, `etp-agent`,
//!   `etp-coordinator` and `etp-sensor-node` each have an integration test,
//!   and cargo builds a package's binaries before its integration tests run.
//!   With `cargo test -p etp-tests` alone, build them first
//!   (`cargo build --release --workspace`, same profile).
//! * [`EtpRun`] — an `etp run` (or any workspace binary) child in its own
//!   process group; dropping it kills the whole group (coordinator, agent,
//!   sensors) and reaps it, so no process outlives a test, even a failing one.
//! * [`processes_of_run`] — the live processes whose command line names a run.
//! * [`unique_run_id`] — a run id per test.
//! * [`pyenv`] — the pinned Python venv of the independent checks (`target/pyenv`).

pub mod pyenv;

use etp_runtime::cleanup;
use etp_runtime::wire::RunId;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

/// `target/<profile>/`, where cargo puts the workspace binaries.
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let deps = exe.parent().expect("deps folder");
    let dir = if deps.ends_with("deps") {
        deps.parent().expect("profile folder").to_path_buf()
    } else {
        deps.to_path_buf()
    };
    for b in ["etp", "etp-agent", "etp-coordinator", "etp-sensor-node"] {
        assert!(
            dir.join(b).is_file(),
            "{} missing: run `cargo test --workspace` (or `cargo build --workspace` with the same profile) first",
            dir.join(b).display()
        );
    }
    dir
}

/// A run id unique to this test process and tag.
pub fn unique_run_id(tag: &str) -> String {
    format!("t{}-{tag}", std::process::id())
}

/// Send a signal with the system `kill` (`-9`, `-INT`, …); `target` may be
/// `-PGID` for a process group.
pub fn kill(sig: &str, target: &str) {
    let _ = Command::new("kill")
        .args([sig, "--", target])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
}

/// An `etp run` in its own process group, killed with its children on drop.
pub struct EtpRun {
    pub child: Option<Child>,
    pub run_id: String,
}

impl EtpRun {
    /// Spawn `etp run <args> --run-id <run_id> --json` with stdout captured.
    pub fn spawn(run_id: &str, args: &[&str]) -> Self {
        let mut all = vec!["run"];
        all.extend_from_slice(args);
        all.extend_from_slice(&["--run-id", run_id, "--json"]);
        Self::spawn_binary(run_id, "etp", &all)
    }

    /// Spawn workspace binary `binary` with `args` (stdout and stderr
    /// captured) under the same guard: its process group is killed and
    /// reaped, and the run's iceoryx2 files removed, on drop.
    pub fn spawn_binary(run_id: &str, binary: &str, args: &[&str]) -> Self {
        use std::os::unix::process::CommandExt;
        let child = Command::new(bin_dir().join(binary))
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .process_group(0)
            .spawn()
            .unwrap_or_else(|e| panic!("spawning {binary}: {e}"));
        Self {
            child: Some(child),
            run_id: run_id.to_string(),
        }
    }

    /// Wait for the end; (success, stdout, stderr).
    pub fn finish(mut self) -> (bool, String, String) {
        let child = self.child.take().expect("child");
        let out = child.wait_with_output().expect("waiting for etp run");
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }

    /// Wait for the end; (exit code, stdout, stderr).
    pub fn finish_code(mut self) -> (Option<i32>, String, String) {
        let child = self.child.take().expect("child");
        let out = child.wait_with_output().expect("waiting for the child");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }

    pub fn pid(&self) -> u32 {
        self.child.as_ref().map_or(0, Child::id)
    }
}

impl Drop for EtpRun {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            kill("-KILL", &format!("-{}", c.id()));
            let _ = c.wait();
        }
        // The run's processes live in process groups of their own (so that
        // a terminal's Ctrl-C reaches `etp run` only): kill them by run id.
        for (pid, _) in processes_of_run(&self.run_id) {
            kill("-KILL", &pid.to_string());
        }
        // Whatever was left in /dev/shm and the root folder by killed nodes.
        // (iceoryx2 warns about its global config while cleaning a dead
        // node whose details are gone: noise, as in every etp process.)
        etp_runtime::shell::quiet_iceoryx2();
        if let Ok(run) = RunId::new(&self.run_id) {
            for _ in 0..50 {
                if processes_of_run(&self.run_id).is_empty() {
                    break;
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            cleanup::remove_run(&run);
        }
    }
}

/// Wait (up to 20 s) until `binary` of the run is alive (with `flag_value`
/// among its arguments, if given); its pid.
pub fn wait_for_process(run_id: &str, binary: &str, flag_value: Option<(&str, &str)>) -> u32 {
    let start = std::time::Instant::now();
    loop {
        if let Some(pid) = find_process(run_id, binary, flag_value) {
            return pid;
        }
        assert!(
            start.elapsed() < std::time::Duration::from_secs(20),
            "{binary} {flag_value:?} of run {run_id} never started"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// Live processes (pid, command line) whose arguments contain `--run-id <id>`.
/// Zombies have an empty command line and are not listed.
pub fn processes_of_run(run_id: &str) -> Vec<(u32, Vec<String>)> {
    let mut found = Vec::new();
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return found;
    };
    for e in dir.filter_map(Result::ok) {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(raw) = std::fs::read(e.path().join("cmdline")) else {
            continue;
        };
        let args: Vec<String> = raw
            .split(|b| *b == 0)
            .filter(|a| !a.is_empty())
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        if args
            .windows(2)
            .any(|w| w[0] == "--run-id" && w[1] == run_id)
        {
            found.push((pid, args));
        }
    }
    found
}

/// The pid of a run's process whose command line has `needle` as an argument
/// next to `flag` (e.g. `--sensor s2`), or that runs binary `needle`.
pub fn find_process(run_id: &str, binary: &str, flag_value: Option<(&str, &str)>) -> Option<u32> {
    processes_of_run(run_id)
        .into_iter()
        .find_map(|(pid, args)| {
            let is_bin = args.first().is_some_and(|a| a.ends_with(binary));
            let has =
                flag_value.is_none_or(|(f, v)| args.windows(2).any(|w| w[0] == f && w[1] == v));
            (is_bin && has).then_some(pid)
        })
}

/// Send `sig` to every live process of a run (and to `extra` pids).
pub fn signal_run(run_id: &str, sig: &str, extra: &[u32]) {
    for (pid, _) in processes_of_run(run_id) {
        kill(sig, &pid.to_string());
    }
    for pid in extra {
        kill(sig, &pid.to_string());
    }
}

/// Busy processes that saturate `n` cores until dropped (then killed and
/// reaped): the CPU hog of the soak and fault tests.
pub struct CpuHog(Vec<Child>);

impl CpuHog {
    pub fn start(n: usize) -> Self {
        Self(
            (0..n)
                .map(|_| {
                    Command::new("sh")
                        .args(["-c", "while :; do :; done"])
                        .stdin(Stdio::null())
                        .stdout(Stdio::null())
                        .stderr(Stdio::null())
                        .spawn()
                        .expect("spawning a CPU hog")
                })
                .collect(),
        )
    }
}

impl Drop for CpuHog {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// The run's folder (`<private>/run/<run-id>`, `etp_files::folders`).
pub fn run_folder(run_id: &str) -> PathBuf {
    etp_files::folders::base().join("run").join(run_id)
}

/// No iceoryx2 file of the run is left in /dev/shm, nor its root folder.
pub fn no_leftovers(run_id: &str) -> Result<(), String> {
    let run = RunId::new(run_id).map_err(|e| e.to_string())?;
    let shm = cleanup::shm_files(&run);
    if !shm.is_empty() {
        return Err(format!("left in /dev/shm: {shm:?}"));
    }
    if run.root_dir().exists() {
        return Err(format!("left: {}", run.root_dir().display()));
    }
    if run_folder(run_id).exists() {
        return Err(format!("left: {}", run_folder(run_id).display()));
    }
    Ok(())
}
