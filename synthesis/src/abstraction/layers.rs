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
use super::layer_steps::{LayerRun, Regions, Totals, next_pool, simulate_layer, tally_layer};
use super::on_policy::{PoolPolicy, next_reach, offered_choices, on_policy_weights, state_key};
use super::segments::Particle;
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

/// A state of the current layer: its region and its pool particles (drawn
/// in proportion to `cumulative` where an on-policy pool kept weights).
pub(super) struct LayerState<const N: usize> {
    pub(super) region: Region,
    pub(super) particles: Vec<Particle<N>>,
    pub(super) cumulative: Option<Vec<f64>>,
}

/// How beliefs are mapped to states at a decision point.
pub(super) enum Classifier {
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
    pub(super) fn classify<const N: usize>(&self, cov: &Matrix<N, N>) -> Region {
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
    let p_kf = steady_state_posteriors(cs);
    let (workspace, lambda) = workspace_and_range(scenario, cs, params, &p_kf);
    let binning = Binning {
        params,
        given,
        workspace: workspace.as_ref(),
    };
    let legs = cs.legs.len();
    let mut classifier = binning.classifier(0, &mut std::iter::once(cs.initial.cov), lambda);
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
    let mut totals = Totals::default();
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
            progress
                .progress(deltas.len() as u64 * u64::from(params.samples + params.holdout_samples));
            classifier = binning.classifier::<N>(dp + 1, &mut std::iter::empty(), lambda);
            continue;
        }
        let last = dp + 1 == legs;
        // ω of the pool policy at each state, and the (state, action)
        // pairs simulated: all, or with `policy_only` the policy's own.
        let omegas = policy.map(|omega| layer_omegas(omega, dp, &layer));
        let policy_only = given.is_some_and(|g| g.policy_only);
        let offered = offered_choices(layer.len(), deltas.len(), omegas.as_deref(), policy_only);
        let run = LayerRun {
            cs,
            seed: params.seed,
            dp,
            last,
            layer: &layer,
            modes: leg_modes(deltas, kf, &p_kf, cs.legs[dp].sensor),
            keys: layer
                .iter()
                .enumerate()
                .map(|(i, ls)| state_key(i, &ls.region, policy.is_some()))
                .collect(),
        };
        let sim = simulate_layer(&run, params, &offered, extra, states.len(), progress)?;

        // The next layer's bins and the region of every arrival.
        let next_classifier = if last {
            None
        } else {
            let range = match (&workspace, params.range) {
                // Given bins carry their own range.
                _ if given.is_some() => lambda,
                (Some(w), RangeRule::Arrivals) => {
                    arrival_range(&sim.main, w, lambda.0, progress)?.unwrap_or(lambda)
                }
                _ => lambda,
            };
            let mut covs = sim
                .main
                .iter()
                .flat_map(|r| r.arrivals.iter().map(|a| a.belief.cov));
            Some(binning.classifier(dp + 1, &mut covs, range))
        };
        let next_offset = states.len() + layer.len();
        let regions = Regions::of(next_classifier.as_ref(), &sim, next_offset, progress)?;
        let cost = cs.filters[cs.legs[dp].sensor].cost();
        tally_layer(
            &mut states,
            &mut totals,
            dp,
            &layer,
            &offered,
            &sim,
            &regions,
            params,
            // A leg lasts at most k_max steps, one transmission each.
            (cost, f64::from(cs.k_max) * cost),
        );

        // The next pool: a bottom-k reservoir per region; with a pool policy,
        // weighted by the policy's mass of the arrival's (state, action).
        let weights = omegas.as_ref().map(|omegas| {
            let w = on_policy_weights(&offered, omegas, &reach);
            reach = next_reach(
                &states[states.len() - layer.len()..],
                &w,
                next_offset,
                regions.index.len(),
            );
            w
        });
        let carry = given.is_some_and(|g| g.carry_state);
        layer = next_pool(
            &sim.main,
            regions,
            weights.as_deref(),
            params,
            carry,
            next_offset,
        );
        if let Some(c) = next_classifier {
            classifier = c;
        }
    }
    Ok(assemble(
        scenario, params, kf, given, dp_bins, states, totals,
    ))
}

/// P_KF per sensor, once (the Riccati iteration is not free). Only the
/// sensors serving a leg are needed; computed in parallel.
fn steady_state_posteriors<const N: usize>(cs: &CompiledScenario<N>) -> Vec<Matrix<N, N>> {
    (0..cs.filters.len())
        .into_par_iter()
        .map(|s| {
            if cs.legs.iter().any(|l| l.sensor == s) {
                cs.filters[s].steady_state_posterior()
            } else {
                Matrix::<N, N>::zeros()
            }
        })
        .collect()
}

/// The workspace marginal of the descriptor (None: per-axis bins) and the
/// eigenvalue range (λ_lo, λ_hi) the bins cover.
fn workspace_and_range<const N: usize>(
    scenario: &Scenario,
    cs: &CompiledScenario<N>,
    params: &AbstractionParams,
    p_kf: &[Matrix<N, N>],
) -> (Option<WorkspaceMarginal>, (f64, f64)) {
    let deltas = &scenario.deltas;
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
                p_kf,
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
        None => magnitude_range(cs, deltas, p_kf),
    };
    (
        workspace.map(|(_, w)| w),
        (range.lambda_lo, range.lambda_hi),
    )
}

/// How each decision point's classifier is made.
struct Binning<'a> {
    params: &'a AbstractionParams,
    given: Option<&'a Given<'a>>,
    workspace: Option<&'a WorkspaceMarginal>,
}

impl Binning<'_> {
    /// The classifier of decision point `dp`: given bins (with their
    /// splits), else bins from the covariances that arrived there.
    fn classifier<const N: usize>(
        &self,
        dp: usize,
        covs: &mut dyn Iterator<Item = Matrix<N, N>>,
        lambda: (f64, f64),
    ) -> Classifier {
        match self.params.method {
            Method::Discretized => {
                match self
                    .given
                    .and_then(|g| Some((g, g.bins.decision_points.get(dp)?)))
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
                        bins: bins_from(self.params, lambda, self.workspace, covs),
                        dp,
                        splits: Vec::new(),
                    },
                }
            }
            Method::KfConvergence => Classifier::Single,
        }
    }
}

/// The leg mode of each threshold of Δ on the leg served by `sensor`.
fn leg_modes<const N: usize>(
    deltas: &[f64],
    kf: Option<KfConvergenceParams>,
    p_kf: &[Matrix<N, N>],
    sensor: usize,
) -> Vec<LegMode<N>> {
    deltas
        .iter()
        .map(|&d| {
            let threshold = Threshold::new(d);
            match kf {
                None => LegMode::EventTriggered(threshold),
                Some(k) => LegMode::KfConvergence {
                    threshold,
                    eps_kf: k.eps_kf,
                    eps_p: k.eps_p,
                    p_kf: p_kf[sensor],
                },
            }
        })
        .collect()
}

/// The MDP of the built layers.
fn assemble(
    scenario: &Scenario,
    params: &AbstractionParams,
    kf: Option<KfConvergenceParams>,
    given: Option<&Given<'_>>,
    dp_bins: Vec<DecisionPointBins>,
    states: Vec<State>,
    totals: Totals,
) -> Mdp {
    Mdp {
        scenario_name: scenario.name.clone(),
        scenario_hash: scenario.content_hash.clone(),
        method: params.method,
        deltas: scenario.deltas.clone(),
        discretization: match params.method {
            Method::Discretized => Some(Discretization {
                decision_points: dp_bins,
            }),
            Method::KfConvergence => None,
        },
        kf_convergence: kf,
        states,
        initial: 0,
        samples_per_choice: params.samples,
        holdout_samples: params.holdout_samples,
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
        total_segments: totals.segments,
        total_steps: totals.steps,
        splits: given.map(|g| g.splits.to_vec()).unwrap_or_default(),
    }
}

#[cfg(test)]
#[path = "layers_tests.rs"]
mod tests;
