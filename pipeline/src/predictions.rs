//! A strategy's predictions as `etp strategy` and `etp validate` report them
//! (docs/MODEL.md §4.1, §7.4): first the one prediction etp stands by
//! (`predicted` with its ±, from the strategy's on-policy rebuilds), its
//! certified bounds and the selection-time aggregation check; then, under
//! `diagnostics`, the values that only explain it (selection-time and
//! cross-fitted on the selection MDP — biased —, each rebuild, the rounds of
//! the request loop).

use crate::error::{Context, Result};
use crate::progress::Progress;
use etp_shared::stats::verdict::{Check, Family, Measured, Outcomes, prediction_checks};
use etp_shared::strategy::{
    AggregationCheck, CertifiedPrediction, Prediction, PredictionCi95, SimulatedValue, Strategy,
};
use etp_synthesis::exec::Executor;
use etp_synthesis::simulate::SimulationSummary;
use serde_json::{Value, json};

/// What certified bounds on an on-policy rebuild cover.
pub const SCOPE_ON_POLICY: &str = "certified bounds of the strategy's first on-policy rebuild: \
     they cover that rebuild's sampling error at the stated confidence (union bound over its \
     MDP) and, its pools being the strategy's own beliefs, the aggregation error of the strategy \
     that runs";

/// What certified bounds on the selection MDP cover (`--quick`, old files).
pub const SCOPE_SELECTION: &str = "certified bounds on the selection MDP: they cover the \
     sampling error of the abstraction's estimates, not the aggregation of other strategies' \
     beliefs into its regions (biased for this strategy)";

/// Seed of the selection-time aggregation check: not `etp validate`'s
/// default (0), so a default validation is an independent measurement.
pub const AGGREGATION_CHECK_SEED: u64 = 0x00A6_6C4E;

/// Default episodes of the selection-time check: about ±0.9 pt (95 %) on a
/// probability near 0.9, in well under a second for n ≤ 6.
pub const AGGREGATION_CHECK_EPISODES: u64 = 4000;

/// What the aggregation check and `validate` compare a simulation with:
/// the prediction etp stands by, or for a `--quick` strategy its
/// cross-fitted (else selection-time) value on the selection MDP, named.
pub fn reference(s: &Strategy) -> Option<(Prediction, Option<PredictionCi95>, &'static str)> {
    if let Some(p) = s.predictions.predicted {
        return Some((p, s.predictions.predicted_ci95, "predicted"));
    }
    let sel = s.predictions.diagnostics.as_ref()?.selection;
    match (sel.crossfit, sel.selection_time) {
        (Some(c), _) => Some((
            c,
            sel.crossfit_ci95,
            "cross-fitted on the selection MDP (biased)",
        )),
        (None, Some(t)) => Some((t, None, "selection-time (biased)")),
        (None, None) => None,
    }
}

/// The selection-time aggregation check: `strategy` simulated in-process
/// under its own channel, against [`reference()`].
pub fn aggregation_check(
    strategy: &Strategy,
    episodes: u64,
    progress: &Progress,
    exec: &Executor,
) -> Result<Option<AggregationCheck>> {
    let scenario = strategy
        .policy
        .scenario()
        .in_strategy("the aggregation check needs the strategy's scenario")?;
    let pb = progress.bar(exec, episodes, "aggregation check");
    let sum = etp_synthesis::validate::simulate_strategy(
        &scenario,
        &strategy.policy,
        episodes,
        AGGREGATION_CHECK_SEED,
        &exec.work(|k| pb.inc(k)),
    )?
    .summary();
    pb.finish_and_clear();
    Ok(check_of(strategy, &sum, AGGREGATION_CHECK_SEED))
}

/// A simulation of `strategy` (`seed`) as an aggregation check of it.
pub fn check_of(
    strategy: &Strategy,
    sum: &SimulationSummary,
    seed: u64,
) -> Option<AggregationCheck> {
    let (reference, reference_ci95, _) = reference(strategy)?;
    Some(AggregationCheck {
        episodes: sum.episodes,
        seed,
        reference,
        reference_ci95,
        simulated: SimulatedValue {
            p_target: sum.p_target.value,
            p_target_ci95: sum.p_target.ci95,
            p_collision: sum.p_collision.value,
            p_collision_ci95: sum.p_collision.ci95,
            energy_mean: sum.energy_mean.value,
            energy_mean_ci95: sum.energy_mean.ci95,
        },
    })
}

/// JSON of an aggregation check: what was compared, the error and whether
/// the simulation resolves it.
pub fn aggregation_json(c: &AggregationCheck, reference: &str) -> Value {
    let e = c.error();
    let s = &c.simulated;
    let [t, k, en] = c.resolved();
    let w = c.error_ci95();
    json!({
        "episodes": c.episodes, "seed": c.seed, "reference": reference,
        "simulated": {"p_target": s.p_target, "p_target_ci95": s.p_target_ci95,
            "p_collision": s.p_collision, "p_collision_ci95": s.p_collision_ci95,
            "energy_mean": s.energy_mean, "energy_mean_ci95": s.energy_mean_ci95},
        "reference_ci95": c.reference_ci95.map(|r| ci95_json(&r)),
        "error": {"p_target": e.p_target, "p_collision": e.p_collision, "energy_mean": e.energy_mean},
        "error_ci95": ci95_json(&w),
        "resolved": {"p_target": t, "p_collision": k, "energy_mean": en},
    })
}

pub fn ci95_json(c: &PredictionCi95) -> Value {
    json!({"p_target": c.p_target, "p_collision": c.p_collision, "energy_mean": c.energy_mean})
}

pub fn prediction_json(p: &Prediction) -> Value {
    json!({"p_target": p.p_target, "p_collision": p.p_collision, "p_free": p.p_free,
        "energy_mean": p.energy_mean})
}

/// One text line of an aggregation check.
pub fn aggregation_text(c: &AggregationCheck, reference: &str, when: &str) -> String {
    let e = c.error();
    let s = &c.simulated;
    let w = c.error_ci95();
    let rel = |x: f64| {
        if s.energy_mean != 0.0 {
            100.0 * x / s.energy_mean
        } else {
            0.0
        }
    };
    let both = if c.reference_ci95.is_some() {
        "both sampling errors"
    } else {
        "the simulation's sampling error"
    };
    format!(
        "  {reference} − simulated ({} episodes {when}, seed {}): \
         P_tar {:+.2} pt (±{:.2})  P_coll {:+.2} pt (±{:.2})  energy {:+.2} % (±{:.2})   (± 95 %, {both})\n",
        c.episodes,
        c.seed,
        100.0 * e.p_target,
        100.0 * w.p_target,
        100.0 * e.p_collision,
        100.0 * w.p_collision,
        rel(e.energy_mean),
        rel(w.energy_mean),
    )
}

/// The name of [`reference()`] for `s`.
pub fn reference_name(s: &Strategy) -> &'static str {
    reference(s).map_or("none", |r| r.2)
}

fn certified_json(c: &CertifiedPrediction) -> Value {
    json!({
        "confidence": c.confidence, "p_target_low": c.p_target_low,
        "p_collision_high": c.p_collision_high, "energy_high": c.energy_high,
        "covers_aggregation": c.covers_aggregation,
        "scope": if c.covers_aggregation { SCOPE_ON_POLICY } else { SCOPE_SELECTION }})
}

/// The predictions of a strategy file as every `--json` states them:
/// `predicted` (null for `--quick`), `predicted_ci95`, `prediction_basis`,
/// `certified`, `aggregation` and `diagnostics`.
pub fn json_fields(s: &Strategy) -> serde_json::Map<String, Value> {
    let mut m = serde_json::Map::new();
    m.insert(
        "predicted".into(),
        s.predictions
            .predicted
            .as_ref()
            .map_or(Value::Null, prediction_json),
    );
    m.insert(
        "predicted_ci95".into(),
        s.predictions
            .predicted_ci95
            .as_ref()
            .map_or(Value::Null, ci95_json),
    );
    m.insert("prediction_basis".into(), json!(basis_text(s)));
    m.insert(
        "certified".into(),
        s.predictions
            .certified
            .as_ref()
            .map_or(Value::Null, certified_json),
    );
    m.insert(
        "aggregation".into(),
        s.predictions
            .aggregation
            .as_ref()
            .map_or(Value::Null, |c| aggregation_json(c, reference_name(s))),
    );
    m.insert("diagnostics".into(), diagnostics_json(s));
    m
}

/// `prediction_basis`, or what a strategy without a prediction is.
pub fn basis_text(s: &Strategy) -> String {
    if s.predictions.predicted.is_none() {
        QUICK.into()
    } else if s.predictions.prediction_basis.is_empty() {
        "not stated (a strategy file without `prediction_basis`)".into()
    } else {
        s.predictions.prediction_basis.clone()
    }
}

/// What a `--quick` strategy is.
pub const QUICK: &str = "none: a --quick strategy (its values on the selection MDP are biased \
     and only diagnostics; predict it with `etp strategy evaluate`)";

/// `diagnostics` of a strategy file as JSON (null without).
pub fn diagnostics_json(s: &Strategy) -> Value {
    let Some(d) = &s.predictions.diagnostics else {
        return Value::Null;
    };
    let sel = &d.selection;
    json!({
        "selection_time": sel.selection_time.as_ref().map(prediction_json),
        "crossfit": sel.crossfit.as_ref().map(prediction_json),
        "crossfit_ci95": sel.crossfit_ci95.as_ref().map(ci95_json),
        "optimizer_bias": sel.selection_time.zip(sel.crossfit).map(|(p, c)| json!({
            "p_target": p.p_target - c.p_target,
            "p_collision": p.p_collision - c.p_collision,
            "energy_mean": p.energy_mean - c.energy_mean})),
        "certified_selection_mdp": sel.certified.as_ref().map(certified_json),
        "rebuilds": d.rebuilds.iter().map(|r| json!({
            "seed": r.seed,
            "selection_time": prediction_json(&r.selection_time),
            "crossfit": r.crossfit.as_ref().map(prediction_json),
            "crossfit_ci95": r.crossfit_ci95.as_ref().map(ci95_json),
        })).collect::<Vec<_>>(),
        "rounds": d.rounds.iter().map(|r| json!({
            "asked_p_target": r.asked_p_target, "asked_p_collision": r.asked_p_collision,
            "asked_energy": r.asked_energy,
            "selection_time": prediction_json(&r.selection_time),
            "predicted": prediction_json(&r.predicted),
            "predicted_ci95": ci95_json(&r.predicted_ci95),
            "rebuilds": r.rebuilds, "meets": r.meets,
        })).collect::<Vec<_>>(),
    })
}

fn prob(x: f64) -> String {
    format!("{:.4}", x)
}

/// The text report of a strategy's predictions: the one etp stands by
/// first, then its bounds and check, then the diagnostics, labelled.
pub fn text_of(s: &Strategy) -> String {
    let mut o = String::new();
    match (&s.predictions.predicted, &s.predictions.predicted_ci95) {
        (Some(p), Some(h)) => o.push_str(&format!(
            "  predicted       P_tar {} ± {}  P_coll {} ± {}  energy {:.3} ± {:.3}   (95 %)\n",
            prob(p.p_target),
            prob(h.p_target),
            prob(p.p_collision),
            prob(h.p_collision),
            p.energy_mean,
            h.energy_mean
        )),
        (Some(p), None) => o.push_str(&format!(
            "  predicted       P_tar {}  P_coll {}  energy {:.3}\n",
            prob(p.p_target),
            prob(p.p_collision),
            p.energy_mean
        )),
        (None, _) => {}
    }
    o.push_str(&format!("    ({})\n", basis_text(s)));
    if let Some(c) = &s.predictions.certified {
        o.push_str(&format!(
            "  certified {:.0} %  P_tar ≥ {:.6}  P_coll ≤ {:.6}  energy ≤ {:.4}\n    ({})\n",
            100.0 * c.confidence,
            c.p_target_low,
            c.p_collision_high,
            c.energy_high,
            if c.covers_aggregation {
                SCOPE_ON_POLICY
            } else {
                SCOPE_SELECTION
            },
        ));
    }
    if let Some(c) = &s.predictions.aggregation {
        o.push_str(&aggregation_text(c, reference_name(s), "at selection"));
    }
    o.push_str(&diagnostics_text(s));
    o
}

/// The diagnostics, each line saying what it is.
pub fn diagnostics_text(s: &Strategy) -> String {
    let Some(d) = &s.predictions.diagnostics else {
        return String::new();
    };
    let mut o = String::from(
        "  diagnostics (explain the prediction; biased where said, never to be used as it):\n",
    );
    let sel = &d.selection;
    if let Some(p) = &sel.selection_time {
        o.push_str(&format!(
            "    selection-time on the selection MDP   P_tar {}  P_coll {}  energy {:.3}   (biased: the optimiser's pick, other strategies' beliefs in the pools)\n",
            prob(p.p_target),
            prob(p.p_collision),
            p.energy_mean
        ));
    }
    if let Some(c) = &sel.crossfit {
        let h = sel.crossfit_ci95.unwrap_or_default();
        o.push_str(&format!(
            "    cross-fitted on the selection MDP     P_tar {} ± {}  P_coll {} ± {}  energy {:.3}   (held-out transitions; biased by aggregation)\n",
            prob(c.p_target),
            prob(h.p_target),
            prob(c.p_collision),
            prob(h.p_collision),
            c.energy_mean
        ));
    }
    if let Some(c) = &sel.certified {
        o.push_str(&format!(
            "    certified on the selection MDP        P_tar ≥ {:.6}  P_coll ≤ {:.6}  energy ≤ {:.4}   ({:.0} %; sampling error only)\n",
            c.p_target_low,
            c.p_collision_high,
            c.energy_high,
            100.0 * c.confidence
        ));
    }
    if !d.rebuilds.is_empty() {
        let each: Vec<String> = d
            .rebuilds
            .iter()
            .map(|r| prob(r.crossfit.unwrap_or(r.selection_time).p_target))
            .collect();
        o.push_str(&format!(
            "    each rebuild's P_tar (seeds {}…{})   {}\n",
            d.rebuilds.first().map_or(0, |r| r.seed),
            d.rebuilds.last().map_or(0, |r| r.seed),
            each.join(", ")
        ));
    }
    for (k, r) in d.rounds.iter().enumerate() {
        let asked = match (r.asked_p_target, r.asked_p_collision, r.asked_energy) {
            _ if r.most_transmitting => {
                "nothing: the policy that transmits most (smallest δ everywhere)".into()
            }
            (Some(t), Some(c), _) => format!("the MDP P_tar ≥ {t:.6}, P_coll ≤ {c:.6}"),
            (Some(t), None, _) => format!("the MDP P_tar ≥ {t:.6}"),
            (None, _, Some(e)) => format!("the MDP energy ≤ {e:.4}"),
            _ => "—".into(),
        };
        o.push_str(&format!(
            "    round {k}: asked {asked} → selection-time P_tar {} → predicted {} ± {} P_coll {} energy {:.3} ({} rebuild{}) {}\n",
            prob(r.selection_time.p_target),
            prob(r.predicted.p_target),
            prob(r.predicted_ci95.p_target),
            prob(r.predicted.p_collision),
            r.predicted.energy_mean,
            r.rebuilds,
            if r.rebuilds == 1 { "" } else { "s" },
            if r.meets { "meets the request" } else { "misses" }
        ));
    }
    o
}

/// Every prediction the strategy file stands by against the simulation,
/// as one family at 95 % family-wise (`etp_shared::stats::verdict`, THE
/// verdict of `run` and `replay` too): `predicted` (P_tar, P_coll, energy)
/// within the simulation's interval joined with its own ±; the certified
/// bounds on the right side of the simulation's interval; each check at
/// 1 − 0.05/m (Bonferroni over the m checks). The diagnostics are
/// reported, never checked. A `--quick` strategy stands by nothing: no
/// check.
pub fn checks(strategy: &Strategy, sum: &SimulationSummary) -> (Family, Vec<Check>) {
    prediction_checks(
        strategy.predictions.predicted.as_ref(),
        strategy.predictions.predicted_ci95.as_ref(),
        strategy.predictions.certified.as_ref(),
        &outcomes_of(sum),
    )
}

/// A simulation's P_tar, P_coll (counts of its episodes) and energy per
/// episode, as the verdict measures them.
pub fn outcomes_of(sum: &SimulationSummary) -> Outcomes {
    let n = sum.episodes;
    // The proportion times the episodes is the count, exactly.
    let count = |p: f64| Measured::Proportion {
        k: (p * n as f64).round() as u64,
        n,
    };
    Outcomes {
        p_target: Some(count(sum.p_target.value)),
        p_collision: Some(count(sum.p_collision.value)),
        energy: Some(Measured::from_estimate(sum.energy_mean)),
    }
}
