//! THE JSON vocabulary of `simulate`, `validate`, `run` and `replay`
//! (published as JSON Schemas in `schemas/`, checked by the CLI tests): one
//! name and one type per quantity, whichever command prints it.
//!
//! * identity: `scenario` (string), `seed` (integer), `strategy` (label,
//!   string or null), `delta` (number: a constant threshold; null for a
//!   strategy that varies it), `episodes` (integer);
//! * measured outcomes: `p_target`, `p_collision`, `p_free`, `energy_mean`,
//!   each with `<key>_ci95` (95 % half-width) where the command has it;
//! * `predicted`: `{p_target, p_collision, p_free, energy_mean}` (numbers);
//! * `transmissions` (integer): transmissions counted by the sensors;
//!   `received` what the agent received; `measurements` the `measurement`
//!   messages of a recording;
//! * `sensors`: one object per sensor with `name`, `transmissions`,
//!   `energy` and `predicted_energy` (number or null), plus what the command
//!   knows more (`slots`, `received`, `measurements`).
//!
//! Numbers are JSON numbers, never strings.

use etp_shared::strategy::{Prediction, Strategy};
use serde_json::{Value, json};

/// `predicted` of every command.
pub fn prediction(p: &Prediction) -> Value {
    json!({
        "p_target": p.p_target,
        "p_collision": p.p_collision,
        "p_free": p.p_free,
        "energy_mean": p.energy_mean,
    })
}

/// The constant threshold of a strategy (every state's ω puts all its mass
/// on one δ, the same everywhere); `None` when δ varies.
pub fn constant_delta(s: &Strategy) -> Option<f64> {
    let mut index = None;
    for st in &s.states {
        let (k, w) = st
            .omega
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))?;
        if *w < 1.0 - 1e-12 || index.is_some_and(|i| i != k) {
            return None;
        }
        index = Some(k);
    }
    s.deltas.get(index?).copied()
}

/// An energy or count-like float without the noise of its last bits
/// (`25869.399999999994` → `25869.4`): 10 significant digits.
pub fn round_energy(x: f64) -> f64 {
    round_sig(x, 10)
}

/// `x` rounded to `digits` significant digits (non-finite and 0 unchanged).
pub fn round_sig(x: f64, digits: i32) -> f64 {
    if !x.is_finite() || x == 0.0 {
        return x;
    }
    // Rust's `{:e}` rounds correctly to the digits asked; parsing it back
    // gives the nearest f64 (which prints with those digits only).
    format!("{:.*e}", (digits - 1).max(0) as usize, x)
        .parse()
        .unwrap_or(x)
}

/// A number for people: a few significant digits, no float noise
/// (`25869.399999999994` → `25869.4`, `0.95213` → `0.9521`).
pub fn human(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    let r = round_sig(x, 5);
    if r.abs() >= 1e6 || (r != 0.0 && r.abs() < 1e-4) {
        format!("{r:e}")
    } else {
        format!("{r}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_lose_their_noise() {
        assert_eq!(round_energy(25869.399999999994), 25869.4);
        assert_eq!(human(25869.399999999994), "25869");
        assert_eq!(human(0.95213), "0.95213");
        assert_eq!(human(0.952134), "0.95213");
        assert_eq!(human(1.5), "1.5");
        assert_eq!(human(0.0), "0");
        assert_eq!(human(2.0e-7), "2e-7");
    }
}
