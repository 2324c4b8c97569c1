//! Predictions that hold (docs/MODEL.md §4.1), as `etp strategy` and
//! `etp validate` report them: selection-time value, cross-fitted value and
//! their gap (the optimiser's bias), and certified bounds.

use crate::progress;
use anyhow::{Context, Result};
use etp_shared::stats::Z95;
use etp_shared::strategy::{
    AggregationCheck, CertifiedPrediction, Prediction, PredictionCi95, SimulatedValue, Strategy,
};
use etp_synthesis::certify::crossfit::CrossFit;
use etp_synthesis::certify::robust::Certified;
use etp_synthesis::pareto::policy::Objectives;
use etp_synthesis::simulate::SimulationSummary;
use serde_json::json;

/// What the certified bounds cover, in every report.
pub const SCOPE: &str = "certified bounds cover the sampling error of the abstraction's \
     transition and energy estimates (at the stated confidence, union bound over the whole MDP), \
     not the aggregation of beliefs into regions: see the measured aggregation error, and \
     `etp strategy --cover-aggregation`";

/// What widened bounds cover (`etp strategy --cover-aggregation`).
pub const SCOPE_COVERED: &str = "certified bounds cover the sampling error of the abstraction's \
     estimates and the aggregation error measured at selection time (each part at (1 + level)/2, \
     union bound): they hold for the simulated loop, within the check's own sampling error";

/// Seed of the selection-time aggregation check: not `etp validate`'s
/// default (0), so a default validation is an independent measurement.
pub const AGGREGATION_CHECK_SEED: u64 = 0x00A6_6C4E;

/// Default episodes of the selection-time check: about ±0.9 pt (95 %) on a
/// probability near 0.9, in well under a second for n ≤ 6.
pub const AGGREGATION_CHECK_EPISODES: u64 = 4000;

/// The selection-time aggregation check: `strategy` simulated in-process
/// under its own channel, against its cross-fitted value (its selection-time
/// one without a held-out sample).
pub fn aggregation_check(
    strategy: &Strategy,
    episodes: u64,
    quiet: bool,
) -> Result<AggregationCheck> {
    let scenario = strategy
        .scenario()
        .context("the aggregation check needs the strategy's scenario")?;
    let pb = progress::bar(episodes, "aggregation check", quiet);
    let sum = etp_synthesis::validate::simulate_strategy(
        &scenario,
        strategy,
        episodes,
        AGGREGATION_CHECK_SEED,
        &|k| pb.inc(k),
    )
    .summary();
    pb.finish_and_clear();
    Ok(check_of(strategy, &sum, AGGREGATION_CHECK_SEED))
}

/// A simulation of `strategy` (`seed`) as an aggregation check of it.
pub fn check_of(strategy: &Strategy, sum: &SimulationSummary, seed: u64) -> AggregationCheck {
    AggregationCheck {
        episodes: sum.episodes,
        seed,
        reference: strategy.crossfit.unwrap_or(strategy.predicted),
        reference_ci95: strategy.crossfit.and(strategy.crossfit_ci95),
        simulated: SimulatedValue {
            p_target: sum.p_target.value,
            p_target_ci95: sum.p_target.ci95,
            p_collision: sum.p_collision.value,
            p_collision_ci95: sum.p_collision.ci95,
            energy_mean: sum.energy_mean.value,
            energy_mean_ci95: sum.energy_mean.ci95,
        },
    }
}

/// JSON of an aggregation check: what was compared, the error and whether
/// the simulation resolves it.
pub fn aggregation_json(c: &AggregationCheck, reference: &str) -> serde_json::Value {
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

fn ci95_json(c: &PredictionCi95) -> serde_json::Value {
    json!({"p_target": c.p_target, "p_collision": c.p_collision, "energy_mean": c.energy_mean})
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
        "  aggregation error ({reference} − simulated, {} episodes {when}, seed {}): \
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

pub fn reference_name(s: &Strategy) -> &'static str {
    if s.crossfit.is_some() {
        "cross-fitted"
    } else {
        "selection-time"
    }
}

pub fn prediction(o: &Objectives) -> Prediction {
    Prediction {
        p_target: o.p_target,
        p_collision: o.p_collision,
        p_free: (1.0 - o.p_target - o.p_collision).max(0.0),
        energy_mean: o.energy,
    }
}

pub fn certified_prediction(c: &Certified, confidence: f64) -> CertifiedPrediction {
    CertifiedPrediction {
        confidence,
        p_target_low: c.p_target_low,
        p_collision_high: c.p_collision_high,
        energy_high: c.energy_high,
        covers_aggregation: false,
    }
}

/// Cross-fit and certified bounds stored in a strategy file.
pub fn attach(s: &mut Strategy, crossfit: Option<&CrossFit>, certified: &CertifiedPrediction) {
    s.crossfit = crossfit.map(|c| prediction(&c.objectives));
    s.crossfit_ci95 = crossfit.map(|c| {
        let e = &c.standard_error;
        PredictionCi95 {
            p_target: Z95 * e.p_target,
            p_collision: Z95 * e.p_collision,
            energy_mean: Z95 * e.energy,
        }
    });
    s.certified = Some(*certified);
}

/// JSON of the three kinds of prediction of a strategy file.
pub fn json_of(s: &Strategy) -> serde_json::Value {
    let p = &s.predicted;
    json!({
        "selection_time": {"p_target": p.p_target, "p_collision": p.p_collision, "energy_mean": p.energy_mean},
        "crossfit": s.crossfit.map(|c| json!({
            "p_target": c.p_target, "p_collision": c.p_collision, "energy_mean": c.energy_mean,
            "ci95": s.crossfit_ci95.map(|r| ci95_json(&r))})),
        "optimizer_bias": s.crossfit.map(|c| json!({
            "p_target": p.p_target - c.p_target,
            "p_collision": p.p_collision - c.p_collision,
            "energy_mean": p.energy_mean - c.energy_mean})),
        "certified": s.certified.map(|c| json!({
            "confidence": c.confidence, "p_target_low": c.p_target_low,
            "p_collision_high": c.p_collision_high, "energy_high": c.energy_high,
            "covers_aggregation": c.covers_aggregation,
            "scope": if c.covers_aggregation { SCOPE_COVERED } else { SCOPE }})),
        "aggregation": s.aggregation.map(|c| aggregation_json(&c, reference_name(s))),
    })
}

/// What the cross-fitted ± of [`text_of`] is, by default.
pub const HELD_OUT_CI: &str = "the held-out sample's own error";

/// Text rows: selection-time, cross-fitted with the bias, certified.
pub fn text_of(s: &Strategy) -> String {
    text_with_ci(s, HELD_OUT_CI)
}

/// [`text_of`], saying what its cross-fitted ± is (`ci`).
pub fn text_with_ci(s: &Strategy, ci: &str) -> String {
    let p = &s.predicted;
    let mut o = format!(
        "  selection-time  P_tar {:.6}  P_coll {:.6}  energy {:.4}\n",
        p.p_target, p.p_collision, p.energy_mean
    );
    match &s.crossfit {
        Some(c) => o.push_str(&format!(
            "  cross-fitted    P_tar {:.6}  P_coll {:.6}  energy {:.4}   (held-out transitions)\n\
             \x20 optimizer bias  P_tar {:+.4} pt  P_coll {:+.4} pt  energy {:+.4}   (selection-time − cross-fitted)\n",
            c.p_target,
            c.p_collision,
            c.energy_mean,
            100.0 * (p.p_target - c.p_target),
            100.0 * (p.p_collision - c.p_collision),
            p.energy_mean - c.energy_mean
        )),
        None => o.push_str(
            "  cross-fitted    n/a (mdp.bin has no held-out sample: synthesize with --holdout-samples > 0)\n",
        ),
    }
    if let (Some(c), Some(r)) = (&s.crossfit, &s.crossfit_ci95) {
        o.push_str(&format!(
            "  its sampling    P_tar ±{:.2} pt  P_coll ±{:.2} pt  energy ±{:.2} %   (95 %, {ci})\n",
            100.0 * r.p_target,
            100.0 * r.p_collision,
            if c.energy_mean != 0.0 {
                100.0 * r.energy_mean / c.energy_mean
            } else {
                0.0
            },
        ));
    }
    if let Some(c) = &s.certified {
        o.push_str(&format!(
            "  certified {:.0} %  P_tar ≥ {:.6}  P_coll ≤ {:.6}  energy ≤ {:.4}   (P_tar gap {:.4} pt)\n\
             \x20   ({})\n",
            100.0 * c.confidence,
            c.p_target_low,
            c.p_collision_high,
            c.energy_high,
            100.0 * (p.p_target - c.p_target_low),
            if c.covers_aggregation {
                SCOPE_COVERED
            } else {
                SCOPE
            },
        ));
    }
    if let Some(c) = &s.aggregation {
        o.push_str(&aggregation_text(c, reference_name(s), "at selection"));
    }
    o
}
