//! `etp simulate SCENARIO --delta D`: in-process episodes with a constant threshold.

use crate::input::load_scenario_with_radio;
use crate::report::{radio_table, summary_table};
use crate::scenario_flags::{RadioArgs, TriggerArgs};
use anyhow::Result;
use etp_pipeline::progress;
use etp_shared::trigger::TriggerFamily;
use etp_synthesis::constant::{check_delta, simulate_constant};
use etp_synthesis::exec::Executor;
use etp_synthesis::report::sensor_names;
use etp_synthesis::report::simulate_json;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Built-in name (winding-2d, open-2d, superg-3d, inertia-2d, inertia-3d) or path to a scenario TOML.
    pub scenario: String,
    /// The constant threshold δ ≥ 0 used on every leg (0 = full Kalman filter).
    #[arg(long, value_parser = crate::values::non_negative)]
    pub delta: f64,
    #[command(flatten)]
    pub sim: crate::input::EpisodeArgs,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub radio: RadioArgs,
    #[command(flatten)]
    pub trigger: TriggerArgs,
}

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    check_delta(a.delta)?;
    let s = a
        .trigger
        .apply(load_scenario_with_radio(&a.scenario, &a.radio)?);
    let pb = progress::bar(exec, a.sim.episodes, "simulate", a.json);
    let started = std::time::Instant::now();
    let sum = simulate_constant(
        &s,
        a.delta,
        a.sim.episodes,
        a.sim.seed,
        &exec.work(|k| pb.inc(k)),
    )?;
    pb.finish_and_clear();
    crate::report::ensure_finite(&sum)?;
    let secs = started.elapsed().as_secs_f64();
    if a.json {
        let v = simulate_json(&s, &sum, a.delta, a.sim.seed);
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "{} · {}δ = {} · {} episodes · seed {} · {:.2} s · radio: {}",
            s.name,
            match s.trigger {
                TriggerFamily::Box => String::new(),
                family => format!("trigger {family} · "),
            },
            a.delta,
            sum.episodes,
            a.sim.seed,
            secs,
            s.radio.describe(&sensor_names(&s))
        );
        print!("{}", summary_table(&sum));
        print!("{}", radio_table(&s, &sum));
    }
    Ok(())
}
