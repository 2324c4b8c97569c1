//! The certified front beside the nominal one (`front.json` field `certified`,
//! docs/MODEL.md §4.1): every nominal vertex's policy with its certified
//! bounds (upper energy, upper P_coll, lower P_tar) and its cross-fitted
//! values; `dominated` marks the points another certified point beats in all
//! three. It is conservative: a strategy designed for certification (e.g.
//! `etp strategy --confidence`) can lie below it.

use super::CertifyError;
use super::crossfit::crossfit;
use super::intervals::interval_mdp;
use super::robust::certify;
use crate::mdp::{CostModel, Mdp};
use crate::pareto::ParetoFront;
use crate::pareto::policy::as_randomised;
// The types live beside `ParetoFront`, which holds them, so that `pareto`
// needs nothing of `certify` (no module cycle).
pub use crate::pareto::{CertifiedFront, CertifiedPoint};

/// Default confidence of the certified front.
pub const FRONT_CONFIDENCE: f64 = 0.95;

/// Certify every vertex of `front` (built on `mdp`) at `confidence`.
pub fn certified_front(
    mdp: &Mdp,
    front: &ParetoFront,
    cost: CostModel,
    confidence: f64,
) -> Result<CertifiedFront, CertifyError> {
    let im = interval_mdp(mdp, confidence, cost)?;
    let mut points: Vec<CertifiedPoint> = front
        .vertices
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let policy = as_randomised(mdp, &v.policy);
            let c = certify(mdp, &im, &policy);
            CertifiedPoint {
                vertex: k,
                p_target_low: c.p_target_low,
                p_collision_high: c.p_collision_high,
                energy_high: c.energy_high,
                crossfit: crossfit(mdp, &policy, cost).map(|x| x.objectives),
                dominated: false,
            }
        })
        .collect();
    let key = |p: &CertifiedPoint| [p.energy_high, p.p_collision_high, -p.p_target_low];
    let flags: Vec<bool> = points
        .iter()
        .map(|p| {
            let a = key(p);
            points.iter().any(|q| {
                let b = key(q);
                (0..3).all(|i| b[i] <= a[i]) && (0..3).any(|i| b[i] < a[i])
            })
        })
        .collect();
    for (p, d) in points.iter_mut().zip(flags) {
        p.dominated = d;
    }
    Ok(CertifiedFront {
        confidence,
        union_events: im.events,
        per_event_level: im.per_event,
        points,
    })
}
