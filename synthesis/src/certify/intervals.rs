//! The interval MDP of docs/MODEL.md §4.1: per choice, from its sample counts,
//! a Clopper–Pearson interval per observed outcome, a one-sided bound on the
//! mass of outcomes never observed, and an empirical-Bernstein upper bound on
//! the mean segment energy — all at one per-event level `α / events`, so that by
//! the union bound every interval of the whole MDP holds at once with
//! probability ≥ 1 − α.

use super::CertifyError;
use super::beta::{clopper_pearson, zero_count_upper};
use crate::mdp::{CostModel, Mdp, Next};

/// The intervals of one choice.
#[derive(Debug, Clone, PartialEq)]
pub struct ChoiceIntervals {
    /// `(next, low, high)` per observed outcome, in the choice's order.
    pub outcomes: Vec<(Next, f64, f64)>,
    /// Upper bound on the total probability of outcomes never observed
    /// (treated as the worst possible successor).
    pub unseen_high: f64,
    /// Upper bound on the mean segment energy.
    pub cost_high: f64,
}

/// The whole MDP as an interval MDP at confidence `1 − alpha`.
#[derive(Debug, Clone, PartialEq)]
pub struct IntervalMdp {
    pub confidence: f64,
    pub cost: CostModel,
    /// Events the union bound runs over (intervals of the whole MDP).
    pub events: u64,
    /// The error level of each event: `(1 − confidence) / events`.
    pub per_event: f64,
    /// Per state, per choice.
    pub choices: Vec<Vec<ChoiceIntervals>>,
    /// `energy_tail[i]`: an a-priori bound on the energy of decision points
    /// `i..` (Σ of `k_max · c_m` over those legs); the value of an unseen
    /// successor in the energy bound. One entry past the last decision point (0).
    pub energy_tail: Vec<f64>,
}

/// The events of the union bound: per choice one per observed outcome, one
/// for the unseen mass and one for the energy (times `Mdp::looks`, the sample
/// sizes a choice can have after sample allocation, in [`interval_mdp`]).
pub fn union_events(mdp: &Mdp) -> u64 {
    mdp.states
        .iter()
        .flat_map(|s| &s.choices)
        .map(|c| c.transitions.len() as u64 + 2)
        .sum()
}

/// Maurer & Pontil (2009, Thm 4) for values in `[0, range]`: with probability
/// ≥ 1 − delta the mean is ≤ the bound (capped at `range`).
pub fn empirical_bernstein_upper(mean: f64, mean_sq: f64, n: u64, range: f64, delta: f64) -> f64 {
    if n < 2 || range <= 0.0 {
        return if n == 0 { range } else { mean.min(range) };
    }
    let nf = n as f64;
    let variance = (nf / (nf - 1.0) * (mean_sq - mean * mean)).max(0.0);
    let l = (2.0 / delta).ln();
    let bound = mean + (2.0 * variance * l / nf).sqrt() + 7.0 * range * l / (3.0 * (nf - 1.0));
    bound.min(range).max(mean)
}

/// Build the interval MDP at `confidence` (in (0, 1)).
pub fn interval_mdp(
    mdp: &Mdp,
    confidence: f64,
    cost: CostModel,
) -> Result<IntervalMdp, CertifyError> {
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(CertifyError::Confidence(confidence));
    }
    let events = union_events(mdp) * u64::from(mdp.looks.max(1));
    let per_event = (1.0 - confidence) / events.max(1) as f64;
    let choices = mdp
        .states
        .iter()
        .map(|s| {
            s.choices
                .iter()
                .map(|c| {
                    let n = u64::from(c.samples);
                    ChoiceIntervals {
                        outcomes: c
                            .transitions
                            .iter()
                            .map(|t| {
                                let (lo, hi) = clopper_pearson(u64::from(t.count), n, per_event);
                                (t.next, lo, hi)
                            })
                            .collect(),
                        unseen_high: if c.unmatched > 0 {
                            clopper_pearson(u64::from(c.unmatched), n, per_event).1
                        } else {
                            zero_count_upper(n, per_event)
                        },
                        cost_high: empirical_bernstein_upper(
                            c.cost(cost),
                            c.cost_sq(cost),
                            n,
                            c.cost_range,
                            per_event,
                        ),
                    }
                })
                .collect()
        })
        .collect();
    // Per decision point the largest a-priori segment energy.
    let dps = mdp.num_decision_points();
    let global = mdp
        .states
        .iter()
        .flat_map(|s| &s.choices)
        .map(|c| c.cost_range)
        .fold(0.0_f64, f64::max);
    let mut range = vec![None::<f64>; dps];
    for s in &mdp.states {
        for c in &s.choices {
            let r = &mut range[s.decision_point as usize];
            *r = Some(r.map_or(c.cost_range, |v: f64| v.max(c.cost_range)));
        }
    }
    let mut energy_tail = vec![0.0; dps + 1];
    for i in (0..dps).rev() {
        energy_tail[i] = energy_tail[i + 1] + range[i].unwrap_or(global);
    }
    Ok(IntervalMdp {
        confidence,
        cost,
        events,
        per_event,
        choices,
        energy_tail,
    })
}
