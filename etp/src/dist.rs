//! The ranks of an MPI job (`mpirun -n N etp …`, `srun etp …`), behind the
//! cargo feature `mpi` (off by default: without it `etp` is one process and
//! every function here says so).
//!
//! * [`start`] initialises MPI when the process was launched by a job
//!   launcher (Open MPI's `OMPI_COMM_WORLD_SIZE`, PMI's `PMI_SIZE`, PMIx's
//!   `PMIX_RANK`), and returns the executor every command hands to the
//!   libraries: `etp_synthesis::exec::Executor` on this process's threads,
//!   its units shared out over MPI's world (a `Ranks` transport).
//! * Rank 0 alone writes files (`etp_pipeline::output` skips the others), prints to
//!   stdout and draws progress; the other ranks compute the same things
//!   and exchange their share of the segments and episodes.
//! * [`finish`] ends the job: a normal end (exit code 0, or a command's own
//!   documented code) finalises MPI; an error aborts the whole job
//!   (`MPI_Abort`), so no rank waits forever for one that gave up.

use etp_synthesis::exec::Executor;

#[cfg(feature = "mpi")]
#[path = "dist/mpi_exec.rs"]
mod mpi_exec;

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

/// Start MPI if this process is one rank of a job (and the feature is on):
/// the session and the executor of every command (this process's threads
/// on rayon's global pool, `RAYON_NUM_THREADS`; alone, or one rank of the
/// job).
pub fn start() -> anyhow::Result<(Session, Executor)> {
    let threads = Executor::LOCAL;
    #[cfg(feature = "mpi")]
    {
        if !launched_by_mpi() {
            return Ok((Session { inner: None }, threads));
        }
        let (session, world) = mpi_exec::start()?;
        if world.rank != 0 {
            mpi_exec::silence_stdout()?;
        }
        Ok((
            Session {
                inner: Some(session),
            },
            threads.on_ranks(std::sync::Arc::new(world)),
        ))
    }
    #[cfg(not(feature = "mpi"))]
    {
        if launched_by_mpi() {
            tracing::debug!(
                "launched by an MPI launcher, but etp was built without `--features mpi`"
            );
        }
        Ok((Session {}, threads))
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
