//! The text and JSON of a simulation's summary, written once for the
//! commands that print one: `simulate`, `validate` and `run` (the flat keys
//! of `crate::vocab`, the tables, the channel line).

use etp_shared::scenario::Scenario;
use etp_shared::stats::Estimate;
use etp_synthesis::simulate::{SensorCounts, SimulationSummary};
use serde_json::{Map, Value, json};

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

pub fn sensor_names(s: &Scenario) -> Vec<String> {
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
