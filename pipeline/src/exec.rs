//! The executor every step hands to the libraries' Monte Carlo
//! (`etp_synthesis::exec`): this process's threads ([`Local`]), or the
//! ranks of an MPI job that `etp` installed at start ([`install`]; the
//! MPI code itself lives in the `etp` binary's crate, feature `mpi`).
//!
//! Rank 0 alone writes files ([`crate::output`] skips the others) and draws
//! progress; the other ranks compute the same things and exchange their
//! share of the segments and episodes. The Python package never installs
//! an executor: it is always one process.

use etp_synthesis::exec::{Executor, Local, On};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, Ordering};

static EXECUTOR: OnceLock<Box<dyn Executor + Send>> = OnceLock::new();

/// Set while this rank works alone ([`alone`]).
static ALONE: AtomicBool = AtomicBool::new(false);

/// Install the job's executor, once, before any work (`etp`'s MPI start).
/// A second call is refused: the executor of a running process never
/// changes under its computations.
pub fn install(exec: Box<dyn Executor + Send>) -> Result<(), &'static str> {
    EXECUTOR
        .set(exec)
        .map_err(|_| "the executor of this process is already installed")
}

/// The executor of this process: the job's ranks, or [`Local`] (no job, or
/// inside [`alone`]).
pub fn executor() -> &'static dyn Executor {
    if ALONE.load(Ordering::SeqCst) {
        return &Local;
    }
    job()
}

/// The ranks of the job, whatever [`alone`] says (the study's scheduler).
pub fn job() -> &'static dyn Executor {
    match EXECUTOR.get() {
        Some(e) => e.as_ref(),
        None => &Local,
    }
}

/// Run `f` as if this rank were the whole job: its Monte Carlo on this
/// rank's threads only, its files written by this rank (`etp study` hands
/// whole cases to ranks; the other ranks are busy with theirs). Called from
/// one thread at a time (the study's loop); not re-entrant.
pub fn alone<T>(f: impl FnOnce() -> T) -> T {
    struct Reset;
    impl Drop for Reset {
        fn drop(&mut self) {
            ALONE.store(false, Ordering::SeqCst);
        }
    }
    ALONE.store(true, Ordering::SeqCst);
    let _reset = Reset;
    f()
}

/// Whether this process writes the outputs: rank 0 (or no job at all, or
/// inside [`alone`]).
pub fn is_root() -> bool {
    executor().rank() == 0
}

/// A progress callback on this process's executor, for the libraries'
/// `progress: &dyn Work` arguments.
pub fn work<F: Fn(u64) + Sync>(progress: F) -> On<'static, F> {
    On {
        exec: executor(),
        progress,
    }
}
