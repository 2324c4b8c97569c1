//! `etp process <name> ARGS…` (hidden): run one of the run's processes —
//! `etp-agent`, `etp-sensor-node`, `etp-coordinator`, `etp-recorder` — from
//! the `etp` executable. `etp run` uses it when those binaries are not
//! installed beside `etp` (e.g. `cargo run -p etp -- demo` on a fresh
//! checkout builds only `etp`). It calls the same library entry point as the
//! standalone binary, in a process of its own: nothing is shared in memory.

use std::ffi::OsString;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// `etp-agent`, `etp-sensor-node`, `etp-coordinator` or `etp-recorder`.
    /// (`--help` in its place prints this; after it, the process's own.)
    #[arg(allow_hyphen_values = true)]
    pub name: String,
    /// The process's own arguments.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub args: Vec<OsString>,
}

pub fn run(a: Args) -> ExitCode {
    // Every argument after NAME is the process's own (its `--help` too), so
    // clap's help flag is off here: `etp process --help` is answered by hand.
    if matches!(a.name.as_str(), "--help" | "-h") {
        let mut cli = crate::cli::command();
        return match cli
            .find_subcommand_mut("process")
            .map(|c| c.print_long_help())
        {
            Some(Ok(())) => ExitCode::SUCCESS,
            _ => ExitCode::FAILURE,
        };
    }
    crate::processes::run(&a.name, a.args)
}
