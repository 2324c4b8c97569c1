//! Issue 42 item 4: a rank killed (`kill -9`) in the middle of a synthesis
//! fails the whole job with a message naming it, and nothing is left at
//! the output path (rank 0 alone writes, beside then renamed, at the end).

use super::{ETP, mpirun, require_mpirun, scratch};
use std::process::Stdio;
use std::time::{Duration, Instant};

/// The pid of rank `rank` among the children of `parent` (Open MPI sets
/// OMPI_COMM_WORLD_RANK in each rank's environment).
fn rank_pid(parent: u32, rank: u32) -> Option<u32> {
    let want = format!("OMPI_COMM_WORLD_RANK={rank}");
    for e in std::fs::read_dir("/proc").ok()?.flatten() {
        let Some(pid) = e.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else {
            continue;
        };
        let stat = std::fs::read_to_string(e.path().join("stat")).unwrap_or_default();
        // pid (comm) state ppid …
        let ppid = stat
            .rsplit(')')
            .next()
            .and_then(|rest| rest.split_whitespace().nth(1))
            .and_then(|p| p.parse::<u32>().ok());
        if ppid != Some(parent) {
            continue;
        }
        let env = std::fs::read(e.path().join("environ")).unwrap_or_default();
        if env.split(|&b| b == 0).any(|v| v == want.as_bytes()) {
            return Some(pid);
        }
    }
    None
}

/// Kill (-9) rank 1 of the job `mpirun` runs as `child` (waiting up to
/// 60 s for it to appear): the job must fail and say which rank died and
/// how. Its stderr.
pub(crate) fn kill_rank_1(child: std::process::Child) -> String {
    let started = Instant::now();
    let victim = loop {
        if let Some(pid) = rank_pid(child.id(), 1) {
            break pid;
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "rank 1 never appeared"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let killed = std::process::Command::new("kill")
        .args(["-9", &victim.to_string()])
        .status()
        .expect("kill runs");
    assert!(killed.success());
    let out = child.wait_with_output().expect("mpirun ends");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "the job succeeded without rank 1: {stderr}"
    );
    assert!(
        stderr.contains("rank 1") && (stderr.contains("signal 9") || stderr.contains("Killed")),
        "no word of the killed rank: {stderr}"
    );
    stderr
}

#[test]
fn a_killed_rank_fails_the_job_and_leaves_no_output() {
    require_mpirun();
    let root = scratch("killed");
    let dir = root.join("out");
    let child = mpirun(2)
        .arg(ETP)
        .args(["synthesize", "winding-2d", "--samples", "20000", "-o"])
        .arg(&dir)
        .env("RAYON_NUM_THREADS", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mpirun starts");
    std::thread::sleep(Duration::from_secs(3));
    kill_rank_1(child);
    // Nothing at the output path: no output, no temporary sibling.
    let left: Vec<String> = std::fs::read_dir(&dir)
        .map(|d| {
            d.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    assert!(
        left.is_empty(),
        "a failed job left {left:?} in {}",
        dir.display()
    );
    let _ = std::fs::remove_dir_all(&root);
}
