//! `etp simulate SCENARIO --delta D`: in-process episodes with a constant threshold.

use crate::input::load_scenario;
use crate::progress;
use anyhow::{Result, bail};
use etp_shared::episode::{CompiledScenario, LegMode};
use etp_shared::etkf::Threshold;
use etp_shared::rng::streams;
use etp_shared::scenario::Scenario;
use etp_shared::stats::Estimate;
use etp_shared::with_dim;
use etp_synthesis::simulate::{SimulationSummary, simulate};
use serde_json::{Map, Value, json};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Built-in name (winding-2d, open-2d, superg-3d, inertia-2d, inertia-3d) or path to a scenario TOML.
    pub scenario: String,
    /// The constant threshold δ ≥ 0 used on every leg (0 = full Kalman filter).
    #[arg(long)]
    pub delta: f64,
    /// Number of episodes.
    #[arg(long, default_value_t = 3000)]
    pub episodes: u64,
    /// Seed of the random streams (same seed, same numbers, any thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Simulate a constant threshold on a scenario (all threads).
pub fn simulate_constant(
    s: &Scenario,
    delta: f64,
    episodes: u64,
    seed: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> SimulationSummary {
    let t = Threshold::new(delta);
    with_dim!(s.dim, N => {
        let c = CompiledScenario::<N>::new(s);
        let policy = move |_: usize, _: &_, _: &mut _| LegMode::<N>::EventTriggered(t);
        simulate(&c, &policy, episodes, seed, streams::SIMULATE, progress).summary()
    })
}

pub fn run(a: Args) -> Result<()> {
    if !(a.delta.is_finite() && a.delta >= 0.0) {
        bail!("--delta must be a finite number ≥ 0, got {}", a.delta);
    }
    if a.episodes == 0 {
        bail!("--episodes must be at least 1");
    }
    let s = load_scenario(&a.scenario)?;
    let pb = progress::bar(a.episodes, "simulate", a.json);
    let started = std::time::Instant::now();
    let sum = simulate_constant(&s, a.delta, a.episodes, a.seed, &|k| pb.inc(k));
    pb.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    if a.json {
        let mut v = summary_json(&s, &sum);
        if let Some(m) = v.as_object_mut() {
            m.insert("scenario".into(), json!(s.name));
            m.insert("seed".into(), json!(a.seed));
            m.insert(
                "strategy".into(),
                json!(format!("constant δ = {}", a.delta)),
            );
            m.insert("delta".into(), json!(a.delta));
            // No model prediction for a plain simulation.
            m.insert("predicted".into(), Value::Null);
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "{} · δ = {} · {} episodes · seed {} · {:.2} s",
            s.name, a.delta, sum.episodes, a.seed, secs
        );
        print!("{}", summary_table(&sum));
    }
    Ok(())
}

/// The flat JSON object of a summary (`crate::vocab`): `<key>` and
/// `<key>_ci95` per estimate, total and per-sensor transmissions and energy.
pub fn summary_json(s: &Scenario, sum: &SimulationSummary) -> Value {
    let mut m = Map::new();
    m.insert("episodes".into(), json!(sum.episodes));
    for (k, e) in estimates(sum) {
        m.insert(k.into(), json!(e.value));
        m.insert(format!("{k}_ci95"), json!(e.ci95));
    }
    m.insert("total_steps".into(), json!(sum.total_steps));
    m.insert(
        "transmissions".into(),
        json!(sum.sensors.iter().map(|c| c.transmissions).sum::<u64>()),
    );
    let sensors: Vec<Value> = s
        .sensors
        .iter()
        .zip(&sum.sensors)
        .map(|(x, c)| {
            json!({"name": x.name, "slots": c.slots, "transmissions": c.transmissions,
                   "energy": crate::vocab::round_energy(x.cost * c.transmissions as f64),
                   "predicted_energy": null})
        })
        .collect();
    m.insert("sensors".into(), json!(sensors));
    Value::Object(m)
}

fn estimates(sum: &SimulationSummary) -> [(&'static str, Estimate); 7] {
    [
        ("p_target", sum.p_target),
        ("p_collision", sum.p_collision),
        ("p_free", sum.p_free),
        ("energy_mean", sum.energy_mean),
        ("steps_mean", sum.steps_mean),
        ("trigger_rate", sum.trigger_rate),
        ("trigger_rate_expected", sum.trigger_rate_expected),
    ]
}

/// A readable table of a summary.
pub fn summary_table(sum: &SimulationSummary) -> String {
    let mut o = String::new();
    for (k, e) in estimates(sum) {
        o.push_str(&format!("  {k:<22} {:>12.4} ± {:.4}\n", e.value, e.ci95));
    }
    o
}
