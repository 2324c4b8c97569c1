//! The command-line interface (clap derive). Each variant's arguments are a
//! struct owned by its command module.

use clap::{Parser, Subcommand};

/// etpareto: Pareto-optimal event-triggered estimation strategies, computed and run.
#[derive(Debug, Parser)]
#[command(name = "etp", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// The whole pipeline on the built-in default scenario, with one summary table.
    Demo(crate::cmd::demo::Args),
    /// Validate a scenario and print its legs, sensors, obstacles and thresholds.
    Check(crate::cmd::check::Args),
    /// Generate scenarios: `etp scenario random --dim-agent 4 --seed 7`.
    Scenario(crate::cmd::scenario::Args),
    /// Run episodes in-process with a constant threshold.
    Simulate(crate::cmd::simulate::Args),
    /// Pick the strategy for a requested trade-off from a synthesized front.
    Strategy(crate::cmd::strategy::Args),
    /// A batch of cases (scenario × trigger family × request: synthesis,
    /// strategy, validation) from a SPEC file, resumable, shared across MPI
    /// ranks; one JSON and one CSV table.
    Study(crate::cmd::study::Args),
    /// Simulate a strategy in-process and compare with its prediction.
    Validate(crate::cmd::validate::Args),
    /// Build the belief-space MDP by Monte Carlo and write DIR/mdp.bin.
    Synthesize(crate::cmd::synthesize::Args),
    /// Export an MDP for a model checker: `--format prism` (explicit files),
    /// `jani` (QComp interchange, properties included) or `drn` (Storm's).
    Export(crate::cmd::export::Args),
    /// What the radio or the trigger family costs: the fronts of several
    /// syntheses of one scenario (e.g. under different `--loss` or
    /// `--trigger`) on one figure, least energy per P_tar, certified dashed.
    Fronts(crate::cmd::fronts::Args),
    /// Compare trigger families (or radios): for each request, the least
    /// energy each synthesis of one scenario needs, predicted as `etp
    /// strategy` does, and its ratio to the paper's trigger (box).
    Compare(crate::cmd::compare::Args),
    /// The literature's plot of trigger families: estimation error (RMSE,
    /// NEES/n) against communication rate over the scenario's thresholds.
    TriggerCurves(crate::cmd::trigger_curves::Args),
    /// Measure simulator throughput (episode-steps per second).
    Bench(crate::cmd::bench::Args),
    /// Run a strategy as processes (coordinator, agent, one per sensor) over iceoryx2.
    Run(crate::cmd::run::Args),
    /// Serve remote sensors of a run on this host (`etp run --listen … --remote …` on the agent host).
    SensorHost(crate::cmd::sensor_host::Args),
    /// Key material of an authenticated, encrypted run across hosts:
    /// `etp certs init DIR` (then `--tls DIR` on `run` and `sensor-host`).
    Certs(crate::cmd::certs::Args),
    /// Recording tools: `etp replay FILE` summarises a run's MCAP recording (finished
    /// or not); `etp replay info|cat|export|filter|verify|repair|publish|foxglove|plot`.
    Replay(crate::cmd::replay::Args),
    /// Run one process of a run (used by `etp run` when the process binaries
    /// are not installed beside `etp`).
    #[command(hide = true, disable_help_flag = true)]
    Process(crate::cmd::process::Args),
}

#[cfg(test)]
mod tests {
    /// clap's own consistency checks (ids in `requires`/`conflicts_with`,
    /// duplicate flags) on every subcommand; release builds skip them.
    #[test]
    fn the_interface_is_consistent() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
