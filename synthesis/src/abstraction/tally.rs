//! Counting the segments of one (state, action) and turning the counts into a
//! [`Choice`] with probabilities, Wilson 95 % intervals and both cost models.

use crate::mdp::{Choice, Next, Transition};
use etp_shared::etkf::Belief;
use etp_shared::stats::wilson_interval;
use std::collections::BTreeMap;

/// A belief that reached the next decision point, with its reservoir key.
#[derive(Debug, Clone, Copy)]
pub(super) struct Arrival<const N: usize> {
    pub key: u64,
    pub belief: Belief<N>,
}

/// Raw sums of a chunk of segments of one (state, action).
#[derive(Debug, Clone, Default)]
pub(super) struct ChunkTally<const N: usize> {
    pub samples: u32,
    pub steps: u64,
    pub transmissions: u64,
    /// Σ over slots of γ̄(δ, m) (the paper's cost model).
    pub expected_transmissions: f64,
    pub collisions: u32,
    /// Last leg only: segments ending with the true state in the target box.
    pub target: u32,
    /// Last leg only: the others.
    pub free: u32,
    /// Not the last leg: arrival beliefs, in segment order.
    pub arrivals: Vec<Arrival<N>>,
}

/// The merged counts of one (state, action).
#[derive(Debug, Clone, Default)]
pub(super) struct ChoiceTally {
    pub samples: u32,
    pub steps: u64,
    pub transmissions: u64,
    pub expected_transmissions: f64,
    pub counts: BTreeMap<Next, u32>,
}

impl ChoiceTally {
    /// Add a chunk; `next_of(k)` is the next state of the chunk's k-th arrival.
    pub fn add<const N: usize>(&mut self, c: &ChunkTally<N>, next_of: impl Fn(usize) -> u32) {
        self.samples += c.samples;
        self.steps += c.steps;
        self.transmissions += c.transmissions;
        self.expected_transmissions += c.expected_transmissions;
        let mut bump = |n: Next, k: u32| {
            if k > 0 {
                *self.counts.entry(n).or_insert(0) += k;
            }
        };
        bump(Next::Collision, c.collisions);
        bump(Next::Target, c.target);
        bump(Next::Free, c.free);
        for k in 0..c.arrivals.len() {
            bump(Next::State(next_of(k)), 1);
        }
    }

    /// The MDP choice: frequencies, Wilson intervals, counted and model costs
    /// (`cost` = energy per transmission c_m of the leg's sensor).
    pub fn into_choice(self, action: u16, cost: f64) -> Choice {
        let n = f64::from(self.samples.max(1));
        let transitions = self
            .counts
            .into_iter()
            .map(|(next, count)| {
                let (ci_low, ci_high) = wilson_interval(u64::from(count), u64::from(self.samples));
                Transition {
                    next,
                    count,
                    probability: f64::from(count) / n,
                    ci_low,
                    ci_high,
                }
            })
            .collect();
        Choice {
            action,
            samples: self.samples,
            cost_counted: self.transmissions as f64 * cost / n,
            cost_model: self.expected_transmissions * cost / n,
            mean_steps: self.steps as f64 / n,
            transitions,
        }
    }
}
