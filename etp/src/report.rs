//! The text of a simulation's summary, written once for the commands that
//! print one: `simulate`, `validate` and `run` (the tables, the channel
//! line); its JSON is `etp_synthesis::report`'s, shared with the Python
//! package.

use etp_shared::scenario::Scenario;
use etp_synthesis::report::{estimates, first_non_finite};
use etp_synthesis::simulate::SimulationSummary;

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

/// The last line of defence against a result that is not a number: a
/// summary holding one (a scenario whose numbers overflowed in a way
/// `Scenario::from_toml` did not foresee) is an error naming the quantity,
/// never a table or a JSON `null` with exit 0.
pub fn ensure_finite(sum: &SimulationSummary) -> anyhow::Result<()> {
    match first_non_finite(sum) {
        None => Ok(()),
        Some((key, v)) => anyhow::bail!(
            "the simulation's {key} is {v}, not a number: the scenario's arithmetic overflowed \
             over {} episodes ({} steps); nothing is reported (check the scenario's model.F, \
             Q, R and P0: docs/MODEL.md §1.1)",
            sum.episodes,
            sum.total_steps
        ),
    }
}

/// A readable table of a summary.
pub fn summary_table(sum: &SimulationSummary) -> String {
    let mut o = String::new();
    for (k, e) in estimates(sum) {
        o.push_str(&format!("  {k:<22} {:>12.4} ± {:.4}\n", e.value, e.ci95));
    }
    o
}
