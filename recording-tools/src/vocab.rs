//! THE JSON vocabulary of `simulate`, `validate`, `run` and `replay`
//! (published as JSON Schemas in `schemas/`, checked by the CLI tests): one
//! name and one type per quantity, whichever command prints it.
//!
//! * identity: `scenario` (string), `seed` (integer), `strategy` (label,
//!   string or null), `delta` (number: a constant threshold; null for a
//!   strategy that varies it), `episodes` (integer);
//! * measured outcomes: `p_target`, `p_collision`, `p_free`, `energy_mean`,
//!   each with `<key>_ci95` (95 % half-width) where the command has it;
//! * `predicted`: `{p_target, p_collision, p_free, energy_mean}` (numbers),
//!   the prediction etp stands by, or null (a `--quick` strategy);
//!   `predicted_ci95` its 95 % half-widths (null where it has none);
//!   `prediction_check` each of P_tar, P_coll and energy measured against it
//!   ([`prediction_check`]);
//! * `transmissions` (integer): transmissions counted by the sensors;
//!   `received` what the agent received; `measurements` the `measurement`
//!   messages of a recording;
//! * `sensors`: one object per sensor with `name`, `transmissions`,
//!   `energy` and `predicted_energy` (number or null), plus what the command
//!   knows more (`slots`, `received`, `measurements`).
//!
//! Numbers are JSON numbers, never strings.

use etp_shared::strategy::{Policy, Prediction, PredictionCi95};
use serde_json::{Value, json};

/// A measurement with its 95 % half-width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    pub value: f64,
    pub ci95: f64,
}

/// Measured P_tar, P_coll and energy per episode against the prediction:
/// each `inside` when |predicted − measured| ≤ the measured half-width and
/// the prediction's own joined in quadrature. Null without a prediction.
pub fn prediction_check(
    p: Option<&Prediction>,
    ci: Option<&PredictionCi95>,
    measured: [Measured; 3],
) -> Value {
    let Some(p) = p else {
        return Value::Null;
    };
    let own = ci.copied().unwrap_or_default();
    let row = |pred: f64, own: f64, m: Measured| {
        let width = m.ci95.hypot(own);
        json!({"predicted": pred, "measured": m.value, "measured_ci95": m.ci95,
            "predicted_ci95": own, "inside": (pred - m.value).abs() <= width})
    };
    json!({
        "p_target": row(p.p_target, own.p_target, measured[0]),
        "p_collision": row(p.p_collision, own.p_collision, measured[1]),
        "energy_mean": row(p.energy_mean, own.energy_mean, measured[2]),
    })
}

/// One text line of a [`prediction_check`]: which quantities fall outside.
pub fn prediction_check_text(v: &Value) -> String {
    if v.is_null() {
        return "  prediction: none to compare (a --quick strategy)\n".into();
    }
    let mut out = Vec::new();
    for (k, name) in [
        ("p_target", "P_tar"),
        ("p_collision", "P_coll"),
        ("energy_mean", "energy"),
    ] {
        let r = &v[k];
        if r["inside"].as_bool() == Some(false) {
            out.push(format!(
                "{name} predicted {} outside measured {} ± {}",
                human(r["predicted"].as_f64().unwrap_or(f64::NAN)),
                human(r["measured"].as_f64().unwrap_or(f64::NAN)),
                human(r["measured_ci95"].as_f64().unwrap_or(f64::NAN)),
            ));
        }
    }
    if out.is_empty() {
        "  prediction: P_tar, P_coll and energy inside the measured 95 % intervals (joined with the prediction's ±)\n".into()
    } else {
        format!(
            "  PREDICTION OUTSIDE the measured interval: {}\n",
            out.join("; ")
        )
    }
}

/// `predicted` of every command.
pub fn prediction(p: Option<&Prediction>) -> Value {
    let Some(p) = p else {
        return Value::Null;
    };
    json!({
        "p_target": p.p_target,
        "p_collision": p.p_collision,
        "p_free": p.p_free,
        "energy_mean": p.energy_mean,
    })
}

/// The constant threshold of a strategy's policy (every state's ω puts all
/// its mass on one δ, the same everywhere); `None` when δ varies.
pub fn constant_delta(policy: &Policy) -> Option<f64> {
    let mut index = None;
    for st in &policy.states {
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
    policy.deltas.get(index?).copied()
}

/// The rounding of the vocabulary's energies (`etp_shared::stats`: the
/// simulation summary of `etp-synthesis` rounds with it too).
pub use etp_shared::stats::{round_energy, round_sig};

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

/// The radio of a validation or a run: the strategy's own channel, or both
/// when the options evaluate it under another one (a robustness study,
/// docs/MODEL.md §8.6).
pub fn channels_text(
    synthesized: &etp_shared::radio::Radio,
    evaluated: &etp_shared::radio::Radio,
    names: &[String],
) -> String {
    if synthesized == evaluated {
        format!("radio: {}, the strategy's own", evaluated.describe(names))
    } else {
        format!(
            "radio: {} — the strategy was synthesized for {}",
            evaluated.describe(names),
            synthesized.describe(names)
        )
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
