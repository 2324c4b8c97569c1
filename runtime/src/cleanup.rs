//! Removing iceoryx2 leftovers: a finished run's files, and stale runs whose
//! processes all died (kill -9, crash) before they could clean up.

use crate::wire::{ROOT_FOLDER, RunId, alive_nodes, config, remove_dead_nodes};

/// Files in /dev/shm that belong to a run (its prefix).
pub fn shm_files(run: &RunId) -> Vec<std::path::PathBuf> {
    let prefix = run.shm_prefix();
    std::fs::read_dir("/dev/shm")
        .map(|d| {
            d.filter_map(Result::ok)
                .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
                .map(|e| e.path())
                .collect()
        })
        .unwrap_or_default()
}

/// Remove what a run left once none of its nodes is alive: dead nodes' stale
/// resources, the per-prefix `global_mgmt` file, and the run's root folder.
/// Returns `false` (and removes nothing but dead nodes) while a node lives.
pub fn remove_run(run: &RunId) -> bool {
    let Ok(cfg) = config(run) else { return false };
    remove_dead_nodes(&cfg);
    if alive_nodes(&cfg) > 0 {
        return false;
    }
    for f in shm_files(run) {
        let _ = std::fs::remove_file(f);
    }
    let _ = std::fs::remove_dir_all(run.root_dir());
    true
}

/// How long a run's folder is left alone after its last change, live node
/// or not: a run that is starting has its folder before its first node is
/// alive (iceoryx2 creates the folder, then the node's token), and another
/// run starting meanwhile must not sweep it away (its sensor then failed
/// with `iceoryx2 node: InternalError`).
pub const YOUNG: std::time::Duration = std::time::Duration::from_secs(60);

/// Whether `path` changed less than [`YOUNG`] ago (or its age is unknown):
/// a folder a run may still be setting up, left alone by every sweep.
pub fn young(path: &std::path::Path) -> bool {
    std::fs::symlink_metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_none_or(|age| age < YOUNG)
}

/// Clean every stale run in the user's iceoryx2 folder ([`ROOT_FOLDER`] of
/// `etp_files::folders`; nothing if it is not private) — runs with no live
/// node whose folder is older than [`YOUNG`]; returns the ids removed. Runs
/// with a live node are left alone.
pub fn remove_stale_runs() -> Vec<String> {
    let mut removed = Vec::new();
    let Ok(base) = etp_files::folders::private(ROOT_FOLDER) else {
        return removed;
    };
    let Ok(dir) = std::fs::read_dir(base) else {
        return removed;
    };
    for e in dir.filter_map(Result::ok) {
        let name = e.file_name().to_string_lossy().to_string();
        if young(&e.path()) {
            continue;
        }
        if let Ok(run) = RunId::from_folder(&name)
            && remove_run(&run)
        {
            removed.push(name);
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run's folder without a live node yet (a run that is starting) is
    /// left to it; the same folder, once older than [`YOUNG`], is swept.
    #[test]
    fn a_starting_run_is_not_swept_and_an_old_dead_one_is() {
        let run = RunId::generate();
        let Ok(base) = etp_files::folders::private(ROOT_FOLDER) else {
            panic!("the user's iceoryx2 folder is not private");
        };
        let dir = run.root_dir();
        assert!(dir.starts_with(&base));
        std::fs::create_dir_all(dir.join("nodes")).expect("a starting run's folder");
        let folder = dir.file_name().map(|n| n.to_string_lossy().to_string());
        let swept = |removed: Vec<String>| folder.as_ref().is_some_and(|f| removed.contains(f));
        assert!(!swept(remove_stale_runs()), "a starting run was swept");
        assert!(dir.is_dir());
        std::fs::File::open(&dir)
            .and_then(|d| {
                d.set_modified(
                    std::time::SystemTime::now() - YOUNG - std::time::Duration::from_secs(1),
                )
            })
            .expect("mtime");
        assert!(swept(remove_stale_runs()), "an old dead run was left");
        assert!(!dir.exists());
    }
}
