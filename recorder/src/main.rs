//! `etp-recorder`: the process shell with [`etp_recorder::RecorderProcess`].

fn main() -> std::process::ExitCode {
    etp_runtime::shell::main_with::<etp_recorder::RecorderProcess, _, _>(std::env::args_os())
}
