//! The cross-fitted value's standard error: a closed form on the toy MDP, and
//! the spread of the cross-fitted value over many independent held-out
//! samples of a synthetic MDP whose main probabilities are the truth.

use super::crossfit;
use crate::mdp::tests::toy;
use crate::mdp::{CostModel, Holdout, Mdp, Next};
use crate::pareto::policy::{Objectives, RandomisedPolicy, evaluate};
use crate::synthetic::{SyntheticParams, layered_mdp};
use etp_shared::rng::stream_rng;
use rand::RngExt;

#[test]
fn standard_error_of_the_toy_is_the_closed_form() {
    let mut mdp = toy();
    mdp.holdout_samples = 100;
    for s in &mut mdp.states {
        for c in &mut s.choices {
            c.holdout = Some(Holdout {
                samples: 100,
                cost_counted: 1.0,
                cost_model: 1.0,
                counts: c.transitions.iter().map(|t| (t.next, t.count)).collect(),
                unmatched: 0,
            });
        }
    }
    let policy = vec![vec![1.0, 0.0], vec![1.0, 0.0], vec![1.0, 0.0]];
    let x = crossfit(&mdp, &policy, CostModel::Counted).expect("held out");
    // Root row (main 0.9 → state 1, 0.1 collide), state 1 reached with
    // held-out occupation 0.9 (main 0.95 target, 0.05 free); V₁ = (0.95, 0, 1).
    let v1: f64 = 0.95;
    let root_tar = 0.9 * v1 * v1 - (0.9 * v1) * (0.9 * v1);
    let var_tar = root_tar / 100.0 + 0.9 * 0.9 * (0.95 * 0.05) / 100.0;
    assert!((x.standard_error.p_target - var_tar.sqrt()).abs() < 1e-12);
    // P_coll: only the root row spreads (0.1 · 0.9); the energy likewise
    // (the successor's held-out energy 1 against 0; costs have no spread).
    assert!((x.standard_error.p_collision - (0.09f64 / 100.0).sqrt()).abs() < 1e-12);
    assert!((x.standard_error.energy - (0.09f64 / 100.0).sqrt()).abs() < 1e-12);
}

/// Held-out counts of `n` segments per choice drawn from the main
/// probabilities (the truth here), with the main mean cost.
fn resample(mdp: &mut Mdp, n: u32, seed: u64) {
    mdp.holdout_samples = n;
    for (s, state) in mdp.states.iter_mut().enumerate() {
        for (c, ch) in state.choices.iter_mut().enumerate() {
            let mut rng = stream_rng(seed, 0x484F_4C44, (s * 64 + c) as u64);
            let mut counts: Vec<(Next, u32)> = ch.transitions.iter().map(|t| (t.next, 0)).collect();
            for _ in 0..n {
                let u: f64 = rng.random();
                let mut acc = 0.0;
                let mut k = counts.len() - 1;
                for (i, t) in ch.transitions.iter().enumerate() {
                    acc += t.probability;
                    if u < acc {
                        k = i;
                        break;
                    }
                }
                counts[k].1 += 1;
            }
            counts.retain(|&(_, k)| k > 0);
            ch.cost_sq_counted = ch.cost_counted * ch.cost_counted;
            ch.holdout = Some(Holdout {
                samples: n,
                cost_counted: ch.cost_counted,
                cost_model: ch.cost_model,
                counts,
                unmatched: 0,
            });
        }
    }
}

#[test]
fn standard_error_matches_the_spread_over_independent_held_out_samples() {
    let mut mdp = layered_mdp(&SyntheticParams {
        states: 300,
        layers: 6,
        deltas: 4,
        min_actions: 2,
        max_actions: 4,
        successors: 8,
        seed: 7,
    });
    // Half on the first choice, half on the last: the weights enter squared.
    let policy: RandomisedPolicy = mdp
        .states
        .iter()
        .map(|s| {
            let mut w = vec![0.0; s.choices.len()];
            w[0] += 0.5;
            w[s.choices.len() - 1] += 0.5;
            w
        })
        .collect();
    let truth = evaluate(&mdp, &policy, CostModel::Counted);
    let (reps, n) = (400, 30);
    let (mut values, mut predicted_sd, mut covered) = (Vec::new(), Vec::new(), [0u32; 3]);
    for r in 0..reps {
        resample(&mut mdp, n, r);
        let x = crossfit(&mdp, &policy, CostModel::Counted).expect("held out");
        let (o, e) = (x.objectives, x.standard_error);
        let pairs = [
            (o.p_target, truth.p_target, e.p_target),
            (o.p_collision, truth.p_collision, e.p_collision),
            (o.energy, truth.energy, e.energy),
        ];
        for (k, (v, t, sd)) in pairs.into_iter().enumerate() {
            covered[k] += u32::from((v - t).abs() <= 1.96 * sd);
        }
        values.push(o);
        predicted_sd.push(e);
    }
    let part = |f: fn(&Objectives) -> f64| {
        let xs: Vec<f64> = values.iter().map(f).collect();
        let m = xs.iter().sum::<f64>() / xs.len() as f64;
        let sd = (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (xs.len() - 1) as f64).sqrt();
        let predicted = predicted_sd.iter().map(f).sum::<f64>() / predicted_sd.len() as f64;
        (sd, predicted)
    };
    for (name, f, k) in [
        (
            "P_tar",
            (|o: &Objectives| o.p_target) as fn(&Objectives) -> f64,
            0,
        ),
        ("P_coll", |o: &Objectives| o.p_collision, 1),
        ("energy", |o: &Objectives| o.energy, 2),
    ] {
        let (empirical, predicted) = part(f);
        // 400 replicates: the empirical sd is itself within ~±7 % (2σ).
        let ratio = predicted / empirical;
        assert!(
            (0.85..1.15).contains(&ratio),
            "{name}: delta {predicted} vs spread {empirical}"
        );
        // The 95 % interval covers the truth in 92–98 % of the replicates
        // (binomial 2σ at 400 is ±2.2 pt).
        let rate = f64::from(covered[k]) / reps as f64;
        assert!((0.92..=0.98).contains(&rate), "{name}: coverage {rate}");
    }
}
