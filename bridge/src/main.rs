//! `etp-bridge`: the process shell with [`etp_bridge::BridgeProcess`].

fn main() -> std::process::ExitCode {
    etp_runtime::shell::main_with::<etp_bridge::BridgeProcess, _, _>(std::env::args_os())
}
