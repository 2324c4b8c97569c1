//! `etp-agent`: thin main over [`etp_agent::main_with`].

fn main() -> std::process::ExitCode {
    etp_agent::main_with(std::env::args_os())
}
