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
use super::on_policy::{PoolPolicy, next_reach, offered_choices, on_policy_weights, state_key};
use super::pool::{bottom_k, weighted_pool};
use super::segments::{CHUNK, ExtraTask, Particle, Task, run_task, tasks_of};
use super::tally::{ChoiceTally, ChunkTally};
use super::{AbstractionError, AbstractionParams, Descriptor, RangeRule, resolve_descriptor};
use crate::mdp::{KfConvergenceParams, Mdp, Method, State};
use etp_shared::discretization::{
    DecisionPointBins, Discretization, Region, RegionSplit, WorkspaceMarginal, refine_region,
};
use etp_shared::episode::{CompiledScenario, LegMode};
use etp_shared::etkf::{Matrix, Threshold};
use etp_shared::linalg::to_dynamic;
use etp_shared::scenario::Scenario;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// A state of the current layer: its region and its pool particles (drawn
/// in proportion to `cumulative` where an on-policy pool kept weights).
struct LayerState<const N: usize> {
    region: Region,
    particles: Vec<Particle<N>>,
    cumulative: Option<Vec<f64>>,
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
    /// On-policy: simulate only the actions the policy takes (ω > 0) at
    /// each state — all that predicting the policy itself needs, at a
    /// fraction of the cost. Its states offer only those choices.
    pub policy_only: bool,
}

/// ω of the pool policy at each state of the layer, looked up by the
/// state's first particle (all of a state's particles share its region).
fn layer_omegas<const N: usize>(
    omega: PoolPolicy<'_>,
    dp: usize,
    layer: &[LayerState<N>],
) -> Vec<Vec<f64>> {
    layer
        .iter()
        .map(|ls| {
            ls.particles
                .first()
                .map(|p| omega(dp, &to_dynamic(&p.belief.cov)))
                .unwrap_or_default()
        })
        .collect()
}

pub(super) fn build<const N: usize>(
    scenario: &Scenario,
    cs: &CompiledScenario<N>,
    params: &AbstractionParams,
    kf: Option<KfConvergenceParams>,
    extra: &[Vec<u32>],
    given: Option<&Given<'_>>,
    progress: &dyn crate::exec::Work,
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
            progress.progress(deltas.len() as u64 * u64::from(samples + holdout));
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
        // ω of the pool policy at each state, and the (state, action)
        // pairs simulated: all, or with `policy_only` the policy's own.
        let omegas = policy.map(|omega| layer_omegas(omega, dp, &layer));
        let policy_only = given.is_some_and(|g| g.policy_only);
        let offered = offered_choices(layer.len(), deltas.len(), omegas.as_deref(), policy_only);
        let keys: Vec<u64> = layer
            .iter()
            .enumerate()
            .map(|(i, ls)| state_key(i, &ls.region, policy.is_some()))
            .collect();
        // Main and held-out segments in one parallel pass (the held-out ones
        // start from the same pool particles, with their own stream).
        let mut tasks = tasks_of(&offered, samples, false);
        let n_main = tasks.len();
        tasks.extend(tasks_of(&offered, holdout, true));
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
                keys[t.state],
                t,
            )
        };
        // A decision point is worth |Δ| · M units (`progress_total`), spread
        // over the offered choices: segment position g of C · M maps to
        // unit g · |Δ| / C.
        let (units, n_choices) = (deltas.len() as u64, offered.len().max(1) as u64);
        // Through the executor: on several ranks each simulates a contiguous
        // slice of the tasks and every rank receives all results (exec.rs).
        let task_units = |i: usize| {
            let t = tasks[i];
            let m = u64::from(if t.holdout { holdout } else { samples });
            let g = t.choice as u64 * m;
            let unit = |pos: u64| pos * units / n_choices;
            unit(g + u64::from(t.hi)) - unit(g + u64::from(t.lo))
        };
        let mut results: Vec<ChunkTally<N>> =
            crate::exec::map(progress, tasks.len(), |i| run(tasks[i]), task_units)?;
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
        let extra_task = |i: usize| {
            let t = extra_tasks[i];
            run(Task {
                state: t.state,
                action: t.action,
                choice: 0,
                lo: t.lo,
                hi: t.hi,
                holdout: false,
            })
        };
        let extra_results: Vec<ChunkTally<N>> =
            crate::exec::map(progress, extra_tasks.len(), extra_task, |_| 0)?;

        // The next layer's bins and the region of every arrival.
        let next_classifier = if last {
            None
        } else {
            let range = match (&workspace, params.range) {
                // Given bins carry their own range.
                _ if given.is_some() => lambda,
                (Some(w), RangeRule::Arrivals) => {
                    arrival_range(&results, w, lambda.0, progress)?.unwrap_or(lambda)
                }
                _ => lambda,
            };
            let mut covs = results
                .iter()
                .flat_map(|r| r.arrivals.iter().map(|a| a.belief.cov));
            Some(classifier_for(dp + 1, &mut covs, range))
        };
        // Each chunk's arrivals classified into the next decision point's
        // regions (none after the last leg); through the executor, so that
        // on several ranks each classifies a slice (an eigen-decomposition
        // per arrival: several per cent of a synthesis, serial if every rank
        // did them all).
        let regions_of = |chunks: &[ChunkTally<N>]| -> Result<Vec<Vec<Region>>, AbstractionError> {
            Ok(match &next_classifier {
                Some(c) => crate::exec::map(
                    progress,
                    chunks.len(),
                    |i| {
                        chunks[i]
                            .arrivals
                            .iter()
                            .map(|a| c.classify(&a.belief.cov))
                            .collect()
                    },
                    |_| 0,
                )?,
                None => Vec::new(),
            })
        };
        let arrival_regions = regions_of(&results)?;
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
        let held_regions = regions_of(&held)?;

        let extra_regions = regions_of(&extra_results)?;

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
        // `offered` is in state order: each state takes the next run of it.
        let mut next_choice = 0;
        for (s, ls) in layer.iter().enumerate() {
            let mut choices = Vec::with_capacity(deltas.len());
            while let Some(&(_, a)) = offered.get(next_choice).filter(|(st, _)| *st == s) {
                let c = next_choice;
                next_choice += 1;
                let mut tally = ChoiceTally::default();
                let first = c * per_choice;
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
                    let first = c * per_holdout;
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
        let weights = omegas.as_ref().map(|omegas| {
            let w = on_policy_weights(&offered, omegas, &reach);
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
            // Chunks are in (offered choice, chunk) order.
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
