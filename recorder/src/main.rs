//! `etp-recorder`: thin main over [`etp_recorder::main_with`].

fn main() -> std::process::ExitCode {
    etp_recorder::main_with(std::env::args_os())
}
