//! Cross-fitted prediction (docs/MODEL.md §4.1): a strategy chosen on the main
//! sample is evaluated, by exact backward induction, on the held-out
//! transitions of the same states — segments from the independent stream
//! `HOLDOUT` — so the luck that made the optimiser prefer an action does not
//! flatter its prediction.
//!
//! A held-out segment that arrives in a region the main sample never reached
//! has no state to continue from; its continuation is valued at the main
//! sample's average continuation of that choice (its state successors
//! weighted by their main-sample probabilities), and the mass this concerns is
//! reported (`unmatched_mass`, typically well below 10⁻³).
//!
//! The cross-fitted value is itself an estimate from finitely many held-out
//! segments. Its standard error is the delta method's (first order in the
//! rows' sampling errors, which are independent across rows): a row
//! (s, c) visited with held-out occupation x(s, c) and estimated from n
//! segments adds x² · Var[cost + V(next)] / n, the variance taken under the
//! *main* sample's distribution of the row (independent of the held-out one,
//! and not degenerate where the held-out row has one or two segments). A
//! segment's energy and its successor's value are correlated, and only their
//! marginal spreads are known, so the energy term uses the Cauchy–Schwarz
//! bound (σ_cost + σ_V)²: the energy error is not understated.

use crate::mdp::{Choice, CostModel, Mdp, Next};
use crate::pareto::policy::{Objectives, RandomisedPolicy, occupation};

/// A strategy's cross-fitted values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossFit {
    pub objectives: Objectives,
    /// Held-out segments per (state, action).
    pub samples: u32,
    /// Probability (under the strategy, on the main sample) of passing through
    /// a held-out transition into a region without a state.
    pub unmatched_mass: f64,
    /// Standard errors of `objectives` from the held-out sample's finite
    /// size (delta method, see the module's text).
    pub standard_error: Objectives,
}

fn terminal(n: Next) -> Objectives {
    match n {
        Next::Collision => Objectives {
            p_collision: 1.0,
            ..Objectives::default()
        },
        Next::Target => Objectives {
            p_target: 1.0,
            ..Objectives::default()
        },
        _ => Objectives::default(),
    }
}

impl CrossFit {
    /// The 95 % half-widths of `objectives` from the held-out sample's own
    /// error (normal approximation), as a strategy file stores them.
    pub fn ci95(&self) -> etp_shared::strategy::PredictionCi95 {
        let e = &self.standard_error;
        let z = etp_shared::stats::Z95;
        etp_shared::strategy::PredictionCi95 {
            p_target: z * e.p_target,
            p_collision: z * e.p_collision,
            energy_mean: z * e.energy,
        }
    }
}

fn add(v: &mut Objectives, o: &Objectives, p: f64) {
    v.energy += p * o.energy;
    v.p_collision += p * o.p_collision;
    v.p_target += p * o.p_target;
}

/// The cross-fitted values of `policy`, or `None` when the MDP has no
/// held-out sample.
pub fn crossfit(mdp: &Mdp, policy: &RandomisedPolicy, cost: CostModel) -> Option<CrossFit> {
    if mdp.holdout_samples == 0 {
        return None;
    }
    let n = mdp.states.len();
    let mut values = vec![Objectives::default(); n];
    for s in (0..n).rev() {
        let mut v = Objectives::default();
        for (c, &p) in policy[s].iter().enumerate() {
            if p <= 0.0 {
                continue;
            }
            let ch = &mdp.states[s].choices[c];
            let h = ch.holdout.as_ref()?;
            let total = f64::from(h.samples.max(1));
            let mut cv = Objectives {
                energy: h.cost(cost),
                ..Objectives::default()
            };
            for &(next, count) in &h.counts {
                let o = match next {
                    Next::State(j) => values[j as usize],
                    t => terminal(t),
                };
                add(&mut cv, &o, f64::from(count) / total);
            }
            if h.unmatched > 0 {
                // The main sample's average continuation among state successors.
                let (cont, mass) = unmatched_continuation(ch, &values);
                if mass > 0.0 {
                    add(&mut cv, &cont, f64::from(h.unmatched) / total / mass);
                }
            }
            add(&mut v, &cv, p);
        }
        values[s] = v;
    }
    let occ = occupation(mdp, policy);
    let mut unmatched_mass = 0.0;
    for (s, row) in occ.iter().enumerate() {
        for (c, &x) in row.iter().enumerate() {
            if let Some(h) = &mdp.states[s].choices[c].holdout {
                unmatched_mass += x * f64::from(h.unmatched) / f64::from(h.samples.max(1));
            }
        }
    }
    Some(CrossFit {
        objectives: values[mdp.initial as usize],
        samples: mdp.holdout_samples,
        unmatched_mass,
        standard_error: standard_error(mdp, policy, cost, &values),
    })
}

/// The continuation of a held-out segment that found no state: the main
/// sample's state successors of the choice weighted by their probabilities,
/// unnormalised, and the mass they carry (to divide by).
fn unmatched_continuation(ch: &Choice, values: &[Objectives]) -> (Objectives, f64) {
    let mut cont = Objectives::default();
    let mut mass = 0.0;
    for t in &ch.transitions {
        if let Next::State(j) = t.next {
            add(&mut cont, &values[j as usize], t.probability);
            mass += t.probability;
        }
    }
    (cont, mass)
}

/// Delta-method standard errors of the cross-fitted `values` (module text):
/// Σ over rows of x_h(s, c)² · Var_main[cost + V(next)] / n_h(s, c), with
/// x_h the occupation under the held-out estimate itself.
fn standard_error(
    mdp: &Mdp,
    policy: &RandomisedPolicy,
    cost: CostModel,
    values: &[Objectives],
) -> Objectives {
    let n = mdp.states.len();
    let mut reach = vec![0.0; n];
    reach[mdp.initial as usize] = 1.0;
    let mut var = Objectives::default();
    for s in 0..n {
        for (c, &p) in policy[s].iter().enumerate() {
            let x = reach[s] * p;
            let ch = &mdp.states[s].choices[c];
            let Some(h) = ch.holdout.as_ref() else {
                continue;
            };
            if x <= 0.0 {
                continue;
            }
            // The held-out occupation flows on (it weights the rows below).
            let total = f64::from(h.samples.max(1));
            for &(next, count) in &h.counts {
                if let Next::State(j) = next {
                    reach[j as usize] += x * f64::from(count) / total;
                }
            }
            if h.unmatched > 0 {
                let share = x * f64::from(h.unmatched) / total;
                let mass = unmatched_continuation(ch, values).1;
                if mass > 0.0 {
                    for t in &ch.transitions {
                        if let Next::State(j) = t.next {
                            reach[j as usize] += share * t.probability / mass;
                        }
                    }
                }
            }
            // The row's spread under the main sample's distribution.
            let (mut m, mut m2) = (Objectives::default(), Objectives::default());
            for t in &ch.transitions {
                let o = match t.next {
                    Next::State(j) => values[j as usize],
                    other => terminal(other),
                };
                add(&mut m, &o, t.probability);
                add(&mut m2, &square(&o), t.probability);
            }
            let spread = |m2: f64, m: f64| (m2 - m * m).max(0.0);
            let sd_cost = (ch.cost_sq(cost) - ch.cost(cost).powi(2)).max(0.0).sqrt();
            let sd_energy = sd_cost + spread(m2.energy, m.energy).sqrt();
            let w = x * x / total;
            var.p_target += w * spread(m2.p_target, m.p_target);
            var.p_collision += w * spread(m2.p_collision, m.p_collision);
            var.energy += w * sd_energy * sd_energy;
        }
    }
    Objectives {
        energy: var.energy.sqrt(),
        p_collision: var.p_collision.sqrt(),
        p_target: var.p_target.sqrt(),
    }
}

fn square(o: &Objectives) -> Objectives {
    Objectives {
        energy: o.energy * o.energy,
        p_collision: o.p_collision * o.p_collision,
        p_target: o.p_target * o.p_target,
    }
}

#[cfg(test)]
#[path = "crossfit_tests.rs"]
mod tests;
