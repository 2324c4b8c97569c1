//! A simulation summary's JSON, written once for every front end that
//! prints or returns one: `etp simulate --json` and `etp validate --json`
//! (the flat keys of `etp_recording_tools::vocab`), and the Python package's
//! `etpareto.simulate(…).summary`, which is `json.loads` of
//! [`simulate_json`]'s text — the CLI's object by construction.

use crate::simulate::{SensorCounts, SimulationSummary};
use etp_shared::scenario::Scenario;
use etp_shared::stats::Estimate;
use etp_shared::trigger::TriggerFamily;
use serde_json::{Map, Value, json};

/// The object `etp simulate SCENARIO --delta D --episodes N --seed S
/// --json` prints: [`summary_json`] with the run's identity (`scenario`,
/// `seed`, `strategy`, `delta`, `trigger` for a family other than `box`)
/// and `predicted` null (a plain simulation has no model prediction).
pub fn simulate_json(s: &Scenario, sum: &SimulationSummary, delta: f64, seed: u64) -> Value {
    let mut v = summary_json(s, sum);
    if let Some(m) = v.as_object_mut() {
        m.insert("scenario".into(), json!(s.name));
        m.insert("seed".into(), json!(seed));
        m.insert("strategy".into(), json!(format!("constant δ = {delta}")));
        m.insert("delta".into(), json!(delta));
        if s.trigger != TriggerFamily::Box {
            m.insert("trigger".into(), json!(s.trigger.name()));
        }
        m.insert("predicted".into(), Value::Null);
    }
    v
}

/// The flat JSON object of a summary (the vocabulary of
/// `etp_recording_tools::vocab`): `<key>` and
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
                json!(etp_shared::stats::round_energy(
                    x.cost * c.transmissions as f64
                )),
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

/// The first estimate (value or half-width) of a summary that is not a
/// number (NaN, ±∞), by its JSON key: what the front ends refuse to print
/// (docs/MODEL.md §1.1).
pub fn first_non_finite(sum: &SimulationSummary) -> Option<(String, f64)> {
    estimates(sum).into_iter().find_map(|(k, e)| {
        if !e.value.is_finite() {
            Some((k.to_string(), e.value))
        } else if !e.ci95.is_finite() {
            Some((format!("{k}_ci95"), e.ci95))
        } else {
            None
        }
    })
}

pub fn estimates(sum: &SimulationSummary) -> [(&'static str, Estimate); 8] {
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

#[cfg(test)]
mod tests {
    use super::first_non_finite;
    use crate::simulate::SimulationTotals;

    /// A summary whose NEES sum overflowed to ∞ − ∞ is named by its key;
    /// one of finite sums is not.
    #[test]
    fn a_quantity_that_is_not_a_number_is_named() {
        let mut t = SimulationTotals {
            episodes: 2,
            target: 1,
            free: 1,
            ..SimulationTotals::default()
        };
        for e in [3.0, 5.0] {
            t.energy.push(e);
            t.steps.push(10.0);
            t.rate.push(2.0, 10.0);
            t.expected_rate.push(2.5, 10.0);
            t.nees.push(9.0, 10.0);
        }
        assert_eq!(first_non_finite(&t.summary()), None);
        t.nees.push(f64::INFINITY - f64::INFINITY, 10.0);
        let (key, v) = first_non_finite(&t.summary()).expect("NaN named");
        assert_eq!(key, "nees");
        assert!(v.is_nan());
    }
}
