//! The `etp` command line.
//!
//! * [`cli`] — the clap definition of every subcommand (one place to read the
//!   whole interface).
//! * [`cmd`] — one module per subcommand, none importing another; each exposes
//!   `run(args) -> anyhow::Result<()>` (with the executor, for a command
//!   that computes).
//! * [`input`] — resolving a `SCENARIO` argument (built-in name or path)
//!   and its options; [`scenario_flags`] — those options' flags (radio,
//!   trigger family).
//! * [`prediction_args`] — how a strategy is predicted and how many rounds
//!   the request loop runs: the options of every command that predicts.
//! * [`dist`] — the ranks of an MPI job (feature `mpi`): MPI started and
//!   the executor every command is handed built on its world; rank 0 writes.
//! * [`report`] — a simulation summary's tables.
//! * [`processes`] — the run's processes `etp process NAME` plays.
//! * [`values`] — the ranges of option values, checked as clap parses.
//! * [`run_args`] — `etp run`'s flags and their typed request for the
//!   launcher (`--tls`/`--insecure` too, shared with `etp sensor-host`).
//!
//! The work is in libraries: the maths in `etp-shared` and `etp-synthesis`,
//! the pipeline's steps in `etp-pipeline` (MDP, front, selection,
//! predictions, output files, progress, studies; shared with the Python package),
//! the runtime in `etp-runtime`, the multi-process run in `etp-launcher`,
//! the recording tools and the JSON vocabulary of simulate, validate, run
//! and replay in `etp-recording-tools`, the figures in `etp-figures`. A
//! command imports each item from the crate that defines it: `etp`
//! re-exports none (`tests/tests/runtime/layering.rs` checks it).
//!
//! Errors are `anyhow` with context; [`run`] prints them to stderr and exits non-zero.

pub mod cli;
pub mod cmd;
pub mod dist;
pub mod input;
pub mod prediction_args;
pub mod processes;
pub mod report;
pub mod run_args;
pub mod scenario_flags;
pub mod values;

use std::process::ExitCode;

use etp_runtime::shell::ExitWith;
use etp_synthesis::exec::Executor;

/// Run a parsed command line; print any error chain to stderr.
pub fn run(cli: cli::Cli) -> ExitCode {
    // A run's process sets up its own logging and exit code.
    if let cli::Command::Process(a) = cli.command {
        return cmd::process::run(a);
    }
    init_tracing();
    let (session, exec) = match dist::start() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: starting MPI: {e:#}");
            return ExitCode::FAILURE;
        }
    };
    let (code, failed) = run_command(cli.command, &exec);
    dist::finish(session, code, failed)
}

/// Dispatch one subcommand: its exit code, and whether it failed (an
/// error, as opposed to a command's own documented exit code).
fn run_command(command: cli::Command, exec: &Executor) -> (u8, bool) {
    let ranks = exec.ranks();
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
        cmd::dispatch(command, exec)
    };
    match result {
        Ok(()) => (0, false),
        Err(e) => match exit_with(&e) {
            Some(x) => {
                // Every rank reached the same outcome: rank 0 says it.
                if exec.is_root() {
                    eprintln!("{}", x.message);
                }
                (x.code, false)
            }
            None => {
                if ranks > 1 {
                    eprintln!("error (rank {} of {ranks}): {e:#}", exec.rank());
                } else {
                    eprintln!("error: {e:#}");
                }
                (1, true)
            }
        },
    }
}

/// The outcome with its own exit code that `e` is, if it is one: an
/// [`ExitWith`] of a command, or one the run returned inside its own error
/// ([`etp_launcher::Error::Exit`]: an interrupt, a run that is not clean).
fn exit_with(e: &anyhow::Error) -> Option<&ExitWith> {
    e.downcast_ref::<ExitWith>().or_else(|| {
        e.downcast_ref::<etp_launcher::Error>()
            .and_then(etp_launcher::Error::exit_with)
    })
}

fn init_tracing() {
    // A second init (tests calling run twice) is harmless.
    etp_runtime::shell::init_logging("etp");
}
