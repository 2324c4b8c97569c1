//! Removing iceoryx2 leftovers: a finished run's files, and stale runs whose
//! processes all died (kill -9, crash) before they could clean up.

use super::private;
use super::services::{RunId, alive_nodes, config, remove_dead_nodes, root_base};

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
    // remove_dir_all never follows a symlink; the root is removed only if it
    // is a folder of this user's (it lives in the private folder anyway).
    let root = run.root_dir();
    if private::owned_folder(&root) {
        let _ = std::fs::remove_dir_all(root);
    }
    true
}

/// Clean every stale run under [`root_base`] (runs with no live node);
/// returns the ids removed. Runs with a live node are left alone, and so is
/// anything that is not a folder owned by this user (never followed).
pub fn remove_stale_runs() -> Vec<String> {
    let mut removed = Vec::new();
    if private::sub("iox2").is_err() {
        return removed;
    }
    let Ok(dir) = std::fs::read_dir(root_base()) else {
        return removed;
    };
    for e in dir.filter_map(Result::ok) {
        let name = e.file_name().to_string_lossy().to_string();
        if !private::owned_folder(&e.path()) {
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
