//! The command-line interface (clap derive). Each variant's arguments are a
//! struct owned by its command module.

use clap::{CommandFactory, Parser, Subcommand};

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
    ///
    /// Under the scenario's trigger family or `--trigger`, and its radio or
    /// the radio options: P_tar, P_coll, P_free, energy, steps, the measured
    /// trigger rate against the family's expected rate and NEES/n, each with
    /// a 95 % half-width (`<key>_ci95`); the same seed gives the same numbers
    /// on any thread count.
    ///
    /// More: docs/cli.md.
    Simulate(crate::cmd::simulate::Args),
    /// Pick the strategy for a requested trade-off from a synthesized front.
    ///
    /// The request loop: select on the MDP (the whole-MDP occupation LP),
    /// predict the strategy on on-policy rebuilds of the abstraction (its own
    /// beliefs in the pools), and tighten the request by the measured gap
    /// while that prediction misses it. The sealed `strategy.json` stands by
    /// that prediction (`predicted` ± 95 %), with certified bounds from its
    /// own rebuild; everything else is under `diagnostics`. `--quick`:
    /// selection only, no prediction.
    ///
    /// More: docs/cli.md.
    Strategy(crate::cmd::strategy::Args),
    /// A batch of cases (scenario × trigger family × request: synthesis,
    /// strategy, validation) from a SPEC file, resumable, shared across MPI
    /// ranks; one JSON and one CSV table.
    Study(crate::cmd::study::Args),
    /// Simulate a strategy in-process and compare with its prediction.
    ///
    /// Predicted against simulated P_tar, P_coll and energy with 95 %
    /// intervals, and whether the prediction, the cross-fitted values and the
    /// certified bounds hold against them; radio options evaluate it under
    /// another channel; `--plot` draws the map with sampled trajectories.
    ///
    /// More: docs/cli.md.
    Validate(crate::cmd::validate::Args),
    /// Build the belief-space MDP by Monte Carlo and write DIR/mdp.bin.
    ///
    /// Then its Pareto front: `front.json` (the vertices and facets of an
    /// ε-front with its certified ε, the certified front at 95 %, constant-δ
    /// baselines, the Method 1 front), `front.png/svg` and `scenario.toml`
    /// (the segments' trigger family written into it). The same seed gives
    /// the same bytes on any thread count and any number of MPI ranks.
    ///
    /// More: docs/cli.md.
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
    ///
    /// On one thread and on all threads, at δ = 0 and at the largest δ, the
    /// median and range of the timed repeats; `--front`: the time of the
    /// front, the strategy LP and the PRISM export.
    ///
    /// More: docs/cli.md.
    Bench(crate::cmd::bench::Args),
    /// Run a strategy as processes (coordinator, agent, one per sensor) over iceoryx2.
    ///
    /// The report gives the outcomes with 95 % intervals and each sensor's
    /// packets (its ledger, what the agent received) against the prediction:
    /// the MDP's expected energy per leg stored in `strategy.json`, or for
    /// `--scenario --delta` an in-process simulation (`--predict-episodes`).
    /// `--record` writes every message to one MCAP file, `--live` serves the
    /// run to Foxglove, `--listen … --remote …` puts sensors on other hosts.
    ///
    /// More: docs/cli.md.
    Run(Box<crate::run_args::RunArgs>),
    /// Serve remote sensors of a run on this host (`etp run --listen … --remote …` on the agent host).
    ///
    /// Fetches the scenario and parameters from the agent host, starts the
    /// sensor processes and exits when the run ends or the agent host is
    /// gone. The link and what it admits: docs/remote.md.
    ///
    /// More: docs/cli.md.
    SensorHost(crate::cmd::sensor_host::Args),
    /// Key material of an authenticated, encrypted run across hosts:
    /// `etp certs init DIR` (then `--tls DIR` on `run` and `sensor-host`).
    Certs(crate::cmd::certs::Args),
    /// Recording tools: `etp replay FILE` summarises a run's MCAP recording (finished
    /// or not); `etp replay info|cat|export|filter|verify|repair|publish|foxglove|plot`.
    Replay(crate::cmd::replay::Args),
    /// Run one process of a run (used by `etp run` when the process binaries
    /// are not installed beside `etp`).
    ///
    /// `etp process NAME --help`: that process's own options.
    #[command(hide = true, disable_help_flag = true)]
    Process(crate::cmd::process::Args),
}

/// The interface as clap builds it, every option that takes a value
/// accepting one that starts with `-`-and-a-digit: `--episodes -1` is then
/// refused as an invalid value of `--episodes` (exit 2), not as an unknown
/// argument `-1` with a tip to write `-- -1`.
pub fn command() -> clap::Command {
    negative_values(Cli::command())
}

fn negative_values(c: clap::Command) -> clap::Command {
    c.mut_args(|a| {
        if a.get_action().takes_values() {
            a.allow_negative_numbers(true)
        } else {
            a
        }
    })
    .mut_subcommands(negative_values)
}

/// Parse the process's command line with [`command`]; clap's usage error
/// (exit 2) or help (exit 0) ends the process.
pub fn parse() -> Cli {
    use clap::FromArgMatches;
    let mut c = command();
    let m = c.get_matches_mut();
    Cli::from_arg_matches(&m).unwrap_or_else(|e| e.format(&mut c).exit())
}

#[cfg(test)]
mod tests {
    /// clap's own consistency checks (ids in `requires`/`conflicts_with`,
    /// duplicate flags) on every subcommand; release builds skip them.
    #[test]
    fn the_interface_is_consistent() {
        super::command().debug_assert();
    }
}
