//! The segments of a layer: units of work over (state, action) pairs, and
//! the simulation of one unit from the state's pool (docs/MODEL.md §4).

use super::pool::{key, weighted_index};
use super::tally::{Arrival, ChunkTally};
use etp_shared::episode::{AgentState, CompiledScenario, LegEnd, LegMode};
use etp_shared::etkf::{Belief, Vector, sample_belief};
use etp_shared::rng::{mix64, stream_rng, streams};
use rand::RngExt;

/// Segments per work unit: small enough to balance 2 cores when a decision
/// point has a single state, large enough to amortise scheduling.
pub(super) const CHUNK: u32 = 128;

/// The random-stream index of segment `m` of (decision point, state, action),
/// the state named by its [`state_key`].
#[inline]
pub(super) fn segment_id(dp: usize, state_key: u64, action: usize, m: u32) -> u64 {
    mix64(mix64(mix64(dp as u64 + 1) ^ state_key) ^ action as u64) ^ u64::from(m)
}

/// One unit of work: segments `lo..hi` of (state, action) at a decision point.
#[derive(Debug, Clone, Copy)]
pub(super) struct Task {
    pub(super) state: usize,
    pub(super) action: usize,
    /// The (state, action) pair's place among the layer's offered choices.
    pub(super) choice: usize,
    pub(super) lo: u32,
    pub(super) hi: u32,
    /// A held-out segment (stream `HOLDOUT`, cross-fitting) instead of a main one.
    pub(super) holdout: bool,
}

/// Extra segments of sample allocation: segment indices from `samples` on
/// (same stream as the main ones, fresh indices), counted into the choice but
/// kept out of the pools and the region set, so the state space is unchanged.
#[derive(Debug, Clone, Copy)]
pub(super) struct ExtraTask {
    pub(super) state: usize,
    pub(super) action: usize,
    pub(super) lo: u32,
    pub(super) hi: u32,
}

/// The tasks of every offered (state, action) of a layer: `samples` segments
/// each, in chunks, in (state, action, chunk) order.
pub(super) fn tasks_of(choices: &[(usize, usize)], samples: u32, holdout: bool) -> Vec<Task> {
    choices
        .iter()
        .enumerate()
        .flat_map(|(choice, &(state, action))| {
            (0..samples.div_ceil(CHUNK)).map(move |c| Task {
                state,
                action,
                choice,
                lo: c * CHUNK,
                hi: ((c + 1) * CHUNK).min(samples),
                holdout,
            })
        })
        .collect()
}

/// A pool particle: a belief that arrived, and on-policy the true
/// state it arrived with (docs/MODEL.md §7.3). Without a carried state a
/// segment draws its true state from N(x̂, P).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Particle<const N: usize> {
    pub(super) belief: Belief<N>,
    pub(super) x: Option<Vector<N>>,
}

/// Simulate the segments of one task.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_task<const N: usize>(
    cs: &CompiledScenario<N>,
    dp: usize,
    last: bool,
    particles: &[Particle<N>],
    cumulative: Option<&[f64]>,
    mode: &LegMode<N>,
    seed: u64,
    state_key: u64,
    t: Task,
) -> ChunkTally<N> {
    let mut c = ChunkTally::<N>::default();
    c.sums.samples = t.hi - t.lo;
    if !last {
        c.arrivals.reserve((t.hi - t.lo) as usize);
    }
    let stream = if t.holdout {
        streams::HOLDOUT
    } else {
        streams::SYNTHESIS
    };
    for m in t.lo..t.hi {
        let id = segment_id(dp, state_key, t.action, m);
        let mut rng = stream_rng(seed, stream, id);
        let start = match cumulative {
            Some(c) => particles[weighted_index(c, rng.random::<f64>())],
            None if particles.len() == 1 => particles[0],
            None => particles[rng.random_range(0..particles.len())],
        };
        // A carried true state replaces the Gaussian draw (and its random
        // numbers: the segment's stream moves on from there).
        let mut st = AgentState {
            x: match start.x {
                Some(x) => x,
                None => sample_belief(&start.belief, &mut rng),
            },
            belief: start.belief,
        };
        // The segment's own radio channels (docs/MODEL.md §8): transitions
        // and energy include the loss; an ideal radio draws nothing.
        let mut channels = cs.channels(seed, stream, id);
        let r = cs.run_leg(dp, &mut st, mode, &mut rng, &mut channels, &mut ());
        c.sums
            .add_segment(r.steps, r.transmissions, r.expected_transmissions);
        match r.end {
            LegEnd::Collision { .. } => c.collisions += 1,
            LegEnd::Terminated if last => {
                if cs.in_target(&st.x) {
                    c.target += 1;
                } else {
                    c.free += 1;
                }
            }
            LegEnd::Terminated => c.arrivals.push(Arrival {
                key: key(id),
                belief: st.belief,
                x: st.x,
            }),
        }
    }
    c
}
