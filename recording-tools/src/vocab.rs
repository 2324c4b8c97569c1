//! THE JSON vocabulary of `simulate`, `validate`, `run` and `replay`
//! (published as JSON Schemas in `schemas/`, checked by the CLI tests): one
//! name and one type per quantity, whichever command prints it.
//!
//! * identity: `scenario` (string), `seed` (integer), `strategy` (label,
//!   string or null), `delta` (number: a constant threshold; null for a
//!   strategy that varies it), `episodes` (integer);
//! * measured outcomes: `p_target`, `p_collision`, `p_free`, `energy_mean`,
//!   each with `<key>_ci95` (95 % half-width) where the command has it,
//!   all from [`outcome_fields`] (`etp_shared::stats`: Wilson for
//!   proportions);
//! * `predicted`: `{p_target, p_collision, p_free, energy_mean}` (numbers),
//!   the prediction etp stands by, or null (a `--quick` strategy);
//!   `predicted_ci95` its 95 % half-widths (null where it has none);
//!   `prediction_check` each of P_tar, P_coll and energy measured against it
//!   at 95 % family-wise ([`prediction_check`]); an error or a miss is
//!   always predicted − measured;
//! * `transmissions` (integer): transmissions counted by the sensors;
//!   `received` what the agent received; `measurements` the `measurement`
//!   messages of a recording;
//! * `sensors`: one object per sensor with `name`, `transmissions`,
//!   `energy` and `predicted_energy` (number or null), plus what the command
//!   knows more (`slots`, `received`, `measurements`).
//!
//! Numbers are JSON numbers, never strings.

use etp_shared::stats::verdict::{Measured, Outcomes, prediction_checks};
use etp_shared::strategy::{Policy, Prediction, PredictionCi95};
use serde_json::{Value, json};

/// The measured outcomes as every command prints them, from one function:
/// `p_target`, `p_collision`, `p_free`, `energy_mean`, each with its
/// `_ci95` (`etp_shared::stats`: Wilson for a proportion, `1.96 s/√n` for
/// the mean; non-finite → null). A quantity not measured: null.
pub fn outcome_fields(m: &Outcomes, free: Option<Measured>) -> serde_json::Map<String, Value> {
    let num = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
    let mut out = serde_json::Map::new();
    for (key, q) in [
        ("p_target", m.p_target),
        ("p_collision", m.p_collision),
        ("p_free", free),
        ("energy_mean", m.energy),
    ] {
        let e = q.map(|q| q.estimate());
        out.insert(key.into(), e.map_or(Value::Null, |e| num(e.value)));
        out.insert(
            format!("{key}_ci95"),
            e.map_or(Value::Null, |e| num(e.ci95)),
        );
    }
    out
}

/// Measured P_tar, P_coll and energy per episode against the prediction,
/// THE verdict of `run` and `replay` (`etp_shared::stats::verdict`): each
/// quantity measured is a check, `inside` when the prediction lies in the
/// measured interval joined with its own ±, the checks a family at 95 %
/// family-wise (Bonferroni: each at `per_check_level`); `low`, `high` the
/// interval each prediction had to lie in; `measured_ci95` the plain 95 %
/// half-width. A quantity not measured (`unmeasured`: its key and why) is
/// `{"predicted", "unchecked": why}`. Null without a prediction.
pub fn prediction_check(
    p: Option<&Prediction>,
    ci: Option<&PredictionCi95>,
    m: &Outcomes,
    unmeasured: &[(&str, String)],
) -> Value {
    let Some(p) = p else {
        return Value::Null;
    };
    let own = ci.copied().unwrap_or_default();
    let (family, checks) = prediction_checks(Some(p), Some(&own), None, m);
    let num = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
    let mut out = json!({
        "family_wise_level": family.level,
        "per_check_level": family.per_check_level(),
        "family_size": family.checks,
    });
    for c in &checks {
        let measured = match c.key {
            "p_target" => m.p_target,
            "p_collision" => m.p_collision,
            _ => m.energy,
        }
        .map(|q| q.estimate());
        let own = match c.key {
            "p_target" => own.p_target,
            "p_collision" => own.p_collision,
            _ => own.energy_mean,
        };
        out[c.key] = json!({"predicted": c.value,
            "measured": measured.map_or(Value::Null, |e| num(e.value)),
            "measured_ci95": measured.map_or(Value::Null, |e| num(e.ci95)),
            "predicted_ci95": own, "low": num(c.low), "high": num(c.high),
            "inside": c.holds});
    }
    for (key, why) in unmeasured {
        let predicted = match *key {
            "p_target" => p.p_target,
            "p_collision" => p.p_collision,
            _ => p.energy_mean,
        };
        out[*key] = json!({"predicted": predicted, "unchecked": why});
    }
    out
}

/// The text of a [`prediction_check`]: which quantities fall outside, at
/// which level; which were not checked and why.
pub fn prediction_check_text(v: &Value) -> String {
    if v.is_null() {
        return "  prediction: none to compare (a --quick strategy)\n".into();
    }
    let (mut outside, mut unchecked, mut inside) = (Vec::new(), Vec::new(), Vec::new());
    let f = |r: &Value, k: &str| human(r[k].as_f64().unwrap_or(f64::NAN));
    for (k, name) in [
        ("p_target", "P_tar"),
        ("p_collision", "P_coll"),
        ("energy_mean", "energy"),
    ] {
        let r = &v[k];
        if let Some(why) = r["unchecked"].as_str() {
            unchecked.push(format!("{name} ({why})"));
        } else if r["inside"].as_bool() == Some(false) {
            outside.push(format!(
                "{name} predicted {} outside [{}, {}] (measured {} ± {} at 95 %)",
                f(r, "predicted"),
                f(r, "low"),
                f(r, "high"),
                f(r, "measured"),
                f(r, "measured_ci95"),
            ));
        } else if r["inside"].as_bool() == Some(true) {
            inside.push(name);
        }
    }
    let level = format!(
        "each check at {:.2} %, {:.0} % family-wise over {}",
        100.0 * v["per_check_level"].as_f64().unwrap_or(f64::NAN),
        100.0 * v["family_wise_level"].as_f64().unwrap_or(f64::NAN),
        v["family_size"].as_u64().unwrap_or(0)
    );
    let mut out = String::new();
    if !outside.is_empty() {
        out.push_str(&format!(
            "  PREDICTION OUTSIDE the measured interval ({level}): {}\n",
            outside.join("; ")
        ));
    } else if !inside.is_empty() {
        out.push_str(&format!(
            "  prediction: {} inside the measured intervals joined with the prediction's ± ({level})\n",
            inside.join(", ")
        ));
    }
    if !unchecked.is_empty() {
        out.push_str(&format!(
            "  prediction NOT CHECKED: {}\n",
            unchecked.join("; ")
        ));
    }
    out
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
