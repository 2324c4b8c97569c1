//! The `etp` command line.
//!
//! * [`cli`] — the clap definition of every subcommand (one place to read the
//!   whole interface).
//! * [`cmd`] — one module per subcommand, none importing another; each exposes
//!   `run(args) -> anyhow::Result<()>`.
//! * [`input`] — resolving a `SCENARIO` argument (built-in name or path)
//!   and its options.
//! * [`mdp_build`] — the MDP step of a synthesis from a typed request
//!   (`synthesize`, `demo`).
//! * [`front`], [`output`] — a synthesis's front and figure written; the
//!   synthesis folder's files read, the overwrite rule.
//! * [`predictions`] — a strategy file's predictions as `strategy` and
//!   `validate` report them (text, JSON, the aggregation check).
//! * [`progress`] — indicatif bars that hide themselves when stderr is not a
//!   terminal (`etp_runtime::progress`).
//! * [`report`] — a simulation summary's JSON and tables.
//! * [`simulation`] — the constant-threshold simulation of `simulate` and `bench`.
//! * [`synthesis_dir`] — a synthesis directory loaded for selection (`strategy`, `compare`).
//! * [`processes`] — the run's processes `etp process NAME` plays.
//! * [`vocab`] — the JSON vocabulary shared by simulate, validate, run and replay.
//!
//! The work is in libraries: the maths in `etp-shared` and `etp-synthesis`,
//! the runtime in `etp-runtime`, the multi-process run in `etp-launcher`,
//! the recording tools in `etp-recording-tools`, the figures in
//! `etp-figures`.
//!
//! Errors are `anyhow` with context; [`run`] prints them to stderr and exits non-zero.

pub mod cli;
pub mod cmd;
pub mod front;
pub mod input;
pub mod mdp_build;
pub mod output;
pub mod predictions;
pub mod processes;
pub mod report;
pub mod simulation;
pub mod synthesis_dir;
pub use etp_recording_tools::vocab;
pub use etp_runtime::progress;

use std::process::ExitCode;

pub use etp_runtime::shell::ExitWith;

/// Run a parsed command line; print any error chain to stderr.
pub fn run(cli: cli::Cli) -> ExitCode {
    // A run's process sets up its own logging and exit code.
    if let cli::Command::Process(a) = cli.command {
        return cmd::process::run(a);
    }
    init_tracing();
    match cmd::dispatch(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => match e.downcast_ref::<ExitWith>() {
            Some(x) => {
                eprintln!("{}", x.message);
                ExitCode::from(x.code)
            }
            None => {
                eprintln!("error: {e:#}");
                ExitCode::FAILURE
            }
        },
    }
}

fn init_tracing() {
    // A second init (tests calling run twice) is harmless.
    etp_runtime::shell::init_logging("etp");
}
