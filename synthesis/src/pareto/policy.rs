//! Exact dynamic programming on the acyclic MDP: weighted backward induction,
//! policy evaluation and occupation measures.
//!
//! Objective vector of a strategy: `f = (E[energy], P_coll, 1 − P_tar)`, to be
//! minimised. Internally values are kept as (energy, P_coll, P_tar).

use crate::mdp::{CostModel, Mdp, Next};
use serde::{Deserialize, Serialize};

/// The three objectives of a strategy (docs/MODEL.md §3).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Objectives {
    pub energy: f64,
    pub p_collision: f64,
    pub p_target: f64,
}

impl Objectives {
    /// As a strategy file's prediction (P_free what is left).
    pub fn prediction(&self) -> etp_shared::strategy::Prediction {
        etp_shared::strategy::Prediction {
            p_target: self.p_target,
            p_collision: self.p_collision,
            p_free: (1.0 - self.p_target - self.p_collision).max(0.0),
            energy_mean: self.energy,
        }
    }

    /// As a strategy file's 95 % half-widths.
    pub fn ci95(&self) -> etp_shared::strategy::PredictionCi95 {
        etp_shared::strategy::PredictionCi95 {
            p_target: self.p_target,
            p_collision: self.p_collision,
            energy_mean: self.energy,
        }
    }

    /// The minimisation vector with energy divided by `scale`.
    pub fn minimisation(&self, scale: f64) -> [f64; 3] {
        [self.energy / scale, self.p_collision, 1.0 - self.p_target]
    }

    fn add_scaled(&mut self, o: &Self, p: f64) {
        self.energy += p * o.energy;
        self.p_collision += p * o.p_collision;
        self.p_target += p * o.p_target;
    }

    /// `Σ w_k o_k`.
    pub fn mix(parts: impl IntoIterator<Item = (f64, Objectives)>) -> Self {
        let mut m = Self::default();
        for (w, o) in parts {
            m.add_scaled(&o, w);
        }
        m
    }
}

/// A deterministic policy: the chosen choice index (into `State::choices`) per state.
pub type DeterministicPolicy = Vec<u16>;

/// A randomised memoryless policy: a distribution over `State::choices` per state.
pub type RandomisedPolicy = Vec<Vec<f64>>;

fn terminal_value(n: Next) -> Objectives {
    match n {
        Next::Collision => Objectives {
            energy: 0.0,
            p_collision: 1.0,
            p_target: 0.0,
        },
        Next::Target => Objectives {
            energy: 0.0,
            p_collision: 0.0,
            p_target: 1.0,
        },
        Next::Free | Next::State(_) => Objectives::default(),
    }
}

/// Value of taking `choice` in state `s` given the values of later states.
fn choice_value(
    mdp: &Mdp,
    s: usize,
    c: usize,
    values: &[Objectives],
    cost: CostModel,
) -> Objectives {
    let ch = &mdp.states[s].choices[c];
    let mut v = Objectives {
        energy: ch.cost(cost),
        ..Objectives::default()
    };
    for t in &ch.transitions {
        let next = match t.next {
            Next::State(j) => values[j as usize],
            other => terminal_value(other),
        };
        v.add_scaled(&next, t.probability);
    }
    v
}

/// Optimal deterministic policy for `min λ · f` with energy scaled by `scale`,
/// by one backward pass (the MDP is acyclic and layered). Ties are broken by a
/// tiny uniform extra weight (so zero weights still yield Pareto-optimal
/// points), then by the lower choice index.
pub fn backward_induction(
    mdp: &Mdp,
    lambda: [f64; 3],
    scale: f64,
    cost: CostModel,
) -> (DeterministicPolicy, Objectives) {
    let o = weighted_optimum(mdp, lambda, scale, cost);
    (o.policy, o.objectives)
}

/// What one weighted backward induction finds.
#[derive(Debug, Clone, PartialEq)]
pub struct WeightedOptimum {
    /// The optimal deterministic policy (tie-broken, see [`backward_induction`]).
    pub policy: DeterministicPolicy,
    /// Its exact values.
    pub objectives: Objectives,
    /// `min λ · f` over *all* strategies, by the same pass without the
    /// tie-breaking weight: every achievable `f` has `λ · f ≥ bound` (up to
    /// floating-point rounding). The certificate of the front rests on it
    /// (docs/MODEL.md §5).
    pub bound: f64,
}

/// [`backward_induction`] with the exact lower bound of `λ · f`.
pub fn weighted_optimum(
    mdp: &Mdp,
    lambda: [f64; 3],
    scale: f64,
    cost: CostModel,
) -> WeightedOptimum {
    const TIE: f64 = 1e-9;
    let n = mdp.states.len();
    let mut values = vec![Objectives::default(); n];
    // Pure optimum of λ · f from each state (no tie term).
    let mut pure = vec![0.0_f64; n];
    let mut policy = vec![0_u16; n];
    let score = |o: &Objectives, l: [f64; 3]| {
        let m = o.minimisation(scale);
        l[0] * m[0] + l[1] * m[1] + l[2] * m[2]
    };
    // λ · f of the terminals: f = (0, 1, 1) at coll, (0, 0, 0) at tar, (0, 0, 1) at free.
    let terminal = |next: Next| match next {
        Next::Collision => lambda[1] + lambda[2],
        Next::Target => 0.0,
        Next::Free => lambda[2],
        Next::State(_) => 0.0,
    };
    for s in (0..n).rev() {
        let mut best: Option<(f64, f64, usize, Objectives)> = None;
        let mut best_pure = f64::INFINITY;
        for c in 0..mdp.states[s].choices.len() {
            let v = choice_value(mdp, s, c, &values, cost);
            let primary = score(&v, lambda);
            let secondary = score(&v, [1.0, 1.0, 1.0]);
            let key = primary + TIE * secondary;
            if best
                .as_ref()
                .is_none_or(|b| key < b.0 - 1e-15 * key.abs().max(1.0))
            {
                best = Some((key, secondary, c, v));
            }
            let ch = &mdp.states[s].choices[c];
            let mut w = lambda[0] * ch.cost(cost) / scale;
            for t in &ch.transitions {
                w += t.probability
                    * match t.next {
                        Next::State(j) => pure[j as usize],
                        other => terminal(other),
                    };
            }
            best_pure = best_pure.min(w);
        }
        if let Some((_, _, c, v)) = best {
            policy[s] = c as u16;
            values[s] = v;
        }
        pure[s] = best_pure;
    }
    WeightedOptimum {
        policy,
        objectives: values[mdp.initial as usize],
        bound: pure[mdp.initial as usize],
    }
}

/// Values of a randomised policy at the initial state.
pub fn evaluate(mdp: &Mdp, policy: &RandomisedPolicy, cost: CostModel) -> Objectives {
    let n = mdp.states.len();
    let mut values = vec![Objectives::default(); n];
    for s in (0..n).rev() {
        let mut v = Objectives::default();
        for (c, &p) in policy[s].iter().enumerate() {
            if p > 0.0 {
                v.add_scaled(&choice_value(mdp, s, c, &values, cost), p);
            }
        }
        values[s] = v;
    }
    values[mdp.initial as usize]
}

/// A deterministic policy as a randomised one.
pub fn as_randomised(mdp: &Mdp, policy: &DeterministicPolicy) -> RandomisedPolicy {
    mdp.states
        .iter()
        .zip(policy)
        .map(|(s, &c)| {
            let mut w = vec![0.0; s.choices.len()];
            w[c as usize] = 1.0;
            w
        })
        .collect()
}

/// The occupation measure of a mixture of deterministic policies,
/// `x(s, c) = Σ_k w_k x_k(s, c)`, summed in the order given.
pub fn mixed_occupation<'a>(
    mdp: &Mdp,
    weighted: impl IntoIterator<Item = (f64, &'a DeterministicPolicy)>,
) -> Vec<Vec<f64>> {
    let mut x: Vec<Vec<f64>> = mdp
        .states
        .iter()
        .map(|s| vec![0.0; s.choices.len()])
        .collect();
    for (w, policy) in weighted {
        let occ = occupation(mdp, &as_randomised(mdp, policy));
        for (xs, os) in x.iter_mut().zip(&occ) {
            for (xc, o) in xs.iter_mut().zip(os) {
                *xc += w * o;
            }
        }
    }
    x
}

/// Occupation measure `x(s, c)`: the probability that the policy visits state s
/// and takes choice c (each state is visited at most once per episode).
pub fn occupation(mdp: &Mdp, policy: &RandomisedPolicy) -> Vec<Vec<f64>> {
    let n = mdp.states.len();
    let mut reach = vec![0.0; n];
    reach[mdp.initial as usize] = 1.0;
    let mut x: Vec<Vec<f64>> = Vec::with_capacity(n);
    for s in 0..n {
        let row: Vec<f64> = policy[s].iter().map(|p| p * reach[s]).collect();
        for (c, &xc) in row.iter().enumerate() {
            if xc > 0.0 {
                for t in &mdp.states[s].choices[c].transitions {
                    if let Next::State(j) = t.next {
                        reach[j as usize] += xc * t.probability;
                    }
                }
            }
        }
        x.push(row);
    }
    x
}

/// Expected energy spent on each leg (decision point `i` starts leg `i`)
/// under `policy`: Σ over the leg's states and choices of the occupation
/// measure × the choice's mean segment energy. Sums to the policy's
/// expected energy ([`evaluate`]) under the same cost model.
pub fn leg_energy(mdp: &Mdp, policy: &RandomisedPolicy, cost: CostModel) -> Vec<f64> {
    let x = occupation(mdp, policy);
    let mut out = vec![0.0; mdp.num_decision_points()];
    for (s, row) in mdp.states.iter().zip(&x) {
        for (c, &xc) in s.choices.iter().zip(row) {
            if let Some(e) = out.get_mut(s.decision_point as usize) {
                *e += xc * c.cost(cost);
            }
        }
    }
    out
}

/// The constant-action policy: action index `a` of Δ in every state, if every
/// state offers it.
pub fn constant_action(mdp: &Mdp, action: u16) -> Option<DeterministicPolicy> {
    mdp.states
        .iter()
        .map(|s| {
            s.choices
                .iter()
                .position(|c| c.action == action)
                .map(|i| i as u16)
        })
        .collect()
}
