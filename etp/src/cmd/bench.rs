//! `etp bench`: throughput of the in-process simulator in episode-steps per
//! second, on one thread and on all threads, at δ = 0 and at the largest δ.

use crate::cmd::simulate::simulate_constant;
use crate::input::load_scenario;
use anyhow::Result;
use serde_json::json;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario to measure on.
    #[arg(default_value = "winding-2d")]
    pub scenario: String,
    /// Episodes per measurement.
    #[arg(long, default_value_t = 4000)]
    pub episodes: u64,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> Result<()> {
    let s = load_scenario(&a.scenario)?;
    let max_delta = s.deltas.iter().copied().fold(0.0, f64::max);
    let threads = rayon::current_num_threads();
    let mut rows = Vec::new();
    for delta in [0.0, max_delta] {
        for t in [1, threads] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build()?;
            // Warm-up run (page faults, caches), then the timed one.
            pool.install(|| simulate_constant(&s, delta, a.episodes / 10 + 1, 1, &|_| {}));
            let start = Instant::now();
            let sum = pool.install(|| simulate_constant(&s, delta, a.episodes, 2, &|_| {}));
            let secs = start.elapsed().as_secs_f64();
            let rate = sum.total_steps as f64 / secs;
            rows.push(
                json!({"scenario": s.name, "delta": delta, "threads": t, "episodes": a.episodes,
                             "steps": sum.total_steps, "seconds": secs, "steps_per_second": rate,
                             "steps_per_second_per_thread": rate / t as f64}),
            );
            if !a.json {
                println!(
                    "{:<12} δ = {:<7.4} threads {}  {:>10} steps in {:>6.3} s  → {:>6.2} M steps/s ({:.2} M/s per thread)",
                    s.name,
                    delta,
                    t,
                    sum.total_steps,
                    secs,
                    rate / 1e6,
                    rate / 1e6 / t as f64
                );
            }
        }
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    }
    Ok(())
}
