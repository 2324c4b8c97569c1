//! The processes of a run inside the `etp` executable: which ones it can
//! play (`etp process <name>`, used by `etp run` when their binaries are
//! not installed beside `etp`) and their one entry point each, the same
//! library call as the standalone binary's `main`.

use etp_launcher::process::NAMES;
use etp_runtime::shell::main_with;
use std::ffi::OsString;
use std::process::ExitCode;

/// Run process `name` with its own arguments `args` (without the program
/// name), in this process; exit 2 for a name that is not one of [`NAMES`].
pub fn run(name: &str, args: Vec<OsString>) -> ExitCode {
    let argv = std::iter::once(OsString::from(name)).chain(args);
    match name {
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
