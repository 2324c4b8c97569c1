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

use crate::mdp::{CostModel, Mdp, Next};
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
                let mut cont = Objectives::default();
                let mut mass = 0.0;
                for t in &ch.transitions {
                    if let Next::State(j) = t.next {
                        add(&mut cont, &values[j as usize], t.probability);
                        mass += t.probability;
                    }
                }
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
    })
}
