fn main() -> std::process::ExitCode {
    etp_bridge::main_with(std::env::args_os())
}
