//! One module per subcommand.

pub mod aggregation;
pub mod bench;
pub mod certs;
pub mod check;
pub mod demo;
pub mod export_prism;
pub mod fronts;
pub mod predictions;
pub mod process;
pub mod replay;
pub mod run;
pub mod scenario;
pub mod simulate;
pub mod split;
pub mod strategy;
pub mod synthesize;
pub mod validate;

use crate::cli::Command;

/// Run one subcommand.
pub fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Check(a) => check::run(a),
        Command::Scenario(a) => scenario::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Run(a) => run::run(a),
        Command::SensorHost(a) => run::sensor_host::run(a),
        Command::Certs(a) => certs::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Synthesize(a) => synthesize::run(a),
        Command::ExportPrism(a) => export_prism::run(a),
        Command::Fronts(a) => fronts::run(a),
        Command::Strategy(a) => strategy::run(a),
        Command::Validate(a) => validate::run(a),
        Command::Process(_) => anyhow::bail!("`etp process` is dispatched by etp::run"),
    }
}
