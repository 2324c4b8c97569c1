//! The ranks of an MPI job (`mpirun -n N etp …`, `srun etp …`), behind the
//! cargo feature `mpi` (off by default: without it `etp` is one process and
//! every function here says so).
//!
//! * [`start`] initialises MPI when the process was launched by a job
//!   launcher (Open MPI's `OMPI_COMM_WORLD_SIZE`, PMI's `PMI_SIZE`, PMIx's
//!   `PMIX_RANK`), and sets the executor every command hands to the
//!   libraries' Monte Carlo through `etp_pipeline::exec::work`.
//! * Rank 0 alone writes files (`etp_pipeline::output` skips the others), prints to
//!   stdout and draws progress; the other ranks compute the same things
//!   and exchange their share of the segments and episodes.
//! * [`finish`] ends the job: a normal end (exit code 0, or a command's own
//!   documented code) finalises MPI; an error aborts the whole job
//!   (`MPI_Abort`), so no rank waits forever for one that gave up.

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

/// Start MPI if this process is one rank of a job (and the feature is on).
pub fn start() -> anyhow::Result<Session> {
    #[cfg(feature = "mpi")]
    {
        if !launched_by_mpi() {
            return Ok(Session { inner: None });
        }
        use etp_synthesis::exec::Executor;
        let (session, exec) = mpi_exec::start()?;
        if exec.rank() != 0 {
            mpi_exec::silence_stdout()?;
        }
        // Set once, at start: `start` is called once, before any command.
        etp_pipeline::exec::install(Box::new(exec)).map_err(anyhow::Error::msg)?;
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
