//! The run's folder (`<private>/run/<run-id>/` in the user's private folder
//! of `etp_files::folders`: the scenario, strategy and recording metadata
//! its processes read), owned by exactly one live `etp run`.
//!
//! The owner holds an exclusive lock on `<folder>/owner.lock` for the whole
//! run. The kernel drops the lock when the owner dies, kill -9 included, so
//! a folder whose lock can be taken belongs to a dead run: it is removed at
//! the next start ([`remove_stale`]), together with that run's iceoryx2
//! files. A run id whose folder is locked is in use ([`RunDir::claim`]
//! refuses it with a clear error instead of a raw iceoryx2 one).
//!
//! Claiming (create folder, create lock file, lock it) is three steps, and a
//! second run's sweep between them would see an unlocked folder and remove
//! it. Both therefore run under one base-wide lock (`<base>/.guard`), held
//! only for those few milliseconds.

use crate::error::{Error, IoContext, Result};
use etp_runtime::cleanup;
use etp_runtime::wire::RunId;
use std::fs::{File, OpenOptions, TryLockError};
use std::path::{Path, PathBuf};

const LOCK: &str = "owner.lock";
const GUARD: &str = ".guard";

/// The base-wide lock that serialises claims and sweeps (see module doc).
fn guard() -> Result<File> {
    let base = base()?;
    let g = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(base.join(GUARD))
        .doing(|| format!("creating {}", base.join(GUARD).display()))?;
    g.lock()
        .doing(|| format!("locking {}", base.join(GUARD).display()))?;
    Ok(g)
}

/// Where every run of this user keeps its folder (created 0700 and checked:
/// a planted link or a foreign folder is refused, never followed).
pub fn base() -> Result<PathBuf> {
    Ok(etp_files::folders::private("run")?)
}

/// A claimed run folder; removed on [`RunDir::remove`] (or by the next start
/// if this process dies).
#[derive(Debug)]
pub struct RunDir {
    pub path: PathBuf,
    _lock: File,
}

fn open_lock(dir: &Path) -> std::io::Result<File> {
    OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(dir.join(LOCK))
}

/// Is the folder's lock held by a live process?
fn locked(dir: &Path) -> bool {
    match OpenOptions::new().write(true).open(dir.join(LOCK)) {
        Ok(f) => matches!(f.try_lock(), Err(TryLockError::WouldBlock)),
        Err(_) => false,
    }
}

impl RunDir {
    /// Create and lock the folder of `run`; refused if another live run
    /// (a locked folder, or live iceoryx2 nodes) uses this id.
    pub fn claim(run: &RunId) -> Result<Self> {
        let _guard = guard()?;
        let path = base()?.join(run.as_str());
        std::fs::create_dir_all(&path).doing(|| format!("creating {}", path.display()))?;
        let lock = open_lock(&path).doing(|| format!("creating {}", path.join(LOCK).display()))?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => return Err(Error::RunIdLocked(run.to_string())),
            Err(TryLockError::Error(e)) => {
                return Err(e).doing(|| format!("locking {}", path.join(LOCK).display()));
            }
        }
        // A recorder or a replay started by hand on this id also owns it.
        let cfg = etp_runtime::wire::config(run)?;
        if etp_runtime::wire::alive_nodes(&cfg) > 0 {
            return Err(Error::RunIdAlive(run.to_string()));
        }
        Ok(Self { path, _lock: lock })
    }

    /// Remove the folder (the lock goes with the file handle).
    pub fn remove(self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// Remove the folders of dead runs and their iceoryx2 files; the ids removed.
/// A folder is stale when its lock is free and no iceoryx2 node of its run
/// lives; one without a lock file only once it is a minute old (it may be a
/// run being set up right now).
pub fn remove_stale() -> Vec<String> {
    let mut removed = Vec::new();
    // Without the guard a sweep could take a folder being claimed right now.
    let Ok(_guard) = guard() else {
        return removed;
    };
    let Some(dir) = base().ok().and_then(|b| std::fs::read_dir(b).ok()) else {
        return removed;
    };
    for e in dir.filter_map(Result::ok) {
        let path = e.path();
        if !path.is_dir() {
            continue;
        }
        let name = e.file_name().to_string_lossy().to_string();
        if locked(&path) || (!path.join(LOCK).exists() && cleanup::young(&path)) {
            continue;
        }
        let iceoryx_clean = RunId::new(&name).map_or(true, |run| cleanup::remove_run(&run));
        if iceoryx_clean && std::fs::remove_dir_all(&path).is_ok() {
            removed.push(name);
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// The sweeps of one test remove the stale folders of another test in
    /// the same process; tests that sweep take turns.
    static SWEEPING: Mutex<()> = Mutex::new(());

    #[test]
    fn a_claimed_id_is_refused_and_a_released_one_is_stale() {
        let _turn = SWEEPING.lock().unwrap_or_else(|e| e.into_inner());
        let run = RunId::new(&format!("unit-rundir-{}", std::process::id())).expect("id");
        let a = RunDir::claim(&run).expect("first claim");
        let err = RunDir::claim(&run).expect_err("second claim of a live id");
        assert!(err.to_string().contains("in use"), "{err}");
        assert!(!remove_stale().contains(&run.to_string()));
        // The owner dies without cleaning up: its lock goes with it.
        let path = a.path.clone();
        drop(a);
        assert!(path.exists());
        assert!(remove_stale().contains(&run.to_string()));
        assert!(!path.exists());
    }

    /// Sweeps running beside claims never take a folder being claimed (a
    /// sweep between "create folder" and "lock it" used to remove it).
    #[test]
    fn a_sweep_never_removes_a_folder_being_claimed() {
        let _turn = SWEEPING.lock().unwrap_or_else(|e| e.into_inner());
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let sweeper = {
            let stop = stop.clone();
            std::thread::spawn(move || {
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    remove_stale();
                }
            })
        };
        let mut held = Vec::new();
        for i in 0..200 {
            let run = RunId::new(&format!("unit-race-{}-{i}", std::process::id())).expect("id");
            let dir = RunDir::claim(&run).expect("claim");
            std::fs::write(dir.path.join("scenario.toml"), "x").expect("the claimed folder exists");
            held.push(dir);
        }
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        sweeper.join().expect("sweeper");
        for d in held {
            assert!(
                d.path.join("scenario.toml").exists(),
                "{}",
                d.path.display()
            );
            d.remove();
        }
    }
}
