//! One module per subcommand (`replay`'s, `run`'s and `strategy`'s
//! subcommands, and `synthesize`'s aggregation check and splitting, in
//! folders of their own). Each is a leaf: no command module imports another
//! (the test `etp_command_modules_import_no_other_command`); what two share
//! lives in a library crate or beside `cmd` (`predictions`, `report`,
//! `input`, `output`, `processes`, `simulation`).

pub mod bench;
pub mod certs;
pub mod check;
pub mod compare;
pub mod demo;
pub mod export;
pub mod fronts;
pub mod process;
pub mod replay;
pub mod run;
pub mod scenario;
pub mod sensor_host;
pub mod simulate;
pub mod strategy;
pub mod study;
pub mod synthesize;
pub mod trigger_curves;
pub mod validate;

use crate::cli::Command;
use etp_synthesis::exec::Executor;

/// Run one subcommand.
pub fn dispatch(command: Command, exec: &Executor) -> anyhow::Result<()> {
    match command {
        Command::Check(a) => check::run(a),
        Command::Scenario(a) => scenario::run(a),
        Command::Demo(a) => demo::run(a, exec),
        Command::Simulate(a) => simulate::run(a, exec),
        Command::Bench(a) => bench::run(a),
        Command::Run(a) => run::run(*a),
        Command::SensorHost(a) => sensor_host::run(a),
        Command::Certs(a) => certs::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Synthesize(a) => synthesize::run(a, exec),
        Command::Export(a) => export::run(a),
        Command::Fronts(a) => fronts::run(a),
        Command::Compare(a) => compare::run(a, exec),
        Command::TriggerCurves(a) => trigger_curves::run(a, exec),
        Command::Strategy(a) => strategy::run(a, exec),
        Command::Study(a) => study::run(a, exec),
        Command::Validate(a) => validate::run(a, exec),
        Command::Process(_) => anyhow::bail!("`etp process` is dispatched by etp::run"),
    }
}
