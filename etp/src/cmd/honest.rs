//! Predictions that hold (docs/MODEL.md §4.1), as `etp strategy` and
//! `etp validate` report them: selection-time value, cross-fitted value and
//! their gap (the optimiser's bias), and certified bounds.

use etp_shared::strategy::{CertifiedPrediction, Prediction, Strategy};
use etp_synthesis::certify::crossfit::CrossFit;
use etp_synthesis::certify::robust::Certified;
use etp_synthesis::pareto::policy::Objectives;
use serde_json::json;

/// What the certified bounds cover, in every report.
pub const SCOPE: &str = "certified bounds cover the sampling error of the abstraction's \
     transition and energy estimates (at the stated confidence, union bound over the whole MDP), \
     not the aggregation of beliefs into regions; `etp validate` measures that";

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
    }
}

/// Cross-fit and certified bounds stored in a strategy file.
pub fn attach(s: &mut Strategy, crossfit: Option<&CrossFit>, certified: &CertifiedPrediction) {
    s.crossfit = crossfit.map(|c| prediction(&c.objectives));
    s.certified = Some(*certified);
}

/// JSON of the three kinds of prediction of a strategy file.
pub fn json_of(s: &Strategy) -> serde_json::Value {
    let p = &s.predicted;
    json!({
        "selection_time": {"p_target": p.p_target, "p_collision": p.p_collision, "energy_mean": p.energy_mean},
        "crossfit": s.crossfit.map(|c| json!({
            "p_target": c.p_target, "p_collision": c.p_collision, "energy_mean": c.energy_mean})),
        "optimizer_bias": s.crossfit.map(|c| json!({
            "p_target": p.p_target - c.p_target,
            "p_collision": p.p_collision - c.p_collision,
            "energy_mean": p.energy_mean - c.energy_mean})),
        "certified": s.certified.map(|c| json!({
            "confidence": c.confidence, "p_target_low": c.p_target_low,
            "p_collision_high": c.p_collision_high, "energy_high": c.energy_high,
            "scope": SCOPE})),
    })
}

/// Text rows: selection-time, cross-fitted with the bias, certified.
pub fn text_of(s: &Strategy) -> String {
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
    if let Some(c) = &s.certified {
        o.push_str(&format!(
            "  certified {:.0} %  P_tar ≥ {:.6}  P_coll ≤ {:.6}  energy ≤ {:.4}   (P_tar gap {:.4} pt)\n\
             \x20   ({SCOPE})\n",
            100.0 * c.confidence,
            c.p_target_low,
            c.p_collision_high,
            c.energy_high,
            100.0 * (p.p_target - c.p_target_low),
        ));
    }
    o
}
