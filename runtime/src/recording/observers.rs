//! The attach barrier between `etp replay publish` and the recorders of its
//! run id.
//!
//! iceoryx2 delivers a sample into a connection that the publisher opens
//! towards each subscriber; the subscriber attaches to that connection only
//! when it next looks (a receive, or `update_connections`). A publisher that
//! ends before then removes the connection, and every sample in it, with
//! itself. A replay at `--rate inf` sends a whole recording in a few
//! milliseconds and ends: a recorder still waking up lost whole channels
//! (its copy had, say, `sensor/4/ack: 0`), while the replay counted every
//! sample as delivered.
//!
//! The barrier, in the run's private folder (`RunId::root_dir`, which only
//! this user can write):
//! 1. a recorder announces itself ([`announce`]: `observer-<pid>`) before
//!    it says `ready`;
//! 2. the replay writes its metadata hand-over (`recording::handover_path`)
//!    once all its publishers exist, then waits ([`await_attached`]) until
//!    every announced recorder still alive has acknowledged that hand-over;
//! 3. a recorder that finds a hand-over it has not acknowledged attaches
//!    every subscriber (after this, a publisher that ends leaves its samples
//!    to the subscriber) and acknowledges it ([`acknowledge`]:
//!    `observer-<pid>.attached`, holding the hand-over's [`Token`]).
//!
//! Only then does the replay send. A subscriber that is not a recorder (a
//! test's, a tool's) is not waited for: it must be attached before the
//! replay starts sending, as iceoryx2 requires of any late reader.

use crate::wire::RunId;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Which hand-over a recorder attached for: the hand-over file's inode (a
/// new replay on the same run id renames a new file in, with a new inode).
pub type Token = u64;

/// How long a replay waits for a live recorder to attach before it gives up
/// (and fails: that recorder's copy would miss messages).
pub const ATTACH_LIMIT: Duration = Duration::from_secs(60);

/// How often the replay looks for acknowledgements.
const POLL: Duration = Duration::from_millis(1);

/// Why the replay could not pass the barrier.
#[derive(Debug, thiserror::Error)]
pub enum AttachError {
    #[error(
        "recorder (pid {pid}) of this run id did not attach within {} s: its copy would miss messages",
        limit.as_secs()
    )]
    TimedOut { pid: u32, limit: Duration },
    #[error("interrupted while waiting for recorder (pid {pid}) to attach")]
    Interrupted { pid: u32 },
}

fn marker(run: &RunId, pid: u32) -> PathBuf {
    run.root_dir().join(format!("observer-{pid}"))
}

fn attached_marker(run: &RunId, pid: u32) -> PathBuf {
    run.root_dir().join(format!("observer-{pid}.attached"))
}

/// Announce this process as a recorder of `run` (its node must exist: it
/// creates the run's folder).
pub fn announce(run: &RunId) -> std::io::Result<()> {
    std::fs::write(marker(run, std::process::id()), b"")
}

/// Remove this process's announcement and acknowledgement (when it stops).
pub fn withdraw(run: &RunId) {
    let pid = std::process::id();
    let _ = std::fs::remove_file(marker(run, pid));
    let _ = std::fs::remove_file(attached_marker(run, pid));
}

/// The token of the replay hand-over present in `run`'s folder, if any.
pub fn handover_token(run: &RunId) -> Option<Token> {
    use std::os::unix::fs::MetadataExt;
    std::fs::symlink_metadata(super::handover_path(run))
        .ok()
        .filter(std::fs::Metadata::is_file)
        .map(|m| m.ino())
}

/// Acknowledge the hand-over `token`: this process's subscribers are all
/// attached. Written beside and renamed, so the replay reads all or nothing.
pub fn acknowledge(run: &RunId, token: Token) -> std::io::Result<()> {
    let path = attached_marker(run, std::process::id());
    let beside = path.with_extension("attached.part");
    std::fs::write(&beside, token.to_string())?;
    std::fs::rename(&beside, &path)
}

/// The pids of the recorders announced in `run`'s folder (regular files
/// named `observer-<pid>` only).
pub fn announced(run: &RunId) -> Vec<u32> {
    let Ok(entries) = std::fs::read_dir(run.root_dir()) else {
        return Vec::new();
    };
    let mut pids: Vec<u32> = entries
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .filter_map(|e| {
            e.file_name()
                .to_str()?
                .strip_prefix("observer-")?
                .parse()
                .ok()
        })
        .collect();
    pids.sort_unstable();
    pids
}

fn acknowledged(run: &RunId, pid: u32) -> Option<Token> {
    let path = attached_marker(run, pid);
    let m = std::fs::symlink_metadata(&path).ok()?;
    if !m.is_file() {
        return None;
    }
    std::fs::read_to_string(path).ok()?.trim().parse().ok()
}

/// A process that can still attach: it exists and is neither a zombie nor
/// dead (`/proc/<pid>/stat`'s state).
fn alive(pid: u32) -> bool {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return false;
    };
    // The state follows the command name, which is in parentheses and may
    // itself hold any character: read after the last `)`.
    let state = stat
        .rsplit_once(')')
        .and_then(|(_, rest)| rest.trim_start().chars().next());
    !matches!(state, None | Some('Z' | 'X' | 'x'))
}

/// Wait until every recorder announced in `run`'s folder and still alive
/// has acknowledged the hand-over `token`; returns the pids that did.
/// `interrupted` is asked between looks (a SIGINT/SIGTERM stops the wait).
pub fn await_attached(
    run: &RunId,
    token: Token,
    limit: Duration,
    mut interrupted: impl FnMut() -> bool,
) -> Result<Vec<u32>, AttachError> {
    let start = Instant::now();
    let mut attached = Vec::new();
    for pid in announced(run) {
        loop {
            if acknowledged(run, pid) == Some(token) {
                attached.push(pid);
                break;
            }
            if !alive(pid) {
                break;
            }
            if interrupted() {
                return Err(AttachError::Interrupted { pid });
            }
            if start.elapsed() >= limit {
                return Err(AttachError::TimedOut { pid, limit });
            }
            std::thread::sleep(POLL);
        }
    }
    Ok(attached)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_is_alive_and_a_missing_one_is_not() {
        assert!(alive(std::process::id()));
        // Above the kernel's pid_max (4 194 304 at most).
        assert!(!alive(4_194_305));
    }
}
