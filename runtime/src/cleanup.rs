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

/// Clean every stale run in the user's iceoryx2 folder ([`ROOT_FOLDER`] of
/// `crate::folders`; nothing if it is not private) — runs with no live
/// node; returns the ids removed. Runs with a live node are left alone.
pub fn remove_stale_runs() -> Vec<String> {
    let mut removed = Vec::new();
    let Ok(base) = crate::folders::private(ROOT_FOLDER) else {
        return removed;
    };
    let Ok(dir) = std::fs::read_dir(base) else {
        return removed;
    };
    for e in dir.filter_map(Result::ok) {
        let name = e.file_name().to_string_lossy().to_string();
        if let Ok(run) = RunId::from_folder(&name)
            && remove_run(&run)
        {
            removed.push(name);
        }
    }
    removed
}
