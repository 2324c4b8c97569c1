//! `etp-sensor-node`: thin main over [`etp_sensor_node::main_with`].

fn main() -> std::process::ExitCode {
    etp_sensor_node::main_with(std::env::args_os())
}
