//! `etp bench`: throughput of the in-process simulator in episode-steps per
//! second, on one thread and on all threads, at δ = 0 and at the largest δ;
//! with `--front`: the Pareto front, the strategy LP and the PRISM export of
//! synthesized MDPs and of a synthetic layered MDP of thousands of states.

use crate::input::load_scenario_with_radio;
use crate::scenario_flags::{RadioArgs, TriggerArgs};
use anyhow::Result;
use etp_synthesis::constant::simulate_constant;
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::optimal::{LpRequest, optimal_strategy};
use etp_synthesis::synthetic::{SyntheticParams, layered_mdp};
use serde_json::json;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario to measure on.
    #[arg(default_value = "winding-2d")]
    pub scenario: String,
    /// Episodes per measurement (at least 1).
    #[arg(long, default_value_t = 4000, value_parser = crate::values::whole::<u64>(1, None))]
    pub episodes: u64,
    /// Timed repetitions per row; the row reports their median rate and
    /// range (this machine is shared: one run can lose a third to a neighbour).
    #[arg(long, default_value_t = 5, value_parser = crate::values::whole::<u32>(1, None))]
    pub repeats: u32,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Instead: time the Pareto front, the strategy LP and the PRISM export of
    /// each DIR/mdp.bin (written by `etp synthesize`) and of a synthetic layered
    /// MDP (`--synthetic-states`).
    #[arg(long, value_name = "DIR", num_args = 0..)]
    pub front: Option<Vec<std::path::PathBuf>>,
    /// With --front: states of the synthetic layered MDP (0: no synthetic row).
    #[arg(long, default_value_t = 5000, value_name = "N")]
    pub synthetic_states: usize,
    /// With --front: seed of the synthetic MDP.
    #[arg(long, default_value_t = 0)]
    pub synthetic_seed: u64,
    /// With --front: stopping tolerance of the front's enumeration on the
    /// synthesized MDPs (scaled units, > 0; the certified ε is reported).
    #[arg(long, default_value_t = etp_synthesis::pareto::enumerate::TOLERANCE,
          value_parser = crate::values::positive)]
    pub tolerance: f64,
    /// With --front: the same for the synthetic MDP (its front has many more
    /// vertices; the certified ε is reported).
    #[arg(long, default_value_t = SYNTHETIC_TOLERANCE, value_parser = crate::values::positive)]
    pub synthetic_tolerance: f64,
    /// Measure the simulator under this radio (docs/MODEL.md §8).
    #[command(flatten)]
    pub radio: RadioArgs,
    /// Measure the simulator with this trigger family (docs/MODEL.md §9).
    #[command(flatten)]
    pub trigger: TriggerArgs,
}

/// Default stopping tolerance of the synthetic row: its front at 1e-6 has
/// thousands of vertices (11211 at 1000 states, 98 s); 1e-3 certifies
/// ε ≈ 1e-3 on 5000 states in a few seconds.
pub const SYNTHETIC_TOLERANCE: f64 = 1e-3;

/// One `--front` row: the front, a strategy and the PRISM export of one MDP.
fn bench_front_row(name: &str, mdp: &Mdp, tolerance: f64) -> Result<serde_json::Value> {
    let start = Instant::now();
    let front = etp_synthesis::pareto::compute_front_to(mdp, CostModel::Counted, tolerance)?;
    let front_secs = start.elapsed().as_secs_f64();
    // A request in the middle of the front's P_tar range.
    let (lo, hi) = front
        .vertices
        .iter()
        .map(|v| v.objectives.p_target)
        .fold((1.0_f64, 0.0_f64), |(lo, hi), p| (lo.min(p), hi.max(p)));
    let min_target = 0.5 * (lo + hi);
    let start = Instant::now();
    let strategy = optimal_strategy(
        mdp,
        CostModel::Counted,
        LpRequest::MinEnergy {
            min_target,
            max_collision: None,
        },
    )?;
    let lp_secs = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let files = etp_synthesis::export::prism::export(mdp, CostModel::Counted, String::new());
    let export_secs = start.elapsed().as_secs_f64();
    let export_bytes: usize = files.files().iter().map(|(_, t)| t.len()).sum();
    let start = Instant::now();
    let props = etp_synthesis::export::prism::properties(mdp, &front, CostModel::Counted);
    let props_secs = start.elapsed().as_secs_f64();
    Ok(
        json!({"mdp": name, "states": mdp.states.len(), "transitions": mdp.num_transitions(),
              "choices": mdp.states.iter().map(|s| s.choices.len()).sum::<usize>(),
              "vertices": front.vertices.len(), "facets": front.facets.len(),
              "optimisations": front.optimisations, "rounds": front.rounds,
              "tolerance": tolerance, "epsilon": front.epsilon, "epsilon_energy": front.epsilon_energy,
              "front_seconds": front_secs,
              "strategy_min_target": min_target, "strategy_energy": strategy.predicted.energy,
              "strategy_margin": strategy.margin, "strategy_seconds": lp_secs,
              "prism_export_seconds": export_secs, "prism_export_bytes": export_bytes,
              "prism_props_seconds": props_secs, "prism_props_bytes": props.len()}),
    )
}

fn bench_front(dirs: &[std::path::PathBuf], a: &Args) -> Result<()> {
    let mut rows = Vec::new();
    for dir in dirs {
        let (mdp, _) = etp_pipeline::output::read_mdp(dir)?;
        rows.push(bench_front_row(
            &dir.display().to_string(),
            &mdp,
            a.tolerance,
        )?);
    }
    if a.synthetic_states > 0 {
        let p = SyntheticParams {
            states: a.synthetic_states,
            seed: a.synthetic_seed,
            ..SyntheticParams::default()
        };
        let mdp = layered_mdp(&p);
        rows.push(bench_front_row(
            &mdp.scenario_name.clone(),
            &mdp,
            a.synthetic_tolerance,
        )?);
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    for r in &rows {
        println!(
            "{}: {} states, {} transitions → front {} vertices, {} facets ({} optimisations, {} rounds, certified ε = {:.2e}) in {:.3} s; exact strategy LP (P_tar ≥ {:.4}) {:.3} s; PRISM export {:.3} s ({} bytes), model.props {:.3} s",
            r["mdp"].as_str().unwrap_or("?"),
            r["states"],
            r["transitions"],
            r["vertices"],
            r["facets"],
            r["optimisations"],
            r["rounds"],
            r["epsilon"].as_f64().unwrap_or(f64::NAN),
            r["front_seconds"].as_f64().unwrap_or(f64::NAN),
            r["strategy_min_target"].as_f64().unwrap_or(f64::NAN),
            r["strategy_seconds"].as_f64().unwrap_or(f64::NAN),
            r["prism_export_seconds"].as_f64().unwrap_or(f64::NAN),
            r["prism_export_bytes"],
            r["prism_props_seconds"].as_f64().unwrap_or(f64::NAN),
        );
    }
    Ok(())
}

pub fn run(a: Args) -> Result<()> {
    if let Some(dirs) = &a.front {
        return bench_front(dirs, &a);
    }
    let s = a
        .trigger
        .apply(load_scenario_with_radio(&a.scenario, &a.radio)?);
    let max_delta = s.deltas.iter().copied().fold(0.0, f64::max);
    let threads = Executor::LOCAL.threads();
    let mut rows = Vec::new();
    for delta in [0.0, max_delta] {
        for t in [1, threads] {
            let exec = Executor::with_threads(t)?;
            let work = exec.work(|_| {});
            // Warm-up run (page faults, caches), then the timed ones (the
            // same episodes each time: same seed).
            simulate_constant(&s, delta, a.episodes / 10 + 1, 1, &work)?;
            let mut secs = Vec::new();
            let mut steps = 0;
            for _ in 0..a.repeats.max(1) {
                let start = Instant::now();
                let sum = simulate_constant(&s, delta, a.episodes, 2, &work)?;
                secs.push(start.elapsed().as_secs_f64());
                steps = sum.total_steps;
            }
            secs.sort_by(f64::total_cmp);
            let median = secs[secs.len() / 2];
            let rate = steps as f64 / median;
            let (fastest, slowest) = (steps as f64 / secs[0], steps as f64 / secs[secs.len() - 1]);
            rows.push(
                json!({"scenario": s.name, "trigger": s.trigger.name(), "delta": delta, "threads": t, "episodes": a.episodes,
                             "steps": steps, "repeats": secs.len(), "seconds": median,
                             "steps_per_second": rate,
                             "steps_per_second_per_thread": rate / t as f64,
                             "steps_per_second_range": [slowest, fastest]}),
            );
            if !a.json {
                println!(
                    "{:<12} {} δ = {:<7.4} threads {}  {:>10} steps in {:>6.3} s  → {:>6.2} M steps/s ({:.2} M/s per thread; median of {}, range {:.2}–{:.2} M/s)",
                    s.name,
                    s.trigger,
                    delta,
                    t,
                    steps,
                    median,
                    rate / 1e6,
                    rate / 1e6 / t as f64,
                    secs.len(),
                    slowest / 1e6,
                    fastest / 1e6,
                );
            }
        }
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    }
    Ok(())
}
