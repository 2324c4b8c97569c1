//! `etp-coordinator`: the process shell with
//! [`etp_coordinator::CoordinatorProcess`]; prints the run report.

fn main() -> std::process::ExitCode {
    etp_runtime::shell::main_with::<etp_coordinator::CoordinatorProcess, _, _>(std::env::args_os())
}
