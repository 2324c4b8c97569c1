//! The layered Monte Carlo engine shared by both methods (docs/MODEL.md §4):
//!
//! ```text
//! pool_0 = { initial belief }
//! for each decision point i:
//!     S_i = regions occupied by pool_i
//!     for each s in S_i, each δ in Δ:
//!         draw M start particles from pool_i in s; x ~ N(x̂, P), or the
//!             particle's carried true state (on-policy pools, MODEL §7.3)
//!         simulate leg i → collision | arrival belief | (last leg) target / free
//!     bins_{i+1} from the arrivals (nominal axes of their mean covariance)
//!     T(s, δ, ·) = frequencies; C(s, δ) = mean transmissions × c_m
//!     pool_{i+1} = per-region bottom-k reservoir of the arrivals (on-policy:
//!         a sample in proportion to the policy's mass, pool.rs)
//! ```

use super::bounds::{arrival_range, bins_from, magnitude_range, workspace_ranges};
use super::pool::{bottom_k, key, weighted_index, weighted_pool};
use super::tally::{Arrival, ChoiceTally, ChunkTally};
use super::{AbstractionError, AbstractionParams, Descriptor, RangeRule, resolve_descriptor};
use crate::mdp::{KfConvergenceParams, Mdp, Method, State};
use etp_shared::discretization::{
    DecisionPointBins, Discretization, Region, RegionSplit, WorkspaceMarginal, refine_region,
};
use etp_shared::episode::{AgentState, CompiledScenario, LegEnd, LegMode};
use etp_shared::etkf::{Belief, Matrix, Threshold, Vector, sample_belief};
use etp_shared::linalg::to_dynamic;
use etp_shared::rng::{mix64, stream_rng, streams};
use etp_shared::scenario::Scenario;
use rand::RngExt;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Segments per work unit: small enough to balance 2 cores when a decision
/// point has a single state, large enough to amortise scheduling.
const CHUNK: u32 = 128;

/// The random-stream index of segment `m` of (decision point, state, action).
#[inline]
fn segment_id(dp: usize, state: usize, action: usize, m: u32) -> u64 {
    mix64(mix64(mix64(dp as u64 + 1) ^ state as u64) ^ action as u64) ^ u64::from(m)
}

/// One unit of work: segments `lo..hi` of (state, action) at a decision point.
#[derive(Debug, Clone, Copy)]
struct Task {
    state: usize,
    action: usize,
    lo: u32,
    hi: u32,
    /// A held-out segment (stream `HOLDOUT`, cross-fitting) instead of a main one.
    holdout: bool,
}

/// Extra segments of sample allocation: segment indices from `samples` on
/// (same stream as the main ones, fresh indices), counted into the choice but
/// kept out of the pools and the region set, so the state space is unchanged.
#[derive(Debug, Clone, Copy)]
struct ExtraTask {
    state: usize,
    action: usize,
    lo: u32,
    hi: u32,
}

/// The tasks of every (state, action) of a layer: `samples` segments each,
/// in chunks, in (state, action, chunk) order.
fn tasks_of(states: usize, actions: usize, samples: u32, holdout: bool) -> Vec<Task> {
    (0..states)
        .flat_map(|state| {
            (0..actions).flat_map(move |action| {
                (0..samples.div_ceil(CHUNK)).map(move |c| Task {
                    state,
                    action,
                    lo: c * CHUNK,
                    hi: ((c + 1) * CHUNK).min(samples),
                    holdout,
                })
            })
        })
        .collect()
}

/// A state of the current layer: its region and its pool particles (drawn
/// in proportion to `cumulative` where an on-policy pool kept weights).
struct LayerState<const N: usize> {
    region: Region,
    particles: Vec<Particle<N>>,
    cumulative: Option<Vec<f64>>,
}

/// A pool particle: a belief that arrived, and on-policy the true
/// state it arrived with (docs/MODEL.md §7.3). Without a carried state a
/// segment draws its true state from N(x̂, P).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Particle<const N: usize> {
    belief: Belief<N>,
    x: Option<Vector<N>>,
}

/// Simulate the segments of one task.
#[allow(clippy::too_many_arguments)]
fn run_task<const N: usize>(
    cs: &CompiledScenario<N>,
    dp: usize,
    last: bool,
    particles: &[Particle<N>],
    cumulative: Option<&[f64]>,
    mode: &LegMode<N>,
    seed: u64,
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
        let id = segment_id(dp, t.state, t.action, m);
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

/// How beliefs are mapped to states at a decision point.
enum Classifier {
    /// Method 2: covariance regions (at decision point `dp`, refined by the
    /// splits of that decision point, if any).
    Bins {
        bins: DecisionPointBins,
        dp: usize,
        splits: Vec<RegionSplit>,
    },
    /// Method 1: one state per decision point.
    Single,
}

impl Classifier {
    fn classify<const N: usize>(&self, cov: &Matrix<N, N>) -> Region {
        match self {
            Self::Bins { bins, dp, splits } => {
                let cov = to_dynamic(cov);
                let base = bins.classify(&cov);
                if splits.is_empty() {
                    base
                } else {
                    refine_region(splits, *dp, bins, &cov, base)
                }
            }
            Self::Single => Region(Vec::new()),
        }
    }
}

/// Bins and splits fixed in advance (adaptive splitting re-runs the build on
/// the first build's bins, with its splits), instead of bins from the arrivals.
pub(super) struct Given<'a> {
    pub bins: &'a Discretization,
    pub splits: &'a [RegionSplit],
    /// Pools drawn on-policy (docs/MODEL.md §7.3, `--pool-policy`): ω of a
    /// belief (decision point, covariance) over the actions, and the pools
    /// weighted by the probability that this strategy brings a belief there.
    pub policy: Option<PoolPolicy<'a>>,
    /// On-policy pools (unless `--no-carry-state`): particles keep the true
    /// state they arrived with, and segments start from it instead of a
    /// draw from N(x̂, P).
    pub carry_state: bool,
}

/// ω (over the actions) of the strategy the pools are drawn under.
pub(super) type PoolPolicy<'a> = &'a (dyn Fn(usize, &nalgebra::DMatrix<f64>) -> Vec<f64> + Sync);

/// The pool policy's mass of each (state, action) of the layer, in
/// (state, action) order: reach(s) · ω(s, a), ω looked up by the state's
/// first particle (all of a state's particles share its region).
fn on_policy_weights<const N: usize>(
    omega: PoolPolicy<'_>,
    dp: usize,
    layer: &[LayerState<N>],
    reach: &[f64],
    actions: usize,
) -> Vec<f64> {
    let mut w = Vec::with_capacity(layer.len() * actions);
    for (s, ls) in layer.iter().enumerate() {
        let r = reach.get(s).copied().unwrap_or(0.0);
        let o = ls
            .particles
            .first()
            .map(|p| omega(dp, &to_dynamic(&p.belief.cov)))
            .unwrap_or_default();
        w.extend((0..actions).map(|a| r * o.get(a).copied().unwrap_or(0.0)));
    }
    w
}

/// The next layer's reach under the policy from this layer's `states` and
/// their (state, action) masses `w`.
fn next_reach(states: &[State], w: &[f64], next_offset: usize, next_len: usize) -> Vec<f64> {
    let mut reach = vec![0.0; next_len];
    let actions = if states.is_empty() {
        1
    } else {
        w.len() / states.len()
    };
    for (s, st) in states.iter().enumerate() {
        for (a, ch) in st.choices.iter().enumerate() {
            let m = w.get(s * actions + a).copied().unwrap_or(0.0);
            if m <= 0.0 {
                continue;
            }
            for t in &ch.transitions {
                if let crate::mdp::Next::State(j) = t.next
                    && let Some(x) = (j as usize)
                        .checked_sub(next_offset)
                        .and_then(|k| reach.get_mut(k))
                {
                    *x += m * t.probability;
                }
            }
        }
    }
    reach
}

pub(super) fn build<const N: usize>(
    scenario: &Scenario,
    cs: &CompiledScenario<N>,
    params: &AbstractionParams,
    kf: Option<KfConvergenceParams>,
    extra: &[Vec<u32>],
    given: Option<&Given<'_>>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Mdp, AbstractionError> {
    let deltas = &scenario.deltas;
    let samples = params.samples;
    let holdout = params.holdout_samples;
    let cap = params.pool_per_region as usize;
    // P_KF per sensor, once (the Riccati iteration is not free).
    // Only the sensors serving a leg are needed; computed in parallel.
    let p_kf: Vec<Matrix<N, N>> = (0..cs.filters.len())
        .into_par_iter()
        .map(|s| {
            if cs.legs.iter().any(|l| l.sensor == s) {
                cs.filters[s].steady_state_posterior()
            } else {
                Matrix::<N, N>::zeros()
            }
        })
        .collect();
    let descriptor = resolve_descriptor(scenario, params.descriptor);
    let workspace = match (descriptor, &scenario.workspace) {
        (Descriptor::WorkspaceMarginal, c) => {
            // Without a map the workspace is the state itself (C = I).
            let c = c
                .clone()
                .unwrap_or_else(|| nalgebra::DMatrix::identity(N, N));
            // Bin the workspace marginal `lookahead` silent steps ahead:
            // C F^h P F^hᵀ Cᵀ (MODEL.md §7.3).
            let c =
                etp_shared::discretization::lookahead_map(&c, &scenario.plant.f, params.lookahead);
            let probe = WorkspaceMarginal::new(&c, 1.0, 1.0, params.rest_bins);
            let (range, rest) = workspace_ranges(
                cs,
                deltas,
                &p_kf,
                &|m| probe.marginal(&to_dynamic(m)),
                &|m| probe.rest(&to_dynamic(m)),
            );
            Some((
                range,
                WorkspaceMarginal::new(&c, rest.0, rest.1, params.rest_bins),
            ))
        }
        _ => None,
    };
    let range = match &workspace {
        Some((r, _)) => *r,
        None => magnitude_range(cs, deltas, &p_kf),
    };
    let workspace = workspace.map(|(_, w)| w);
    let lambda = (range.lambda_lo, range.lambda_hi);
    let legs = cs.legs.len();

    // The classifier of decision point `dp`: given bins (with their splits),
    // else bins from the covariances that arrived there.
    let classifier_for = |dp: usize,
                          covs: &mut dyn Iterator<Item = Matrix<N, N>>,
                          lambda: (f64, f64)| match params.method {
        Method::Discretized => match given.and_then(|g| Some((g, g.bins.decision_points.get(dp)?)))
        {
            Some((g, b)) => Classifier::Bins {
                bins: b.clone(),
                dp,
                splits: g
                    .splits
                    .iter()
                    .filter(|s| s.decision_point as usize == dp)
                    .cloned()
                    .collect(),
            },
            None => Classifier::Bins {
                bins: bins_from(params, lambda, workspace.as_ref(), covs),
                dp,
                splits: Vec::new(),
            },
        },
        Method::KfConvergence => Classifier::Single,
    };
    let mut classifier = classifier_for(0, &mut std::iter::once(cs.initial.cov), lambda);
    let mut dp_bins: Vec<DecisionPointBins> = Vec::with_capacity(legs);
    let mut layer = vec![LayerState {
        region: classifier.classify(&cs.initial.cov),
        particles: vec![Particle {
            belief: cs.initial,
            x: None,
        }],
        cumulative: None,
    }];
    let mut states: Vec<State> = Vec::new();
    let (mut total_segments, mut total_steps) = (0u64, 0u64);
    let policy = given.and_then(|g| g.policy);
    // With a pool policy: the probability that it brings a belief to each
    // state of the current layer (under this build's own transitions).
    let mut reach: Vec<f64> = vec![1.0];

    for dp in 0..legs {
        if let Classifier::Bins { bins, .. } = &classifier {
            dp_bins.push(bins.clone());
        }
        if layer.is_empty() {
            // Every segment collided before this decision point.
            progress(deltas.len() as u64 * u64::from(samples + holdout));
            classifier = classifier_for(dp + 1, &mut std::iter::empty(), lambda);
            continue;
        }
        let last = dp + 1 == legs;
        let cost = cs.filters[cs.legs[dp].sensor].cost();
        // A leg lasts at most k_max steps, one transmission each.
        let cost_range = f64::from(cs.k_max) * cost;
        let modes: Vec<LegMode<N>> = deltas
            .iter()
            .map(|&d| {
                let threshold = Threshold::new(d);
                match kf {
                    None => LegMode::EventTriggered(threshold),
                    Some(k) => LegMode::KfConvergence {
                        threshold,
                        eps_kf: k.eps_kf,
                        eps_p: k.eps_p,
                        p_kf: p_kf[cs.legs[dp].sensor],
                    },
                }
            })
            .collect();
        // Main and held-out segments in one parallel pass (the held-out ones
        // start from the same pool particles, with their own stream).
        let mut tasks = tasks_of(layer.len(), deltas.len(), samples, false);
        let n_main = tasks.len();
        tasks.extend(tasks_of(layer.len(), deltas.len(), holdout, true));
        let n_states = layer.len() as u64;
        // One chunk of segments of (state, action) from the state's pool.
        let run = |t: Task| {
            run_task(
                cs,
                dp,
                last,
                &layer[t.state].particles,
                layer[t.state].cumulative.as_deref(),
                &modes[t.action],
                params.seed,
                t,
            )
        };
        let mut results: Vec<ChunkTally<N>> = tasks
            .par_iter()
            .map(|&t| {
                let m = u64::from(if t.holdout { holdout } else { samples });
                let r = run(t);
                // Each action of a decision point is worth `samples` units, spread
                // over its states: position g of S·M maps to unit g / S.
                let g = t.state as u64 * m;
                progress((g + u64::from(t.hi)) / n_states - (g + u64::from(t.lo)) / n_states);
                r
            })
            .collect();
        let held: Vec<ChunkTally<N>> = results.split_off(n_main);
        // Extra segments of sample allocation for this layer's states.
        let extra_tasks: Vec<ExtraTask> = (0..layer.len())
            .flat_map(|state| {
                let global = states.len() + state;
                (0..deltas.len()).flat_map(move |action| {
                    let e = extra
                        .get(global)
                        .and_then(|v| v.get(action))
                        .copied()
                        .unwrap_or(0);
                    (0..e.div_ceil(CHUNK)).map(move |c| ExtraTask {
                        state,
                        action,
                        lo: samples + c * CHUNK,
                        hi: samples + ((c + 1) * CHUNK).min(e),
                    })
                })
            })
            .collect();
        let extra_results: Vec<ChunkTally<N>> = extra_tasks
            .par_iter()
            .map(|t| {
                run(Task {
                    state: t.state,
                    action: t.action,
                    lo: t.lo,
                    hi: t.hi,
                    holdout: false,
                })
            })
            .collect();

        // The next layer's bins and the region of every arrival.
        let next_classifier = if last {
            None
        } else {
            let range = match (&workspace, params.range) {
                // Given bins carry their own range.
                _ if given.is_some() => lambda,
                (Some(w), RangeRule::Arrivals) => {
                    arrival_range(&results, w, lambda.0).unwrap_or(lambda)
                }
                _ => lambda,
            };
            let mut covs = results
                .iter()
                .flat_map(|r| r.arrivals.iter().map(|a| a.belief.cov));
            Some(classifier_for(dp + 1, &mut covs, range))
        };
        // Each chunk's arrivals classified into the next decision point's
        // regions (none after the last leg).
        let regions_of = |chunks: &[ChunkTally<N>]| -> Vec<Vec<Region>> {
            match &next_classifier {
                Some(c) => chunks
                    .par_iter()
                    .map(|r| {
                        r.arrivals
                            .iter()
                            .map(|a| c.classify(&a.belief.cov))
                            .collect()
                    })
                    .collect(),
                None => Vec::new(),
            }
        };
        let arrival_regions = regions_of(&results);
        let mut region_index: BTreeMap<&Region, u32> = BTreeMap::new();
        for r in arrival_regions.iter().flatten() {
            region_index.insert(r, 0);
        }
        let next_offset = states.len() + layer.len();
        for (k, v) in region_index.values_mut().enumerate() {
            *v = u32::try_from(next_offset + k).map_err(|_| AbstractionError::TooManyStates)?;
        }

        // The held-out arrivals' regions (same bins; a region the main sample
        // did not reach has no state and is counted as unmatched).
        let held_regions = regions_of(&held);

        let extra_regions = regions_of(&extra_results);

        // Transitions and costs per (state, action), chunks merged in order.
        // The state index of arrival `j` of a segment whose arrivals fell in
        // `regions` (None: a region without a state).
        let region_of = |regions: Option<&Vec<Region>>, j: usize| {
            regions
                .and_then(|rs| rs.get(j))
                .and_then(|reg| region_index.get(reg))
                .copied()
        };
        let per_choice = samples.div_ceil(CHUNK) as usize;
        let per_holdout = holdout.div_ceil(CHUNK) as usize;
        for (s, ls) in layer.iter().enumerate() {
            let mut choices = Vec::with_capacity(deltas.len());
            for a in 0..deltas.len() {
                let mut tally = ChoiceTally::default();
                let first = (s * deltas.len() + a) * per_choice;
                for (k, r) in results[first..first + per_choice].iter().enumerate() {
                    let regions = arrival_regions.get(first + k);
                    // Every main-sample arrival's region has a state.
                    tally.add(r, |j| Some(region_of(regions, j).unwrap_or(u32::MAX)));
                }
                for (k, (t, r)) in extra_tasks.iter().zip(&extra_results).enumerate() {
                    if t.state == s && t.action == a {
                        let regions = extra_regions.get(k);
                        tally.add(r, |j| region_of(regions, j));
                    }
                }
                total_segments += u64::from(tally.sums.samples);
                total_steps += tally.sums.steps;
                // `a` < |Δ| ≤ u16::MAX, checked by the caller.
                let mut choice = tally.into_choice(a as u16, cost, cost_range);
                if holdout > 0 {
                    let mut h = ChoiceTally::default();
                    let first = (s * deltas.len() + a) * per_holdout;
                    for (k, r) in held[first..first + per_holdout].iter().enumerate() {
                        let regions = held_regions.get(first + k);
                        h.add(r, |j| region_of(regions, j));
                    }
                    total_segments += u64::from(h.sums.samples);
                    total_steps += h.sums.steps;
                    choice.holdout = Some(h.into_holdout(cost));
                }
                choices.push(choice);
            }
            states.push(State {
                decision_point: dp as u32,
                region: ls.region.clone(),
                merged: Vec::new(),
                choices,
            });
        }

        // The next pool: a bottom-k reservoir per region; with a pool policy,
        // weighted by the policy's mass of the arrival's (state, action).
        let weights = policy.map(|omega| {
            let w = on_policy_weights(omega, dp, &layer, &reach, deltas.len());
            reach = next_reach(
                &states[states.len() - layer.len()..],
                &w,
                next_offset,
                region_index.len(),
            );
            w
        });
        let carry = given.is_some_and(|g| g.carry_state);
        // (reservoir key, the policy's mass of its source, particle).
        type Bucket<const N: usize> = Vec<(u64, f64, Particle<N>)>;
        let mut buckets: Vec<Bucket<N>> = vec![Vec::new(); region_index.len()];
        for (i, (r, regions)) in results.iter().zip(&arrival_regions).enumerate() {
            // Chunks are in (state, action, chunk) order.
            let w = weights.as_ref().map_or(1.0, |w| w[i / per_choice]);
            for (a, reg) in r.arrivals.iter().zip(regions) {
                if let Some(&j) = region_index.get(reg) {
                    let p = Particle {
                        belief: a.belief,
                        x: carry.then_some(a.x),
                    };
                    buckets[j as usize - next_offset].push((a.key, w, p));
                }
            }
        }
        let regions: Vec<Region> = region_index.keys().map(|r| (*r).clone()).collect();
        drop(region_index);
        let on_policy = weights.is_some();
        layer = regions
            .into_iter()
            .zip(buckets)
            .map(|(region, items)| {
                let (particles, cumulative) = if on_policy {
                    let pool = weighted_pool(items, cap);
                    (pool.particles, pool.cumulative)
                } else {
                    let keyed = items.into_iter().map(|(k, _, p)| (k, p)).collect();
                    (bottom_k(keyed, cap), None)
                };
                LayerState {
                    region,
                    particles,
                    cumulative,
                }
            })
            .collect();
        if let Some(c) = next_classifier {
            classifier = c;
        }
    }

    Ok(Mdp {
        scenario_name: scenario.name.clone(),
        scenario_hash: scenario.content_hash.clone(),
        method: params.method,
        deltas: deltas.clone(),
        discretization: match params.method {
            Method::Discretized => Some(Discretization {
                decision_points: dp_bins,
            }),
            Method::KfConvergence => None,
        },
        kf_convergence: kf,
        states,
        initial: 0,
        samples_per_choice: samples,
        holdout_samples: holdout,
        looks: 1,
        build: crate::mdp::BuildSettings {
            magnitude_bins: params.bins.magnitude,
            angle_bins: params.bins.angle,
            pool_per_region: params.pool_per_region,
            descriptor: match params.descriptor {
                Descriptor::Auto => 0,
                Descriptor::PerAxis => 1,
                Descriptor::WorkspaceMarginal => 2,
            },
            rest_bins: params.rest_bins,
            lookahead: params.lookahead,
            range: match params.range {
                RangeRule::Propagation => 0,
                RangeRule::Arrivals => 1,
            },
            merge_alpha: 0.0,
        },
        seed: params.seed,
        total_segments,
        total_steps,
        splits: given.map(|g| g.splits.to_vec()).unwrap_or_default(),
    })
}

#[cfg(test)]
#[path = "layers_tests.rs"]
mod tests;
