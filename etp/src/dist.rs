//! The ranks of an MPI job (`mpirun -n N etp …`, `srun etp …`), behind the
//! cargo feature `mpi` (off by default: without it `etp` is one process and
//! every function here says so).
//!
//! * [`start`] initialises MPI when the process was launched by a job
//!   launcher (Open MPI's `OMPI_COMM_WORLD_SIZE`, PMI's `PMI_SIZE`, PMIx's
//!   `PMIX_RANK`), and sets the executor every command hands to the
//!   libraries' Monte Carlo through [`work`] (`etp_synthesis::exec`).
//! * Rank 0 alone writes files (`crate::output` skips the others), prints to
//!   stdout and draws progress; the other ranks compute the same things
//!   and exchange their share of the segments and episodes.
//! * [`finish`] ends the job: a normal end (exit code 0, or a command's own
//!   documented code) finalises MPI; an error aborts the whole job
//!   (`MPI_Abort`), so no rank waits forever for one that gave up.

use etp_synthesis::exec::{Executor, Local, On};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, Ordering};

#[cfg(feature = "mpi")]
#[path = "dist/mpi_exec.rs"]
mod mpi_exec;

static EXECUTOR: OnceLock<Box<dyn Executor + Send>> = OnceLock::new();

/// Set while this rank works alone ([`alone`]).
static ALONE: AtomicBool = AtomicBool::new(false);

/// The executor of this process: the job's ranks, or [`Local`] (no job, or
/// inside [`alone`]).
pub fn executor() -> &'static dyn Executor {
    if ALONE.load(Ordering::SeqCst) {
        return &Local;
    }
    match EXECUTOR.get() {
        Some(e) => e.as_ref(),
        None => &Local,
    }
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

/// Whether the environment says a job launcher started this process.
pub fn launched_by_mpi() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"]
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}

/// What [`start`] holds until [`finish`] (MPI's environment).
pub struct Session {
    #[cfg(feature = "mpi")]
    inner: Option<mpi_exec::Session>,
}

/// Start MPI if this process is one rank of a job (and the feature is on).
pub fn start() -> anyhow::Result<Session> {
    #[cfg(feature = "mpi")]
    {
        if !launched_by_mpi() {
            return Ok(Session { inner: None });
        }
        let (session, exec) = mpi_exec::start()?;
        if exec.rank() != 0 {
            mpi_exec::silence_stdout()?;
        }
        // Set once, at start: `start` is called once, before any command.
        let _ = EXECUTOR.set(Box::new(exec));
        Ok(Session {
            inner: Some(session),
        })
    }
    #[cfg(not(feature = "mpi"))]
    {
        if launched_by_mpi() {
            tracing::debug!(
                "launched by an MPI launcher, but etp was built without `--features mpi`"
            );
        }
        Ok(Session {})
    }
}

/// End the job with `code`: `failed` (an error, not a command's documented
/// exit code) aborts every rank at once; otherwise MPI is finalised.
pub fn finish(session: Session, code: u8, failed: bool) -> std::process::ExitCode {
    #[cfg(feature = "mpi")]
    if let Some(s) = session.inner {
        s.finish(code, failed);
    }
    #[cfg(not(feature = "mpi"))]
    let _ = (session, failed);
    std::process::ExitCode::from(code)
}
