//! A synthetic layered MDP shaped like the belief abstraction (docs/MODEL.md §4),
//! generated deterministically from a seed: for benchmarks and tests of the
//! front and the strategy LP at sizes the built-in scenarios do not reach.
//!
//! Shape: one initial state, then layers of decision points; every state offers
//! δ = 0 and a subset of the rest of Δ (`min_actions..=max_actions` in all); a choice leads to
//! `successors − 2` states of the next layer plus `coll` and `free` (the last
//! layer: only the terminals). A state's position `r ∈ [0, 1)` in its layer plays
//! the covariance region (0 = well localised); small δ costs more energy and
//! collides less and keeps the belief good, like the real abstraction.

use crate::mdp::{Choice, Mdp, Method, Next, State, Transition};
use etp_shared::discretization::Region;
use etp_shared::rng::stream_rng;
use rand::RngExt;

/// Random stream of the synthetic generator (distinct from the named streams
/// of `etp_shared::rng::streams`).
const SYNTHETIC_STREAM: u64 = 0x5359_4E54_4845_5449;

/// Size and seed of a synthetic MDP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyntheticParams {
    /// Decision states (the terminals come on top).
    pub states: usize,
    /// Decision points (layers); layer 0 holds the initial state only.
    pub layers: usize,
    /// |Δ|.
    pub deltas: usize,
    pub min_actions: usize,
    pub max_actions: usize,
    /// Successors of a choice, terminals included.
    pub successors: usize,
    pub seed: u64,
}

impl Default for SyntheticParams {
    /// 5000 states in 21 layers, 5–8 of 8 actions, 20 successors.
    fn default() -> Self {
        Self {
            states: 5000,
            layers: 21,
            deltas: 8,
            min_actions: 5,
            max_actions: 8,
            successors: 20,
            seed: 0,
        }
    }
}

/// The synthetic MDP of `p` (same parameters, same MDP, bit for bit).
pub fn layered_mdp(p: &SyntheticParams) -> Mdp {
    let layers = p.layers.max(2);
    let deltas: Vec<f64> = (0..p.deltas.max(1))
        .map(|k| k as f64 / (p.deltas.max(2) - 1) as f64)
        .collect();
    // Layer sizes: 1, then the rest spread evenly.
    let rest = p.states.max(layers) - 1;
    let mut sizes = vec![1usize];
    for l in 1..layers {
        sizes.push(rest * l / (layers - 1) - rest * (l - 1) / (layers - 1));
    }
    let starts: Vec<usize> = sizes
        .iter()
        .scan(0, |acc, &n| {
            let s = *acc;
            *acc += n;
            Some(s)
        })
        .collect();
    let mut states = Vec::with_capacity(p.states);
    for (layer, (&size, &start)) in sizes.iter().zip(&starts).enumerate() {
        for i in 0..size {
            let id = (start + i) as u64;
            let mut rng = stream_rng(p.seed, SYNTHETIC_STREAM, id);
            let r = i as f64 / size as f64;
            let lo = p.min_actions.clamp(1, deltas.len());
            let hi = p.max_actions.clamp(lo, deltas.len());
            let k = rng.random_range(lo..=hi);
            // Action 0 (δ = 0, the full KF) and a random subset of the
            // others, k in all, sorted: like the real abstraction, where every
            // state offers δ = 0 (so the full-KF baseline exists).
            let mut actions: Vec<u16> = (0..deltas.len() as u16).collect();
            for j in 1..k {
                let pick = rng.random_range(j..actions.len());
                actions.swap(j, pick);
            }
            actions.truncate(k);
            actions.sort_unstable();
            let last = layer + 1 == layers;
            let choices = actions
                .iter()
                .map(|&a| {
                    let d = deltas[a as usize];
                    let jitter = |rng: &mut etp_shared::rng::SimRng| rng.random_range(0.8..1.2);
                    let cost = 10.0 * (1.0 - 0.85 * d) * (1.0 + 0.5 * r) * jitter(&mut rng);
                    let p_coll = (0.02 * (0.2 + r) * (0.2 + 2.0 * d) * jitter(&mut rng)).min(0.3);
                    let p_free = 0.004 * jitter(&mut rng);
                    let mut out: Vec<(Next, f64)> = Vec::new();
                    if last {
                        let p_tar_loss = 0.1 * (0.1 + r) * (0.3 + d) * jitter(&mut rng);
                        let coll = p_coll + p_tar_loss * 0.3;
                        let free = p_free + p_tar_loss * 0.7;
                        out.push((Next::Collision, coll));
                        out.push((Next::Target, 1.0 - coll - free));
                        out.push((Next::Free, free));
                    } else {
                        let next_size = sizes[layer + 1];
                        let next_start = starts[layer + 1];
                        let m = p.successors.saturating_sub(2).clamp(1, next_size);
                        // Successor window: centred on where this belief drifts
                        // (worse with larger δ and worse regions).
                        let centre = ((0.6 * r + 0.5 * d) * next_size as f64) as usize;
                        let first = centre.saturating_sub(m / 2).min(next_size - m);
                        let weights: Vec<f64> =
                            (0..m).map(|_| rng.random_range(0.05..1.0)).collect();
                        let total: f64 = weights.iter().sum();
                        let stay = 1.0 - p_coll - p_free;
                        for (j, w) in weights.iter().enumerate() {
                            out.push((
                                Next::State((next_start + first + j) as u32),
                                stay * w / total,
                            ));
                        }
                        out.push((Next::Collision, p_coll));
                        out.push((Next::Free, p_free));
                    }
                    let samples = 1000;
                    Choice {
                        action: a,
                        samples,
                        cost_counted: cost,
                        cost_model: cost,
                        mean_steps: 20.0,
                        transitions: out
                            .into_iter()
                            .map(|(next, probability)| Transition {
                                next,
                                count: (probability * f64::from(samples)).round() as u32,
                                probability,
                                ci_low: probability,
                                ci_high: probability,
                            })
                            .collect(),
                        cost_sq_counted: cost * cost,
                        cost_sq_model: cost * cost,
                        cost_range: 4.0 * cost.max(1.0),
                        holdout: None,
                        unmatched: 0,
                    }
                })
                .collect();
            states.push(State {
                decision_point: layer as u32,
                region: Region(vec![(i as u16, 0)]),
                merged: Vec::new(),
                choices,
            });
        }
    }
    Mdp {
        scenario_name: format!("synthetic-{}", p.states),
        scenario_hash: format!("{:064x}", etp_shared::rng::mix64(p.seed)),
        method: Method::Discretized,
        deltas,
        discretization: None,
        kf_convergence: None,
        states,
        initial: 0,
        samples_per_choice: 1000,
        holdout_samples: 0,
        looks: 1,
        build: crate::mdp::BuildSettings::default(),
        seed: p.seed,
        total_segments: 0,
        total_steps: 0,
        splits: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_mdp_has_the_requested_shape_and_is_reproducible() {
        let p = SyntheticParams {
            states: 600,
            ..SyntheticParams::default()
        };
        let m = layered_mdp(&p);
        m.check().expect("a valid MDP");
        assert_eq!(m.states.len(), 600);
        assert_eq!(m.num_decision_points(), 21);
        for s in &m.states {
            assert!((5..=8).contains(&s.choices.len()));
        }
        let inner = &m.states[1].choices[0].transitions;
        assert_eq!(inner.len(), 20);
        assert_eq!(layered_mdp(&p), m);
        let other = layered_mdp(&SyntheticParams { seed: 1, ..p });
        assert_ne!(other, m);
    }
}
