//! Robust backward induction on the acyclic interval MDP (docs/MODEL.md §4.1).
//!
//! For a fixed memoryless policy and one objective, the worst transition
//! function in the product of the choices' interval sets is found state by
//! state, from the last decision point back: in each choice, start every
//! outcome at its lower bound and give the remaining mass to the outcomes in
//! order of worst successor value first, each up to its upper bound. Because
//! the uncertainty sets are independent per (state, choice) and the value is
//! monotone in the successors' values, this greedy pass is the exact minimum
//! (or maximum) over the whole interval MDP, not a relaxation.

use super::intervals::{ChoiceIntervals, IntervalMdp};
use crate::mdp::{Mdp, Next};
use crate::pareto::policy::RandomisedPolicy;
use serde::{Deserialize, Serialize};

/// Certified bounds of a strategy at the interval MDP's confidence.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Certified {
    pub p_target_low: f64,
    pub p_collision_high: f64,
    pub energy_high: f64,
}

/// Which bound to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Objective {
    /// Lower bound on P_tar (the adversary minimises).
    TargetLow,
    /// Upper bound on P_coll (the adversary maximises).
    CollisionHigh,
    /// Upper bound on the expected energy (the adversary maximises).
    EnergyHigh,
}

impl Objective {
    fn maximises(self) -> bool {
        !matches!(self, Self::TargetLow)
    }

    fn terminal(self, n: Next) -> f64 {
        match (self, n) {
            (Self::TargetLow, Next::Target) | (Self::CollisionHigh, Next::Collision) => 1.0,
            _ => 0.0,
        }
    }

    /// The value of an outcome never observed: the worst any successor can have.
    fn unseen(self, energy_tail_next: f64) -> f64 {
        match self {
            Self::TargetLow => 0.0,
            Self::CollisionHigh => 1.0,
            Self::EnergyHigh => energy_tail_next,
        }
    }
}

/// The worst expectation of `values` over `{p : lo ≤ p ≤ hi, Σ p = 1}`
/// (`worst_is_max`: the adversary maximises). `items` are (value, lo, hi).
pub fn extreme_expectation(items: &mut [(f64, f64, f64)], worst_is_max: bool) -> f64 {
    // Order: worst value first; ties by position (the caller's order).
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by(|&a, &b| {
        let c = items[a].0.total_cmp(&items[b].0);
        (if worst_is_max { c.reverse() } else { c }).then(a.cmp(&b))
    });
    let mut rest = 1.0 - items.iter().map(|i| i.1).sum::<f64>();
    let mut total: f64 = items.iter().map(|i| i.0 * i.1).sum();
    for k in order {
        if rest <= 0.0 {
            break;
        }
        let add = (items[k].2 - items[k].1).min(rest);
        total += add * items[k].0;
        rest -= add;
    }
    total
}

/// The robust value of one choice given the successors' robust values.
fn choice_bound(
    ch: &ChoiceIntervals,
    objective: Objective,
    values: &[f64],
    cost_high: f64,
    energy_tail_next: f64,
) -> f64 {
    let mut items: Vec<(f64, f64, f64)> = ch
        .outcomes
        .iter()
        .map(|&(next, lo, hi)| {
            let v = match next {
                Next::State(j) => values[j as usize],
                t => objective.terminal(t),
            };
            (v, lo, hi)
        })
        .collect();
    items.push((objective.unseen(energy_tail_next), 0.0, ch.unseen_high));
    let v = extreme_expectation(&mut items, objective.maximises());
    match objective {
        Objective::EnergyHigh => v + cost_high,
        _ => v.clamp(0.0, 1.0),
    }
}

/// The bound of `objective` for `policy` at the initial state (robust
/// backward induction, exact on the interval MDP).
pub fn robust_value(
    mdp: &Mdp,
    im: &IntervalMdp,
    policy: &RandomisedPolicy,
    objective: Objective,
) -> f64 {
    robust_values(mdp, im, policy, objective)[mdp.initial as usize]
}

/// [`robust_value`] for every state.
pub fn robust_values(
    mdp: &Mdp,
    im: &IntervalMdp,
    policy: &RandomisedPolicy,
    objective: Objective,
) -> Vec<f64> {
    let n = mdp.states.len();
    let mut values = vec![0.0; n];
    for s in (0..n).rev() {
        let tail = im.energy_tail[mdp.states[s].decision_point as usize + 1];
        let mut v = 0.0;
        for (c, &p) in policy[s].iter().enumerate() {
            if p > 0.0 {
                let ch = &im.choices[s][c];
                v += p * choice_bound(ch, objective, &values, ch.cost_high, tail);
            }
        }
        values[s] = v;
    }
    values
}

/// All three certified bounds of `policy`.
pub fn certify(mdp: &Mdp, im: &IntervalMdp, policy: &RandomisedPolicy) -> Certified {
    Certified {
        p_target_low: robust_value(mdp, im, policy, Objective::TargetLow),
        p_collision_high: robust_value(mdp, im, policy, Objective::CollisionHigh),
        energy_high: robust_value(mdp, im, policy, Objective::EnergyHigh),
    }
}

/// The largest certified P_tar lower bound over all strategies and a
/// deterministic policy attaining it: robust value iteration, `max` over
/// choices of the adversary's `min` (exact for this single objective; the
/// optimum of a max-min over rectangular sets is attained by a deterministic
/// memoryless policy on an acyclic MDP).
pub fn best_certified_target(mdp: &Mdp, im: &IntervalMdp) -> (Vec<u16>, f64) {
    let n = mdp.states.len();
    let mut values = vec![0.0; n];
    let mut policy = vec![0_u16; n];
    for s in (0..n).rev() {
        let tail = im.energy_tail[mdp.states[s].decision_point as usize + 1];
        let mut best = (f64::NEG_INFINITY, 0);
        for (c, ch) in im.choices[s].iter().enumerate() {
            let v = choice_bound(ch, Objective::TargetLow, &values, 0.0, tail);
            if v > best.0 {
                best = (v, c);
            }
        }
        values[s] = best.0.max(0.0);
        policy[s] = best.1 as u16;
    }
    (policy, values[mdp.initial as usize])
}
