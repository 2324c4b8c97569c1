//! One layer of the Monte Carlo engine (docs/MODEL.md §4, `layers.rs`):
//! simulate the offered (state, action) choices from the layer's pools,
//! classify the arrivals into the next decision point's regions, tally each
//! choice's transitions and costs, and draw the next layer's pools.

use super::layers::{Classifier, LayerState};
use super::pool::{bottom_k, weighted_pool};
use super::segments::{CHUNK, ExtraTask, Particle, Task, run_task, tasks_of};
use super::tally::{ChoiceTally, ChunkTally};
use super::{AbstractionError, AbstractionParams};
use crate::mdp::State;
use etp_shared::discretization::Region;
use etp_shared::episode::{CompiledScenario, LegMode};
use std::collections::BTreeMap;

/// What one chunk of segments of a layer needs.
pub(super) struct LayerRun<'a, const N: usize> {
    pub(super) cs: &'a CompiledScenario<N>,
    pub(super) seed: u64,
    pub(super) dp: usize,
    pub(super) last: bool,
    pub(super) layer: &'a [LayerState<N>],
    pub(super) modes: Vec<LegMode<N>>,
    /// Each state's key in the segments' random streams.
    pub(super) keys: Vec<u64>,
}

impl<const N: usize> LayerRun<'_, N> {
    /// One chunk of segments of (state, action) from the state's pool.
    pub(super) fn run(&self, t: Task) -> ChunkTally<N> {
        run_task(
            self.cs,
            self.dp,
            self.last,
            &self.layer[t.state].particles,
            self.layer[t.state].cumulative.as_deref(),
            &self.modes[t.action],
            self.seed,
            self.keys[t.state],
            t,
        )
    }
}

/// A layer's simulated segments: the main sample's chunks (in (offered
/// choice, chunk) order), the held-out ones, and the extra segments of
/// sample allocation with their tasks.
pub(super) struct LayerSegments<const N: usize> {
    pub(super) main: Vec<ChunkTally<N>>,
    pub(super) held: Vec<ChunkTally<N>>,
    pub(super) extra_tasks: Vec<ExtraTask>,
    pub(super) extra: Vec<ChunkTally<N>>,
}

/// Simulate the offered choices of a layer whose first state has global
/// index `first_state`.
pub(super) fn simulate_layer<const N: usize>(
    run: &LayerRun<'_, N>,
    params: &AbstractionParams,
    offered: &[(usize, usize)],
    extra: &[Vec<u32>],
    first_state: usize,
    progress: &dyn crate::exec::Work,
) -> Result<LayerSegments<N>, AbstractionError> {
    let (samples, holdout) = (params.samples, params.holdout_samples);
    let actions = run.modes.len();
    // Main and held-out segments in one parallel pass (the held-out ones
    // start from the same pool particles, with their own stream).
    let mut tasks = tasks_of(offered, samples, false);
    let n_main = tasks.len();
    tasks.extend(tasks_of(offered, holdout, true));
    // A decision point is worth |Δ| · M units (`progress_total`), spread
    // over the offered choices: segment position g of C · M maps to
    // unit g · |Δ| / C.
    let (units, n_choices) = (actions as u64, offered.len().max(1) as u64);
    // Through the executor: on several ranks each simulates a contiguous
    // slice of the tasks and every rank receives all results (exec.rs).
    let task_units = |i: usize| {
        let t = tasks[i];
        let m = u64::from(if t.holdout { holdout } else { samples });
        let g = t.choice as u64 * m;
        let unit = |pos: u64| pos * units / n_choices;
        unit(g + u64::from(t.hi)) - unit(g + u64::from(t.lo))
    };
    let mut main: Vec<ChunkTally<N>> =
        crate::exec::map(progress, tasks.len(), |i| run.run(tasks[i]), task_units)?;
    let held: Vec<ChunkTally<N>> = main.split_off(n_main);
    // Extra segments of sample allocation for this layer's states.
    let extra_tasks: Vec<ExtraTask> = (0..run.layer.len())
        .flat_map(|state| {
            let global = first_state + state;
            (0..actions).flat_map(move |action| {
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
        run.run(Task {
            state: t.state,
            action: t.action,
            choice: 0,
            lo: t.lo,
            hi: t.hi,
            holdout: false,
        })
    };
    let extra = crate::exec::map(progress, extra_tasks.len(), extra_task, |_| 0)?;
    Ok(LayerSegments {
        main,
        held,
        extra_tasks,
        extra,
    })
}

/// The next decision point's region of every arrival of a layer's segments
/// (none after the last leg), and the state index of each region the main
/// sample reached.
pub(super) struct Regions {
    pub(super) main: Vec<Vec<Region>>,
    /// The held-out arrivals' regions (same bins; a region the main sample
    /// did not reach has no state and is counted as unmatched).
    pub(super) held: Vec<Vec<Region>>,
    pub(super) extra: Vec<Vec<Region>>,
    pub(super) index: BTreeMap<Region, u32>,
}

impl Regions {
    /// Classify every arrival of `sim`; the next layer's states are numbered
    /// from `next_offset` in region order.
    pub(super) fn of<const N: usize>(
        next: Option<&Classifier>,
        sim: &LayerSegments<N>,
        next_offset: usize,
        progress: &dyn crate::exec::Work,
    ) -> Result<Self, AbstractionError> {
        // Each chunk's arrivals classified into the next decision point's
        // regions; through the executor, so that on several ranks each
        // classifies a slice (an eigen-decomposition per arrival: several per
        // cent of a synthesis, serial if every rank did them all).
        let regions_of = |chunks: &[ChunkTally<N>]| -> Result<Vec<Vec<Region>>, AbstractionError> {
            Ok(match next {
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
        let main = regions_of(&sim.main)?;
        let mut index: BTreeMap<Region, u32> = BTreeMap::new();
        for r in main.iter().flatten() {
            if !index.contains_key(r) {
                index.insert(r.clone(), 0);
            }
        }
        for (k, v) in index.values_mut().enumerate() {
            *v = u32::try_from(next_offset + k).map_err(|_| AbstractionError::TooManyStates)?;
        }
        Ok(Self {
            held: regions_of(&sim.held)?,
            extra: regions_of(&sim.extra)?,
            main,
            index,
        })
    }

    /// The state index of arrival `j` of a segment whose arrivals fell in
    /// `regions` (None: a region without a state).
    pub(super) fn state_of(&self, regions: Option<&Vec<Region>>, j: usize) -> Option<u32> {
        regions
            .and_then(|rs| rs.get(j))
            .and_then(|reg| self.index.get(reg))
            .copied()
    }
}

/// Segments and plant steps simulated in all.
#[derive(Default)]
pub(super) struct Totals {
    pub(super) segments: u64,
    pub(super) steps: u64,
}

/// The states of a layer with their choices' transitions and costs, chunks
/// merged in order, pushed onto `states`. `cost` is (the leg's sensor's
/// cost of one transmission, the leg's cost range).
#[allow(clippy::too_many_arguments)]
pub(super) fn tally_layer<const N: usize>(
    states: &mut Vec<State>,
    totals: &mut Totals,
    dp: usize,
    layer: &[LayerState<N>],
    offered: &[(usize, usize)],
    sim: &LayerSegments<N>,
    regions: &Regions,
    params: &AbstractionParams,
    (cost, cost_range): (f64, f64),
) {
    let (samples, holdout) = (params.samples, params.holdout_samples);
    let per_choice = samples.div_ceil(CHUNK) as usize;
    let per_holdout = holdout.div_ceil(CHUNK) as usize;
    // `offered` is in state order: each state takes the next run of it.
    let mut next_choice = 0;
    for (s, ls) in layer.iter().enumerate() {
        let mut choices = Vec::new();
        while let Some(&(_, a)) = offered.get(next_choice).filter(|(st, _)| *st == s) {
            let c = next_choice;
            next_choice += 1;
            let mut tally = ChoiceTally::default();
            let first = c * per_choice;
            for (k, r) in sim.main[first..first + per_choice].iter().enumerate() {
                let rs = regions.main.get(first + k);
                // Every main-sample arrival's region has a state.
                tally.add(r, |j| Some(regions.state_of(rs, j).unwrap_or(u32::MAX)));
            }
            for (k, (t, r)) in sim.extra_tasks.iter().zip(&sim.extra).enumerate() {
                if t.state == s && t.action == a {
                    let rs = regions.extra.get(k);
                    tally.add(r, |j| regions.state_of(rs, j));
                }
            }
            totals.segments += u64::from(tally.sums.samples);
            totals.steps += tally.sums.steps;
            // `a` < |Δ| ≤ u16::MAX, checked by the caller.
            let mut choice = tally.into_choice(a as u16, cost, cost_range);
            if holdout > 0 {
                let mut h = ChoiceTally::default();
                let first = c * per_holdout;
                for (k, r) in sim.held[first..first + per_holdout].iter().enumerate() {
                    let rs = regions.held.get(first + k);
                    h.add(r, |j| regions.state_of(rs, j));
                }
                totals.segments += u64::from(h.sums.samples);
                totals.steps += h.sums.steps;
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
}

/// The next layer: per region (in state order from `next_offset`) a
/// bottom-k reservoir of the main sample's arrivals, or with the pool
/// policy's `weights` (per offered choice) a weighted pool.
pub(super) fn next_pool<const N: usize>(
    main: &[ChunkTally<N>],
    regions: Regions,
    weights: Option<&[f64]>,
    params: &AbstractionParams,
    carry: bool,
    next_offset: usize,
) -> Vec<LayerState<N>> {
    let per_choice = params.samples.div_ceil(CHUNK) as usize;
    let cap = params.pool_per_region as usize;
    // (reservoir key, the policy's mass of its source, particle).
    type Bucket<const N: usize> = Vec<(u64, f64, Particle<N>)>;
    let mut buckets: Vec<Bucket<N>> = vec![Vec::new(); regions.index.len()];
    for (i, (r, rs)) in main.iter().zip(&regions.main).enumerate() {
        // Chunks are in (offered choice, chunk) order.
        let w = weights.map_or(1.0, |w| w[i / per_choice]);
        for (a, reg) in r.arrivals.iter().zip(rs) {
            if let Some(&j) = regions.index.get(reg) {
                let p = Particle {
                    belief: a.belief,
                    x: carry.then_some(a.x),
                };
                buckets[j as usize - next_offset].push((a.key, w, p));
            }
        }
    }
    let on_policy = weights.is_some();
    regions
        .index
        .into_keys()
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
        .collect()
}
