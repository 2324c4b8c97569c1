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
    /// Instead: time the Pareto front of DIR/mdp.bin (written by `etp synthesize`).
    #[arg(long, value_name = "DIR")]
    pub front: Option<std::path::PathBuf>,
}

fn bench_front(dir: &std::path::Path, json_out: bool) -> Result<()> {
    let (mdp, _) = crate::output::read_mdp(dir)?;
    let start = Instant::now();
    let front = etp_synthesis::pareto::compute_front(&mdp, Default::default())?;
    let secs = start.elapsed().as_secs_f64();
    let v = json!({"states": mdp.states.len(), "transitions": mdp.num_transitions(),
                   "choices": mdp.states.iter().map(|s| s.choices.len()).sum::<usize>(),
                   "vertices": front.vertices.len(), "facets": front.facets.len(),
                   "optimisations": front.optimisations, "rounds": front.rounds, "seconds": secs});
    if json_out {
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "Pareto front of {}: {} states, {} transitions → {} vertices, {} facets ({} optimisations, {} rounds) in {:.3} s",
            dir.display(),
            mdp.states.len(),
            mdp.num_transitions(),
            front.vertices.len(),
            front.facets.len(),
            front.optimisations,
            front.rounds,
            secs
        );
    }
    Ok(())
}

pub fn run(a: Args) -> Result<()> {
    if let Some(dir) = &a.front {
        return bench_front(dir, a.json);
    }
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
