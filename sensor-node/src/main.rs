//! `etp-sensor-node`: the process shell with [`etp_sensor_node::SensorProcess`].

fn main() -> std::process::ExitCode {
    etp_runtime::shell::main_with::<etp_sensor_node::SensorProcess, _, _>(std::env::args_os())
}
