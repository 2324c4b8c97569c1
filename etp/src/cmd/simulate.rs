//! `etp simulate SCENARIO --delta D`: in-process episodes with a constant threshold.

use crate::input::{RadioArgs, load_scenario_with_radio};
use crate::progress;
use anyhow::{Result, bail};
use etp_shared::episode::{CompiledScenario, LegMode};
use etp_shared::etkf::Threshold;
use etp_shared::rng::streams;
use etp_shared::scenario::Scenario;
use etp_shared::stats::Estimate;
use etp_shared::with_dim;
use etp_synthesis::simulate::{SensorCounts, SimulationSummary, simulate};
use serde_json::{Map, Value, json};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Built-in name (winding-2d, open-2d, superg-3d, inertia-2d, inertia-3d) or path to a scenario TOML.
    pub scenario: String,
    /// The constant threshold δ ≥ 0 used on every leg (0 = full Kalman filter).
    #[arg(long)]
    pub delta: f64,
    #[command(flatten)]
    pub sim: crate::input::EpisodeArgs,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub radio: RadioArgs,
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
    let s = load_scenario_with_radio(&a.scenario, &a.radio)?;
    let pb = progress::bar(a.sim.episodes, "simulate", a.json);
    let started = std::time::Instant::now();
    let sum = simulate_constant(&s, a.delta, a.sim.episodes, a.sim.seed, &|k| pb.inc(k));
    pb.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    if a.json {
        let mut v = summary_json(&s, &sum);
        if let Some(m) = v.as_object_mut() {
            m.insert("scenario".into(), json!(s.name));
            m.insert("seed".into(), json!(a.sim.seed));
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
            "{} · δ = {} · {} episodes · seed {} · {:.2} s · radio: {}",
            s.name,
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

/// The flat JSON object of a summary (`crate::vocab`): `<key>` and
/// `<key>_ci95` per estimate, total and per-sensor transmissions and energy.
pub fn summary_json(s: &Scenario, sum: &SimulationSummary) -> Value {
    let mut m = Map::new();
    m.insert("episodes".into(), json!(sum.episodes));
    for (k, e) in estimates(sum) {
        m.insert(k.into(), json!(e.value));
        m.insert(format!("{k}_ci95"), json!(e.ci95));
    }
    m.insert("steps".into(), json!(sum.total_steps));
    let total = sum
        .sensors
        .iter()
        .fold(SensorCounts::default(), |mut t, c| {
            t.slots += c.slots;
            t.transmissions += c.transmissions;
            t.triggers += c.triggers;
            t.delivered += c.delivered;
            t.expected_triggers += c.expected_triggers;
            t
        });
    m.insert("transmissions".into(), json!(total.transmissions));
    radio_counts(&mut m, &total);
    m.insert("radio".into(), json!(s.radio.describe(&sensor_names(s))));
    let sensors: Vec<Value> = s
        .sensors
        .iter()
        .zip(&sum.sensors)
        .map(|(x, c)| {
            let mut o = Map::new();
            o.insert("name".into(), json!(x.name));
            o.insert("slots".into(), json!(c.slots));
            o.insert("transmissions".into(), json!(c.transmissions));
            o.insert(
                "energy".into(),
                json!(crate::vocab::round_energy(x.cost * c.transmissions as f64)),
            );
            o.insert("predicted_energy".into(), Value::Null);
            radio_counts(&mut o, c);
            let rate = |k: f64| (c.slots > 0).then(|| k / c.slots as f64);
            o.insert("trigger_rate".into(), json!(rate(c.triggers as f64)));
            o.insert(
                "trigger_rate_expected".into(),
                json!(rate(c.expected_triggers)),
            );
            Value::Object(o)
        })
        .collect();
    m.insert("sensors".into(), json!(sensors));
    Value::Object(m)
}

fn sensor_names(s: &Scenario) -> Vec<String> {
    s.sensors.iter().map(|x| x.name.clone()).collect()
}

/// The radio's counts (docs/MODEL.md §8): `triggers`, `delivered`, `lost`
/// (attempts lost: `transmissions = delivered + lost`), `loss_rate` (lost per
/// attempt, null without attempts) and `undelivered_rate` (triggers that
/// never reached the agent, per trigger).
fn radio_counts(m: &mut Map<String, Value>, c: &SensorCounts) {
    m.insert("triggers".into(), json!(c.triggers));
    m.insert("delivered".into(), json!(c.delivered));
    m.insert("lost".into(), json!(c.lost()));
    let per = |k: u64, n: u64| (n > 0).then(|| k as f64 / n as f64);
    m.insert("loss_rate".into(), json!(per(c.lost(), c.transmissions)));
    m.insert(
        "undelivered_rate".into(),
        json!(per(c.triggers - c.delivered, c.triggers)),
    );
}

fn estimates(sum: &SimulationSummary) -> [(&'static str, Estimate); 8] {
    [
        ("p_target", sum.p_target),
        ("p_collision", sum.p_collision),
        ("p_free", sum.p_free),
        ("energy_mean", sum.energy_mean),
        ("steps_mean", sum.steps_mean),
        ("trigger_rate", sum.trigger_rate),
        ("trigger_rate_expected", sum.trigger_rate_expected),
        ("nees", sum.nees),
    ]
}

/// Per-sensor radio counts (only when the radio loses packets).
pub fn radio_table(s: &Scenario, sum: &SimulationSummary) -> String {
    if s.radio.is_ideal() {
        return String::new();
    }
    let mut o = format!(
        "  {:<8} {:>10} {:>10} {:>10} {:>10} {:>9} {:>9} {:>9}\n",
        "sensor", "triggers", "attempts", "delivered", "lost", "loss", "rate", "expected"
    );
    for (x, c) in s.sensors.iter().zip(&sum.sensors) {
        if c.slots == 0 {
            continue;
        }
        let frac = |k: f64, n: u64| if n > 0 { k / n as f64 } else { 0.0 };
        o.push_str(&format!(
            "  {:<8} {:>10} {:>10} {:>10} {:>10} {:>9.4} {:>9.4} {:>9.4}\n",
            x.name,
            c.triggers,
            c.transmissions,
            c.delivered,
            c.lost(),
            frac(c.lost() as f64, c.transmissions),
            frac(c.triggers as f64, c.slots),
            frac(c.expected_triggers, c.slots),
        ));
    }
    o
}

/// A readable table of a summary.
pub fn summary_table(sum: &SimulationSummary) -> String {
    let mut o = String::new();
    for (k, e) in estimates(sum) {
        o.push_str(&format!("  {k:<22} {:>12.4} ± {:.4}\n", e.value, e.ci95));
    }
    o
}
