//! What one round of the request loop asks the selection MDP, and how it
//! judges the answer: the selection (exact LP or certified), the edge of
//! what the MDP offers, a prediction's slack against the goal, and the
//! request moved by a round's measured gap.

use super::{Asked, Goal, TOLERANCE};
use crate::certify::intervals::IntervalMdp;
use crate::certify::robust::Certified;
use crate::certify::select::certified_strategy;
use crate::mdp::{CostModel, Mdp};
use crate::pareto::optimal::{LpRequest, optimal_strategy};
use crate::pareto::policy::{Objectives, RandomisedPolicy};
use crate::pareto::select::SelectError;
use crate::predict::PredictError;

/// A strategy selected on the MDP, before its rebuilds.
#[derive(Clone)]
pub(super) struct Candidate {
    pub omega: RandomisedPolicy,
    pub selection_time: Objectives,
}

/// The MDP's answer to `asked`: `Ok(Err(_))` when the request is infeasible
/// on it, `Err(_)` when the selection itself failed.
pub(super) fn select(
    mdp: &Mdp,
    cost: CostModel,
    asked: Asked,
    certified: Option<&IntervalMdp>,
) -> Result<Result<Candidate, PredictError>, PredictError> {
    match (asked, certified) {
        (
            Asked::MinTarget {
                min_target,
                max_collision,
            },
            Some(im),
        ) => match certified_strategy(mdp, im, cost, min_target.min(1.0), max_collision) {
            Ok(c) => Ok(Ok(Candidate {
                omega: c.strategy.policy,
                selection_time: c.strategy.predicted,
            })),
            Err(e @ crate::certify::CertifyError::Infeasible { .. }) => Ok(Err(e.into())),
            Err(e) => Err(e.into()),
        },
        (asked, _) => {
            let request = match asked {
                Asked::MinTarget {
                    min_target,
                    max_collision,
                } => LpRequest::MinEnergy {
                    min_target: min_target.min(1.0),
                    max_collision: max_collision.map(|c| c.max(0.0)),
                },
                Asked::MaxEnergy { max_energy } => LpRequest::MaxTarget {
                    max_energy: max_energy.max(0.0),
                },
            };
            match optimal_strategy(mdp, cost, request) {
                Ok(o) => Ok(Ok(Candidate {
                    omega: o.policy,
                    selection_time: o.predicted,
                })),
                Err(e @ SelectError::Infeasible { .. }) => Ok(Err(e.into())),
                Err(e) => Err(e.into()),
            }
        }
    }
}

/// The policy that transmits most: at every state the choice with the
/// smallest threshold δ.
pub(super) fn most_transmitting(mdp: &Mdp) -> RandomisedPolicy {
    mdp.states
        .iter()
        .map(|st| {
            let delta = |a: u16| mdp.deltas.get(a as usize).copied().unwrap_or(f64::INFINITY);
            let least = (0..st.choices.len())
                .min_by(|&i, &j| {
                    delta(st.choices[i].action).total_cmp(&delta(st.choices[j].action))
                })
                .unwrap_or(0);
            (0..st.choices.len())
                .map(|i| if i == least { 1.0 } else { 0.0 })
                .collect()
        })
        .collect()
}

/// A feasible request of the kind of `asked` to bisect from: no P_tar bound
/// (its P_coll bound kept), or the MDP's least energy (a hair above).
fn loosest(mdp: &Mdp, cost: CostModel, asked: Asked) -> Asked {
    match asked {
        Asked::MinTarget { max_collision, .. } => Asked::MinTarget {
            min_target: 0.0,
            max_collision,
        },
        Asked::MaxEnergy { max_energy } => {
            let least = LpRequest::MinEnergy {
                min_target: 0.0,
                max_collision: None,
            };
            let e = optimal_strategy(mdp, cost, least).map_or(max_energy, |o| o.predicted.energy);
            Asked::MaxEnergy {
                max_energy: e * (1.0 + 1e-9) + 1e-12,
            }
        }
    }
}

/// Bisection steps towards the edge of what the MDP offers.
const EDGE_STEPS: usize = 30;

/// The most the MDP offers on the segment from `last` (a feasible request;
/// `None`: the user's own request, whose loosest form is used) towards the
/// infeasible `asked`: the request at the edge and its candidate, or `None`
/// when nothing on the segment is feasible.
pub(super) fn edge(
    mdp: &Mdp,
    cost: CostModel,
    last: Option<Asked>,
    asked: Asked,
    certified: Option<&IntervalMdp>,
) -> Result<Option<(Asked, Candidate, Asked)>, PredictError> {
    let from = match last {
        Some(a) => a,
        None => loosest(mdp, cost, asked),
    };
    if last.is_none() && select(mdp, cost, from, certified)?.is_err() {
        return Ok(None);
    }
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut found = None;
    for _ in 0..EDGE_STEPS {
        let mid = 0.5 * (lo + hi);
        match select(mdp, cost, from.towards(asked, mid), certified)? {
            Ok(c) => {
                lo = mid;
                found = Some(c);
            }
            Err(_) => hi = mid,
        }
    }
    Ok(found.map(|c| (from.towards(asked, lo), c, from)))
}

/// How far a prediction is from missing the request: ≥ 0 meets it (each
/// bound on the right side of the request, or short of it by at most
/// `allowance`); the least of its bounds' slacks (energy relative to the
/// request). The loop's rule is `allowance` zero: the prediction itself meets
/// the request, so a wider interval buys no room.
pub(super) fn slack(
    goal: Goal,
    q: &Objectives,
    allowance: &Objectives,
    cert: Option<&Certified>,
) -> f64 {
    let h = allowance;
    match (goal, cert) {
        (
            Goal::MinTarget {
                min_target,
                max_collision,
            },
            Some(c),
        ) => (c.p_target_low - min_target)
            .min(max_collision.map_or(f64::INFINITY, |m| m - c.p_collision_high)),
        (
            Goal::MinTarget {
                min_target,
                max_collision,
            },
            None,
        ) => (q.p_target + h.p_target - min_target)
            .min(max_collision.map_or(f64::INFINITY, |m| m - (q.p_collision - h.p_collision))),
        (Goal::MaxEnergy { max_energy }, _) => {
            (max_energy - (q.energy - h.energy)) / max_energy.abs().max(1e-12)
        }
    }
}

/// Which way a round's request moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Move {
    /// Only the bounds the round missed, by their gap (towards meeting).
    Tighten,
    /// Every bound by its gap, either way (towards the edge of meeting,
    /// from a round that met with room to spare).
    Aim,
}

/// The request to the MDP moved by the gaps between `goal` and what the
/// round measured (point values plus `TOLERANCE` of their half-widths `h`,
/// or the certified bounds): each bound aims where the next prediction
/// lands inside the request by `TOLERANCE · h`.
pub(super) fn moved(
    goal: Goal,
    asked: Asked,
    q: &Objectives,
    h: &Objectives,
    cert: Option<&Certified>,
    how: Move,
) -> Asked {
    // The tightening part of a gap (all of it when aiming).
    let part = |gap: f64| match how {
        Move::Tighten => gap.max(0.0),
        Move::Aim => gap,
    };
    match (goal, asked) {
        (
            Goal::MinTarget {
                min_target,
                max_collision,
            },
            Asked::MinTarget {
                min_target: t,
                max_collision: c,
            },
        ) => {
            let (got_t, got_c) = match cert {
                Some(x) => (x.p_target_low, x.p_collision_high),
                None => (
                    q.p_target - TOLERANCE * h.p_target,
                    q.p_collision + TOLERANCE * h.p_collision,
                ),
            };
            Asked::MinTarget {
                min_target: (t + part(min_target - got_t)).clamp(0.0, 1.0),
                max_collision: c
                    .zip(max_collision)
                    .map(|(c, m)| (c - part(got_c - m)).clamp(0.0, 1.0)),
            }
        }
        (Goal::MaxEnergy { max_energy }, Asked::MaxEnergy { max_energy: e }) => Asked::MaxEnergy {
            max_energy: (e - part(q.energy + TOLERANCE * h.energy - max_energy)).max(0.0),
        },
        (_, a) => a,
    }
}
