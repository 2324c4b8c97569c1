//! `etp process <name> ARGS…` (hidden): run one of the run's processes —
//! `etp-agent`, `etp-sensor-node`, `etp-coordinator`, `etp-recorder` — from
//! the `etp` executable. `etp run` uses it when those binaries are not
//! installed beside `etp` (e.g. `cargo run -p etp -- demo` on a fresh
//! checkout builds only `etp`). It calls the same library entry point as the
//! standalone binary, in a process of its own: nothing is shared in memory.

use etp_runtime::shell::main_with;
use std::ffi::OsString;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// `etp-agent`, `etp-sensor-node`, `etp-coordinator` or `etp-recorder`.
    pub name: String,
    /// The process's own arguments.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub args: Vec<OsString>,
}

const NAMES: [&str; 4] = [
    "etp-agent",
    "etp-sensor-node",
    "etp-coordinator",
    "etp-recorder",
];

/// Can `etp process` run `name`?
pub fn known(name: &str) -> bool {
    NAMES.contains(&name)
}

pub fn run(a: Args) -> ExitCode {
    let argv = std::iter::once(OsString::from(&a.name)).chain(a.args);
    match a.name.as_str() {
        "etp-agent" => main_with::<etp_agent::AgentProcess, _, _>(argv),
        "etp-sensor-node" => main_with::<etp_sensor_node::SensorProcess, _, _>(argv),
        "etp-coordinator" => main_with::<etp_coordinator::CoordinatorProcess, _, _>(argv),
        "etp-recorder" => main_with::<etp_recorder::RecorderProcess, _, _>(argv),
        other => {
            eprintln!(
                "error: `{other}` is not a process of a run ({})",
                NAMES.join(", ")
            );
            ExitCode::from(2)
        }
    }
}
