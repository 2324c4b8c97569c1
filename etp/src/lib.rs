//! The `etp` command line.
//!
//! * [`cli`] — the clap definition of every subcommand (one place to read the
//!   whole interface).
//! * [`cmd`] — one module per subcommand, none importing another; each exposes
//!   `run(args) -> anyhow::Result<()>`.
//! * [`input`] — resolving a `SCENARIO` argument (built-in name or path)
//!   and its options.
//! * [`mdp_build`], [`front`], [`output`], [`predictions`], [`selection`],
//!   [`synthesis_dir`], [`progress`] — re-exported from `etp-pipeline`, the
//!   pipeline's steps as a library (shared with the Python package).
//! * [`dist`] — the ranks of an MPI job (feature `mpi`): MPI started and
//!   its executor installed into `etp_pipeline::exec`; rank 0 writes.
//! * [`report`] — a simulation summary's JSON and tables.
//! * [`simulation`] — the constant-threshold simulation of `simulate` and `bench`.
//! * [`study`] — `etp study`: a SPEC's cases, resumable, scheduled across
//!   MPI ranks; its tables.
//! * [`processes`] — the run's processes `etp process NAME` plays.
//! * [`vocab`] — the JSON vocabulary shared by simulate, validate, run and replay.
//!
//! The work is in libraries: the maths in `etp-shared` and `etp-synthesis`,
//! the pipeline's steps in `etp-pipeline`, the runtime in `etp-runtime`,
//! the multi-process run in `etp-launcher`,
//! the recording tools in `etp-recording-tools`, the figures in
//! `etp-figures`.
//!
//! Errors are `anyhow` with context; [`run`] prints them to stderr and exits non-zero.

pub mod cli;
pub mod cmd;
pub mod dist;
pub mod input;
pub mod processes;
pub mod report;
pub mod simulation;
pub mod study;
pub use etp_pipeline::{front, mdp_build, output, predictions, progress, selection, synthesis_dir};
pub use etp_recording_tools::vocab;

use std::process::ExitCode;

pub use etp_runtime::shell::ExitWith;

/// Run a parsed command line; print any error chain to stderr.
pub fn run(cli: cli::Cli) -> ExitCode {
    // A run's process sets up its own logging and exit code.
    if let cli::Command::Process(a) = cli.command {
        return cmd::process::run(a);
    }
    init_tracing();
    let session = match dist::start() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: starting MPI: {e:#}");
            return ExitCode::FAILURE;
        }
    };
    let (code, failed) = run_command(cli.command);
    dist::finish(session, code, failed)
}

/// Dispatch one subcommand: its exit code, and whether it failed (an
/// error, as opposed to a command's own documented exit code).
fn run_command(command: cli::Command) -> (u8, bool) {
    let ranks = dist::job().ranks();
    let shared = matches!(
        command,
        cli::Command::Synthesize(_)
            | cli::Command::Strategy(_)
            | cli::Command::Validate(_)
            | cli::Command::Simulate(_)
            | cli::Command::Study(_)
    );
    let result = if ranks > 1 && !shared {
        Err(anyhow::anyhow!(
            "this subcommand does not run on {ranks} MPI ranks: run it without mpirun/srun \
             (synthesize, strategy, validate, simulate and study share their work across ranks)"
        ))
    } else {
        cmd::dispatch(command)
    };
    match result {
        Ok(()) => (0, false),
        Err(e) => match e.downcast_ref::<ExitWith>() {
            Some(x) => {
                // Every rank reached the same outcome: rank 0 says it.
                if dist::is_root() {
                    eprintln!("{}", x.message);
                }
                (x.code, false)
            }
            None => {
                if ranks > 1 {
                    eprintln!("error (rank {} of {ranks}): {e:#}", dist::job().rank());
                } else {
                    eprintln!("error: {e:#}");
                }
                (1, true)
            }
        },
    }
}

fn init_tracing() {
    // A second init (tests calling run twice) is harmless.
    etp_runtime::shell::init_logging("etp");
}
