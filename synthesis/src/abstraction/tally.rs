//! Counting the segments of one (state, action) and turning the counts into a
//! [`Choice`] with probabilities, Wilson 95 % intervals and both cost models.

use crate::mdp::{Choice, Holdout, Next, Transition};
use etp_shared::etkf::{Belief, Vector};
use etp_shared::stats::wilson_interval;
use std::collections::BTreeMap;

/// A belief that reached the next decision point, with its reservoir key and
/// the true state it arrived with.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub(super) struct Arrival<const N: usize> {
    pub key: u64,
    pub belief: Belief<N>,
    pub x: Vector<N>,
}

/// Sums over segments of their length and energy (both cost models, with
/// second moments): what a chunk holds and what merging chunks adds up.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub(super) struct SegmentSums {
    pub samples: u32,
    pub steps: u64,
    pub transmissions: u64,
    /// Σ over segments of transmissions² (the energy's second moment).
    pub transmissions_sq: u64,
    /// Σ over slots of γ̄(δ, m) (the paper's cost model).
    pub expected_transmissions: f64,
    /// Σ over segments of (Σ over its slots of γ̄)².
    pub expected_sq: f64,
}

impl SegmentSums {
    /// One segment's steps, transmissions and Σ γ̄ (its sample is counted
    /// by the chunk that holds it).
    pub fn add_segment(&mut self, steps: u32, transmissions: u32, expected: f64) {
        self.steps += u64::from(steps);
        self.transmissions += u64::from(transmissions);
        self.transmissions_sq += u64::from(transmissions) * u64::from(transmissions);
        self.expected_transmissions += expected;
        self.expected_sq += expected * expected;
    }

    pub fn merge(&mut self, o: &Self) {
        etp_shared::add_fields!(
            self, o;
            samples, steps, transmissions, transmissions_sq, expected_transmissions, expected_sq
        );
    }
}

/// Raw sums of a chunk of segments of one (state, action).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub(super) struct ChunkTally<const N: usize> {
    pub sums: SegmentSums,
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
    pub sums: SegmentSums,
    pub counts: BTreeMap<Next, u32>,
    /// Arrivals in a region without a state (held-out sets only).
    pub unmatched: u32,
}

impl ChoiceTally {
    /// Add a chunk; `next_of(k)` is the next state of the chunk's k-th
    /// arrival (`None`: a region without a state).
    pub fn add<const N: usize>(
        &mut self,
        c: &ChunkTally<N>,
        next_of: impl Fn(usize) -> Option<u32>,
    ) {
        self.sums.merge(&c.sums);
        let mut bump = |n: Next, k: u32| {
            if k > 0 {
                *self.counts.entry(n).or_insert(0) += k;
            }
        };
        bump(Next::Collision, c.collisions);
        bump(Next::Target, c.target);
        bump(Next::Free, c.free);
        for k in 0..c.arrivals.len() {
            match next_of(k) {
                Some(j) => bump(Next::State(j), 1),
                None => self.unmatched += 1,
            }
        }
    }

    /// The held-out estimate (same cost conventions as [`Self::into_choice`]).
    pub fn into_holdout(self, cost: f64) -> Holdout {
        let s = self.sums;
        let n = f64::from(s.samples.max(1));
        Holdout {
            samples: s.samples,
            cost_counted: s.transmissions as f64 * cost / n,
            cost_model: s.expected_transmissions * cost / n,
            counts: self.counts.into_iter().collect(),
            unmatched: self.unmatched,
        }
    }

    /// The MDP choice: frequencies, Wilson intervals, counted and model costs
    /// (`cost` = energy per transmission c_m of the leg's sensor) with their
    /// second moments, and `cost_range` = `k_max · c_m`.
    pub fn into_choice(self, action: u16, cost: f64, cost_range: f64) -> Choice {
        let s = self.sums;
        let n = f64::from(s.samples.max(1));
        let transitions = transitions_of(self.counts, s.samples, self.unmatched);
        Choice {
            action,
            samples: s.samples,
            cost_counted: s.transmissions as f64 * cost / n,
            cost_model: s.expected_transmissions * cost / n,
            mean_steps: s.steps as f64 / n,
            transitions,
            cost_sq_counted: s.transmissions_sq as f64 * cost * cost / n,
            cost_sq_model: s.expected_sq * cost * cost / n,
            cost_range,
            holdout: None,
            unmatched: self.unmatched,
        }
    }
}

/// Transitions from segment counts: probabilities over the segments that
/// reached a state or terminal (`samples − unmatched`), Wilson 95 % intervals
/// over all `samples`.
pub(super) fn transitions_of(
    counts: BTreeMap<Next, u32>,
    samples: u32,
    unmatched: u32,
) -> Vec<Transition> {
    let matched = f64::from((samples - unmatched.min(samples)).max(1));
    counts
        .into_iter()
        .map(|(next, count)| {
            let (ci_low, ci_high) = wilson_interval(u64::from(count), u64::from(samples));
            Transition {
                next,
                count,
                probability: f64::from(count) / matched,
                ci_low,
                ci_high,
            }
        })
        .collect()
}
