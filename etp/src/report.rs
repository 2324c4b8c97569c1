//! The text of a simulation's summary, written once for the commands that
//! print one: `simulate`, `validate` and `run` (the tables, the channel
//! line); its JSON is `etp_synthesis::report`'s, shared with the Python
//! package.

use etp_shared::scenario::Scenario;
use etp_synthesis::report::estimates;
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

/// [`etp_pipeline::validation::ensure_finite`]: a summary that is not a
/// number is an error, never a table or a JSON `null` with exit 0.
pub fn ensure_finite(sum: &SimulationSummary) -> anyhow::Result<()> {
    Ok(etp_pipeline::validation::ensure_finite(sum)?)
}

/// A readable table of a summary.
pub fn summary_table(sum: &SimulationSummary) -> String {
    let mut o = String::new();
    for (k, e) in estimates(sum) {
        o.push_str(&format!("  {k:<22} {:>12.4} ± {:.4}\n", e.value, e.ci95));
    }
    o
}
