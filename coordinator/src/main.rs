//! `etp-coordinator`: thin main over [`etp_coordinator::main_with`]; prints the run

fn main() -> std::process::ExitCode {
    etp_coordinator::main_with(std::env::args_os())
}
