//! `etp-agent`: the process shell with [`etp_agent::AgentProcess`].

fn main() -> std::process::ExitCode {
    etp_runtime::shell::main_with::<etp_agent::AgentProcess, _, _>(std::env::args_os())
}
