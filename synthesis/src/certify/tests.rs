//! Properties of the certified bounds: robust backward induction against
//! brute-force enumeration of the interval extremes, the union-bound level
//! (and its coverage, by seeded simulation), the certified selection meeting
//! its request, and cross-fitting on a known MDP.

use super::intervals::{ChoiceIntervals, IntervalMdp, interval_mdp, union_events};
use super::robust::{Objective, best_certified_target, certify, robust_value};
use super::select::certified_strategy;
use crate::mdp::tests::toy;
use crate::mdp::{CostModel, Holdout, Mdp, Next};
use crate::pareto::policy::RandomisedPolicy;
use crate::synthetic::{SyntheticParams, layered_mdp};
use etp_shared::rng::stream_rng;
use rand::RngExt;

/// Interval sets by hand on the toy MDP (two outcomes per choice) with an
/// unseen mass, and a costs' upper bound.
fn toy_intervals(mdp: &Mdp) -> IntervalMdp {
    let choices = mdp
        .states
        .iter()
        .map(|s| {
            s.choices
                .iter()
                .enumerate()
                .map(|(k, c)| ChoiceIntervals {
                    outcomes: c
                        .transitions
                        .iter()
                        .map(|t| {
                            let w = 0.03 + 0.02 * k as f64;
                            (
                                t.next,
                                (t.probability - w).max(0.0),
                                (t.probability + 1.5 * w).min(1.0),
                            )
                        })
                        .collect(),
                    unseen_high: 0.01 * (k + 1) as f64,
                    cost_high: c.cost_counted * 1.1,
                })
                .collect()
        })
        .collect();
    IntervalMdp {
        confidence: 0.95,
        cost: CostModel::Counted,
        events: 1,
        per_event: 0.05,
        choices,
        energy_tail: vec![40.0, 20.0, 0.0],
    }
}

/// Every vertex of `{lo ≤ p ≤ hi, Σ p = 1}` (one coordinate free, the
/// others at a bound), over the outcomes and the unseen mass (lo 0).
fn vertices(ch: &ChoiceIntervals) -> Vec<Vec<f64>> {
    let mut b: Vec<(f64, f64)> = ch.outcomes.iter().map(|o| (o.1, o.2)).collect();
    b.push((0.0, ch.unseen_high));
    let k = b.len();
    let mut out = Vec::new();
    for free in 0..k {
        for mask in 0..(1u32 << (k - 1)) {
            let mut p = vec![0.0; k];
            let mut bit = 0;
            for (i, pi) in p.iter_mut().enumerate() {
                if i != free {
                    *pi = if mask & (1 << bit) != 0 {
                        b[i].1
                    } else {
                        b[i].0
                    };
                    bit += 1;
                }
            }
            let rest = 1.0 - p.iter().sum::<f64>();
            if rest >= b[free].0 - 1e-12 && rest <= b[free].1 + 1e-12 {
                p[free] = rest;
                out.push(p);
            }
        }
    }
    out
}

/// The value of `policy` when choice (s, c) uses distribution `dist[(s, c)]`
/// (last entry: the unseen mass, valued at the objective's worst).
fn value_with(
    mdp: &Mdp,
    im: &IntervalMdp,
    policy: &RandomisedPolicy,
    dist: &std::collections::BTreeMap<(usize, usize), Vec<f64>>,
    objective: Objective,
) -> f64 {
    let n = mdp.states.len();
    let mut v = vec![0.0; n];
    for s in (0..n).rev() {
        let tail = im.energy_tail[mdp.states[s].decision_point as usize + 1];
        let mut acc = 0.0;
        for (c, &w) in policy[s].iter().enumerate() {
            if w <= 0.0 {
                continue;
            }
            let p = &dist[&(s, c)];
            let ch = &im.choices[s][c];
            let mut x = 0.0;
            for (k, &(next, _, _)) in ch.outcomes.iter().enumerate() {
                x += p[k]
                    * match (next, objective) {
                        (Next::State(j), _) => v[j as usize],
                        (Next::Target, Objective::TargetLow) => 1.0,
                        (Next::Collision, Objective::CollisionHigh) => 1.0,
                        _ => 0.0,
                    };
            }
            x += p[ch.outcomes.len()]
                * match objective {
                    Objective::TargetLow => 0.0,
                    Objective::CollisionHigh => 1.0,
                    Objective::EnergyHigh => tail,
                };
            if objective == Objective::EnergyHigh {
                x += ch.cost_high;
            }
            acc += w * x;
        }
        v[s] = acc;
    }
    v[mdp.initial as usize]
}

#[test]
fn robust_induction_equals_brute_force_over_interval_extremes() {
    let mdp = toy();
    let im = toy_intervals(&mdp);
    // Randomising at the root and at one successor, deterministic at the other.
    let policies: Vec<RandomisedPolicy> = vec![
        vec![vec![0.3, 0.7], vec![0.6, 0.4], vec![1.0, 0.0]],
        vec![vec![1.0, 0.0], vec![0.0, 1.0], vec![0.5, 0.5]],
        vec![vec![0.0, 1.0], vec![1.0, 0.0], vec![0.2, 0.8]],
    ];
    for policy in &policies {
        let support: Vec<(usize, usize)> = policy
            .iter()
            .enumerate()
            .flat_map(|(s, w)| {
                w.iter()
                    .enumerate()
                    .filter(|(_, p)| **p > 0.0)
                    .map(move |(c, _)| (s, c))
            })
            .collect();
        let verts: Vec<Vec<Vec<f64>>> = support
            .iter()
            .map(|&(s, c)| vertices(&im.choices[s][c]))
            .collect();
        for objective in [
            Objective::TargetLow,
            Objective::CollisionHigh,
            Objective::EnergyHigh,
        ] {
            let mut idx = vec![0usize; support.len()];
            let mut best = if objective == Objective::TargetLow {
                f64::INFINITY
            } else {
                f64::NEG_INFINITY
            };
            loop {
                let dist = support
                    .iter()
                    .zip(&idx)
                    .zip(&verts)
                    .map(|((&sc, &i), v)| (sc, v[i].clone()))
                    .collect();
                let x = value_with(&mdp, &im, policy, &dist, objective);
                best = if objective == Objective::TargetLow {
                    best.min(x)
                } else {
                    best.max(x)
                };
                // Next combination (odometer).
                let mut k = 0;
                while k < idx.len() {
                    idx[k] += 1;
                    if idx[k] < verts[k].len() {
                        break;
                    }
                    idx[k] = 0;
                    k += 1;
                }
                if k == idx.len() {
                    break;
                }
            }
            let robust = robust_value(&mdp, &im, policy, objective);
            assert!(
                (robust - best).abs() < 1e-12,
                "{objective:?}: robust {robust} vs brute force {best}"
            );
        }
    }
}

#[test]
fn union_bound_level_is_alpha_over_all_events() {
    let mdp = layered_mdp(&SyntheticParams {
        states: 60,
        ..SyntheticParams::default()
    });
    let im = interval_mdp(&mdp, 0.95, CostModel::Counted).expect("valid level");
    let events: u64 = mdp
        .states
        .iter()
        .flat_map(|s| &s.choices)
        .map(|c| c.transitions.len() as u64 + 2)
        .sum();
    assert_eq!(im.events, events);
    assert_eq!(union_events(&mdp), events);
    assert!(im.per_event * im.events as f64 <= 0.05 * (1.0 + 1e-12));
    assert!(im.per_event * im.events as f64 >= 0.05 * (1.0 - 1e-12));
    // Sample allocation widens the union over the possible sample sizes.
    let mut refined = mdp.clone();
    refined.looks = 4;
    let im4 = interval_mdp(&refined, 0.95, CostModel::Counted).expect("valid level");
    assert_eq!(im4.events, 4 * events);
    assert!(im4.per_event < im.per_event);
    assert!(interval_mdp(&mdp, 1.0, CostModel::Counted).is_err());
    assert!(interval_mdp(&mdp, 0.0, CostModel::Counted).is_err());
}

/// Simulated coverage: a one-state MDP whose true distribution is known; the
/// fraction of seeded resamplings where *every* interval holds is ≥ 1 − α.
#[test]
fn all_intervals_hold_at_least_at_the_confidence_level() {
    let truth = [0.6, 0.3, 0.08, 0.02];
    let nexts = [Next::Target, Next::Free, Next::Collision, Next::State(1)];
    let (n, trials, alpha) = (200_u32, 2000_u64, 0.2);
    let mut held = 0;
    for trial in 0..trials {
        let mut rng = stream_rng(17, 99, trial);
        let mut counts = [0u32; 4];
        let mut cost_sum = 0.0;
        let mut cost_sq = 0.0;
        for _ in 0..n {
            let u: f64 = rng.random();
            let mut acc = 0.0;
            let mut k = 3;
            for (i, p) in truth.iter().enumerate() {
                acc += p;
                if u < acc {
                    k = i;
                    break;
                }
            }
            counts[k] += 1;
            // Energy uniform on [0, 10]: mean 5.
            let e: f64 = 10.0 * rng.random::<f64>();
            cost_sum += e;
            cost_sq += e * e;
        }
        let mut mdp = toy();
        mdp.states.truncate(1);
        let c = &mut mdp.states[0].choices[0];
        c.samples = n;
        c.cost_counted = cost_sum / f64::from(n);
        c.cost_sq_counted = cost_sq / f64::from(n);
        c.cost_range = 10.0;
        c.transitions = nexts
            .iter()
            .zip(counts)
            .filter(|(_, k)| *k > 0)
            .map(|(&next, count)| crate::mdp::Transition {
                next,
                count,
                probability: f64::from(count) / f64::from(n),
                ci_low: 0.0,
                ci_high: 1.0,
            })
            .collect();
        mdp.states[0].choices.truncate(1);
        let im = interval_mdp(&mdp, 1.0 - alpha, CostModel::Counted).expect("level");
        let ch = &im.choices[0][0];
        let mut ok = ch.cost_high >= 5.0;
        let mut unseen = 0.0;
        for (next, p) in nexts.iter().zip(truth) {
            match ch.outcomes.iter().find(|o| o.0 == *next) {
                Some(&(_, lo, hi)) => ok &= lo <= p && p <= hi,
                None => unseen += p,
            }
        }
        ok &= unseen <= ch.unseen_high;
        held += u64::from(ok);
    }
    let coverage = held as f64 / trials as f64;
    assert!(coverage >= 1.0 - alpha, "coverage {coverage}");
}

#[test]
fn certified_selection_meets_its_certified_request() {
    let mut mdp = layered_mdp(&SyntheticParams {
        states: 120,
        ..SyntheticParams::default()
    });
    // Wider intervals than the synthetic 1000 samples: make them 4000.
    for s in &mut mdp.states {
        for c in &mut s.choices {
            c.samples = 4000;
            for t in &mut c.transitions {
                t.count = (t.probability * 4000.0).round() as u32;
            }
        }
    }
    let im = interval_mdp(&mdp, 0.95, CostModel::Counted).expect("level");
    let (_, best_low) = best_certified_target(&mdp, &im);
    let request = best_low - 0.05;
    let c = certified_strategy(&mdp, &im, CostModel::Counted, request, None).expect("feasible");
    let again = certify(&mdp, &im, &c.strategy.policy);
    assert_eq!(again, c.certified);
    assert!(again.p_target_low >= request, "{again:?} vs {request}");
    assert!(c.strategy.predicted.p_target >= again.p_target_low);
    // Infeasible beyond the best certified P_tar, with that value in the error.
    let e = certified_strategy(&mdp, &im, CostModel::Counted, best_low + 1e-3, None)
        .expect_err("infeasible");
    assert!(e.to_string().contains(&format!("{best_low:.6}")), "{e}");
}

#[test]
fn crossfit_evaluates_on_the_held_out_counts() {
    let mut mdp = toy();
    mdp.holdout_samples = 100;
    // Held-out counts of the root's choice 0: 80 to state 1, 20 collide;
    // state 1's choice 0: 90 target, 10 free (main: 0.9/0.1 and 0.95/0.05).
    let h = |counts: Vec<(Next, u32)>| {
        Some(Holdout {
            samples: 100,
            cost_counted: 1.0,
            cost_model: 1.0,
            counts,
            unmatched: 0,
        })
    };
    for s in &mut mdp.states {
        for c in &mut s.choices {
            c.holdout = h(c.transitions.iter().map(|t| (t.next, t.count)).collect());
        }
    }
    mdp.states[0].choices[0].holdout = h(vec![(Next::State(1), 80), (Next::Collision, 20)]);
    mdp.states[1].choices[0].holdout = h(vec![(Next::Target, 90), (Next::Free, 10)]);
    let policy = vec![vec![1.0, 0.0], vec![1.0, 0.0], vec![1.0, 0.0]];
    let x = super::crossfit::crossfit(&mdp, &policy, CostModel::Counted).expect("held out");
    assert!((x.objectives.p_target - 0.8 * 0.9).abs() < 1e-12);
    assert!((x.objectives.p_collision - 0.2).abs() < 1e-12);
    assert!((x.objectives.energy - 1.8).abs() < 1e-12);
    assert_eq!(x.unmatched_mass, 0.0);
    mdp.holdout_samples = 0;
    assert!(super::crossfit::crossfit(&mdp, &policy, CostModel::Counted).is_none());
}
