//! Nodes of a run and their liveness: the node names of the processes,
//! creating a node, and what the run's node list says about one (alive,
//! dead — its stale resources removed on the way — or missing).

use super::{RunId, WireError, config};
use iceoryx2::config::Config;
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use std::time::Duration;

/// Node names of the run's processes (used for liveness checks).
pub const COORDINATOR_NODE: &str = "etp-coordinator";
pub const AGENT_NODE: &str = "etp-agent";
/// Node name of the recorder (`etp run --record`), started before the others.
pub const RECORDER_NODE: &str = "etp-recorder";
/// Node name of sensor `i`.
pub fn sensor_node_name(i: usize) -> String {
    format!("etp-sensor-{i}")
}

/// Create a node of a run. iceoryx2 signal handling is off: the processes poll
/// their own termination flag (see the binaries), and tokio owns signals in `etp`.
pub fn create_node(run: &RunId, name: &str) -> Result<Node<ipc::Service>, WireError> {
    let cfg = config(run)?;
    let nname = NodeName::new(name).map_err(|e| WireError::Node(format!("name {name}: {e:?}")))?;
    let node = NodeBuilder::new()
        .name(&nname)
        .config(&cfg)
        .create::<ipc::Service>()
        .map_err(|e| WireError::Node(format!("{e:?}")))?;
    // Installs iceoryx2's SIGINT/SIGTERM handler now (it is lazy): until a
    // process's first wait, a SIGTERM would otherwise kill it outright.
    super::termination_requested(&node);
    restrict_global_mgmt(run)?;
    Ok(node)
}

/// Where POSIX shared memory lives (iceoryx2's `ipc` service's files).
const SHM_DIR: &str = "/dev/shm";

/// iceoryx2 0.10 creates the node counter segment `<prefix>…global_mgmt`
/// with `enable_global_access(true)` (mode 666, hard-wired in
/// `GlobalManagementSegment::open_or_create`, not configurable): meant to be
/// shared by every user of a domain. A run's prefix is its own and all its
/// processes are this user's, so it is made 0600 like every other file of
/// the run (issue 41). Only a regular file of this user with the run's
/// prefix is touched, through the file opened (its identity checked against
/// the name's, so a link planted in /dev/shm is never followed).
fn restrict_global_mgmt(run: &RunId) -> Result<(), WireError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let prefix = run.shm_prefix();
    let Ok(entries) = std::fs::read_dir(SHM_DIR) else {
        return Ok(());
    };
    let me = etp_files::folders::euid();
    for e in entries.filter_map(Result::ok) {
        let name = e.file_name();
        let name = name.to_string_lossy();
        if !(name.starts_with(&prefix) && name.ends_with(".global_mgmt")) {
            continue;
        }
        let path = e.path();
        let Ok(m) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        if !m.file_type().is_file() || m.uid() != me || m.mode() & 0o077 == 0 {
            continue;
        }
        let fail = |e: std::io::Error| WireError::Config(format!("{}: {e}", path.display()));
        let f = std::fs::File::open(&path).map_err(fail)?;
        let fm = f.metadata().map_err(fail)?;
        if (fm.dev(), fm.ino()) == (m.dev(), m.ino()) {
            f.set_permissions(std::fs::Permissions::from_mode(0o600))
                .map_err(fail)?;
        }
    }
    Ok(())
}

/// What the node list says about a named node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Liveness {
    Alive,
    /// Its process died (its stale resources were removed just now).
    Dead,
    /// No such node (never started, or already cleaned up).
    Missing,
}

/// Look a node up by name in the run's node list; a dead node's stale
/// resources are removed on the way (so the peers' counts drop and listeners
/// get [`super::ports::DEAD_NOTIFIER_EVENT`]).
pub fn liveness(cfg: &Config, name: &str) -> Liveness {
    node_state(cfg, name, true)
}

/// [`liveness`] without the cleanup: the verdict only, as fast as the node
/// list can give it (the cleanup of a dead node's ports can take tens of
/// milliseconds; call [`remove_dead_nodes`] afterwards).
pub fn peek_liveness(cfg: &Config, name: &str) -> Liveness {
    node_state(cfg, name, false)
}

fn node_state(cfg: &Config, name: &str, cleanup: bool) -> Liveness {
    let named = |d: &Option<iceoryx2::node::NodeDetails>| {
        d.as_ref().is_some_and(|d| d.name().as_str() == name)
    };
    let mut found = Liveness::Missing;
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        match state {
            NodeState::Alive(view) if named(view.details()) => found = Liveness::Alive,
            NodeState::Dead(view) if named(view.details()) => {
                found = Liveness::Dead;
                if cleanup {
                    remove_abandoned_storage(cfg);
                    let _ = view.try_remove_stale_resources();
                }
            }
            _ => return CallbackProgression::Continue,
        }
        CallbackProgression::Stop
    });
    found
}

/// Remove what dead nodes of a run left behind; returns how many were removed.
pub fn remove_dead_nodes(cfg: &Config) -> usize {
    remove_abandoned_storage(cfg);
    let mut removed = 0;
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        if let NodeState::Dead(view) = state
            && view.try_remove_stale_resources().is_ok()
        {
            removed += 1;
        }
        CallbackProgression::Continue
    });
    removed
}

/// Number of nodes of a run that may be alive: every node the list does not
/// prove dead (alive, inaccessible, undefined). If the list itself fails
/// part-way (a node's files changing while it is read), the count is at
/// least one: the callers remove a run's folder, or refuse its id, on zero,
/// and a folder removed under a live process loses what it left there (the
/// replay's metadata for a recorder, issue 40's CI failure).
pub fn alive_nodes(cfg: &Config) -> usize {
    let mut alive = 0;
    let listed = Node::<ipc::Service>::list(cfg, |state| {
        if !matches!(state, NodeState::Dead(_)) {
            alive += 1;
        }
        CallbackProgression::Continue
    });
    if listed.is_err() { alive.max(1) } else { alive }
}

/// How long a run's shared-memory file may stay empty before it counts as
/// abandoned: iceoryx2 sizes a new one right after creating it (within
/// microseconds), so one still empty after this was left by a process killed
/// in between.
pub const ABANDONED_AFTER: Duration = Duration::from_secs(2);

/// Remove the run's shared-memory files (`/dev/shm/<prefix>…`) that are empty
/// and older than [`ABANDONED_AFTER`]; returns how many.
///
/// Why: iceoryx2 0.10 opens a service's dynamic configuration in a loop
/// that retries a zero-size mapping without a deadline, and as root (who
/// may open the creator's write-only file) the removal of a dead node's
/// resources then waits forever on a service its process was killed while
/// creating. That hung every later sweep of the stale run, and with it
/// every later `etp run` on the machine. So every removal of dead nodes'
/// resources ([`remove_dead_nodes`], [`liveness`]) runs this first.
pub fn remove_abandoned_storage(cfg: &Config) -> usize {
    let prefix = String::from_utf8_lossy(cfg.global.prefix.as_bytes()).into_owned();
    let Ok(dir) = std::fs::read_dir("/dev/shm") else {
        return 0;
    };
    let mut removed = 0;
    for e in dir.filter_map(Result::ok) {
        if !e.file_name().to_string_lossy().starts_with(&prefix) {
            continue;
        }
        // The entry itself (never a link's target): an empty regular file.
        let Ok(m) = e.metadata() else { continue };
        let old = m
            .modified()
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age >= ABANDONED_AFTER);
        if m.is_file() && m.len() == 0 && old && std::fs::remove_file(e.path()).is_ok() {
            tracing::warn!(file = %e.path().display(), "removed an empty shared-memory file a killed process left half-made");
            removed += 1;
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_old_empty_files_of_the_run_are_abandoned() {
        let run = RunId::new(&format!("unit-abandoned-{}", std::process::id())).expect("id");
        let cfg = config(&run).expect("config");
        let prefix = run.shm_prefix();
        let path = |name: &str| std::path::PathBuf::from(format!("/dev/shm/{prefix}{name}"));
        let long_ago = std::time::SystemTime::now() - Duration::from_secs(60);
        let make = |name: &str, bytes: &[u8], old: bool| {
            std::fs::write(path(name), bytes).expect("shm file");
            if old {
                let f = std::fs::File::options()
                    .write(true)
                    .open(path(name))
                    .expect("open");
                f.set_modified(long_ago).expect("mtime");
            }
        };
        make("half.dynamic", b"", true);
        make("new.dynamic", b"", false);
        make("full.dynamic", b"x", true);
        // Another run's empty file is not this run's business.
        let other = format!("/dev/shm/etp_unit-other-{}_x.dynamic", std::process::id());
        std::fs::write(&other, b"").expect("other");
        std::fs::File::options()
            .write(true)
            .open(&other)
            .and_then(|f| f.set_modified(long_ago))
            .expect("mtime");
        assert_eq!(remove_abandoned_storage(&cfg), 1);
        assert!(!path("half.dynamic").exists());
        assert!(path("new.dynamic").exists() && path("full.dynamic").exists());
        assert!(std::path::Path::new(&other).exists());
        for f in [path("new.dynamic"), path("full.dynamic"), other.into()] {
            let _ = std::fs::remove_file(f);
        }
    }
}
