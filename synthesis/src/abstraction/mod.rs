//! The belief-space abstraction of docs/MODEL.md §4: a finite, acyclic MDP estimated
//! by layered Monte Carlo simulation of legs.
//!
//! * Method 2 ([`Method::Discretized`], the paper's contribution): the state at
//!   decision point i is the covariance region of the belief
//!   ([`etp_shared::discretization`]); start beliefs are drawn from a bounded
//!   pool of beliefs that actually arrived at decision point i.
//! * Method 1 ([`Method::KfConvergence`]): the filter is forced to δ = 0 near
//!   each waypoint until the covariance has converged to `P_KF`, so one state per
//!   decision point suffices (|S| = N + 3 with the terminals).
//!
//! Both methods share one layered engine ([`layers`]): for each decision point,
//! for each state and action, `samples` legs are simulated from start beliefs
//! drawn from the pool particles of that state; outcomes and arrival regions are
//! tallied ([`tally`]), arrivals feed a bounded per-region reservoir
//! ([`pool`]) that becomes the next pool.
//!
//! Determinism: every segment draws its randomness from
//! `stream_rng(seed, streams::SYNTHESIS, id)` with `id` derived from (decision
//! point, state, action, sample), the work is split into fixed chunks whose
//! results are merged in index order, and the reservoir keeps the arrivals with
//! the smallest hash keys — so the MDP is bit-identical for a seed whatever the
//! number of threads. Pure: no I/O, no clock.

pub mod aggregation;
mod bounds;
mod layer_steps;
mod layers;
mod merge;
mod on_policy;
mod pool;
mod segments;
pub mod split;
mod tally;

pub use bounds::{MagnitudeRange, magnitude_range, workspace_ranges};
pub use merge::{MergeError, MergeReport, merge_equivalent};

use crate::mdp::{KfConvergenceParams, Mdp, Method};
use etp_shared::discretization::{BinCounts, Discretization, RegionSplit};
use etp_shared::episode::CompiledScenario;
use etp_shared::scenario::Scenario;
use etp_shared::with_dim;

/// Default Monte Carlo segments per (state, action).
pub const DEFAULT_SAMPLES: u32 = 6000;
/// Default bound on the pool particles kept per region and decision point.
pub const DEFAULT_POOL_PER_REGION: u32 = 2048;
/// Default coarse bins of the uncertainty C does not see (workspace descriptor).
pub const DEFAULT_REST_BINS: u16 = 3;
/// Default lookahead of the workspace descriptor, in steps (MODEL.md §7.3).
pub const DEFAULT_LOOKAHEAD: u32 = 5;

/// How Method 2 describes a belief covariance at a decision point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Descriptor {
    /// The workspace marginal for scenarios with a workspace map `[model] C`,
    /// the paper's per-axis regions otherwise (so their MDPs do not change).
    #[default]
    Auto,
    /// The paper's per-axis (magnitude, angle) bins of all n eigen-axes of P.
    PerAxis,
    /// Per-axis bins of `C P Cᵀ` (d axes) plus `rest_bins` coarse bins of
    /// `tr(Π P Π)` (MODEL.md §7; `etp_shared::discretization::WorkspaceMarginal`).
    WorkspaceMarginal,
}

/// Where the log-uniform magnitude bins of the workspace descriptor lie
/// (MODEL.md §7.3). The paper's per-axis regions always use `Propagation`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RangeRule {
    /// From `P_KF` to the largest covariance of silent propagation at the
    /// largest δ (the paper's rule: fixed before any sample).
    Propagation,
    /// Per decision point, from the smallest eigenvalue the main sample's
    /// arrivals have to the 99.5 % quantile of their largest: the bins lie
    /// where the beliefs are (a double integrator's silent propagation grows
    /// without bound, and most of its range is never visited).
    #[default]
    Arrivals,
}

/// Why an abstraction could not be built.
#[derive(Debug, thiserror::Error)]
pub enum AbstractionError {
    #[error("--samples must be at least 1")]
    NoSamples,
    #[error("the pool bound must be at least 1")]
    NoPool,
    #[error(
        "bin counts must be at least 1 (got {magnitude} magnitude, {angle} angle, {rest} rest bins)"
    )]
    Bins {
        magnitude: u16,
        angle: u16,
        rest: u16,
    },
    #[error("the scenario has no thresholds")]
    NoActions,
    #[error("the scenario has {0} thresholds; at most 65535 are supported")]
    TooManyActions(usize),
    #[error("Method 1 parameters must be finite and positive (eps_kf = {eps_kf}, eps_p = {eps_p})")]
    KfParams { eps_kf: f64, eps_p: f64 },
    #[error("the abstraction has more than u32::MAX states")]
    TooManyStates,
    #[error("splitting: the given bins have {bins} decision points, the scenario {legs} legs")]
    SplitBins { bins: usize, legs: usize },
    #[error(
        "--pool-policy: the strategy must come from a Method 2 (discretized) synthesis of this scenario, with its bins per leg and its thresholds"
    )]
    PoolPolicy,
    #[error(transparent)]
    Exec(#[from] crate::exec::ExecError),
}

/// Settings of one abstraction run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AbstractionParams {
    pub method: Method,
    /// Segments simulated per (state, action).
    pub samples: u32,
    /// Held-out segments per (state, action), from the independent stream
    /// `HOLDOUT`, for cross-fitted predictions (0: none; docs/MODEL.md §4.1).
    pub holdout_samples: u32,
    /// Seed of the random streams.
    pub seed: u64,
    /// Method 2's bins.
    pub bins: BinCounts,
    /// Pool particles kept per region at each decision point (reservoir bound).
    pub pool_per_region: u32,
    /// Method 1's parameters; `None` = [`default_kf_params`] of the scenario.
    pub kf: Option<KfConvergenceParams>,
    /// Method 2's belief descriptor.
    pub descriptor: Descriptor,
    /// Coarse bins of the rest (workspace descriptor only).
    pub rest_bins: u16,
    /// Workspace descriptor: bin `C F^h P F^hᵀ Cᵀ`, h = `lookahead` steps.
    pub lookahead: u32,
    /// Workspace descriptor: where its magnitude bins lie.
    pub range: RangeRule,
}

impl Default for AbstractionParams {
    fn default() -> Self {
        Self {
            method: Method::Discretized,
            samples: DEFAULT_SAMPLES,
            holdout_samples: 0,
            seed: 0,
            bins: BinCounts::default(),
            pool_per_region: DEFAULT_POOL_PER_REGION,
            kf: None,
            descriptor: Descriptor::Auto,
            rest_bins: DEFAULT_REST_BINS,
            lookahead: DEFAULT_LOOKAHEAD,
            range: RangeRule::default(),
        }
    }
}

/// Method 1 defaults for a scenario:
/// * `eps_kf = max(5 u_max, 2 eps_x)`: the full KF switches on five full-speed
///   steps before the waypoint — enough for the Riccati recursion (which
///   contracts by ~(1 − K)² per step) to converge before the mean criterion is met;
/// * `eps_p = 1e-2 · min over sensors of ‖P_KF‖max`: the covariance is within
///   1 % of the steady state, so every leg starts from (practically) the same
///   belief covariance and one state per decision point is justified.
pub fn default_kf_params(scenario: &Scenario) -> KfConvergenceParams {
    let c = &scenario.controller;
    let p_kf_min = with_dim!(scenario.dim, N => {
        let cs = CompiledScenario::<N>::new(scenario);
        cs.filters
            .iter()
            .map(|f| f.steady_state_posterior().amax())
            .fold(f64::INFINITY, f64::min)
    });
    KfConvergenceParams {
        eps_kf: (5.0 * c.u_max).max(2.0 * c.eps_x),
        eps_p: 1e-2 * p_kf_min,
    }
}

/// Total units the progress callback of [`build`] reports: decision points ×
/// actions × (samples + held-out samples).
pub fn progress_total(scenario: &Scenario, params: &AbstractionParams) -> u64 {
    scenario.num_legs() as u64
        * scenario.deltas.len() as u64
        * (u64::from(params.samples) + u64::from(params.holdout_samples))
}

/// The descriptor [`Descriptor::Auto`] stands for on `scenario`.
pub fn resolve_descriptor(scenario: &Scenario, d: Descriptor) -> Descriptor {
    match (d, &scenario.workspace) {
        (Descriptor::Auto, Some(_)) => Descriptor::WorkspaceMarginal,
        (Descriptor::Auto, None) => Descriptor::PerAxis,
        (other, _) => other,
    }
}

/// Build the MDP of `scenario` by layered Monte Carlo (docs/MODEL.md §4).
/// `progress(k)` is called as work finishes; the units add up to
/// [`progress_total`].
pub fn build(
    scenario: &Scenario,
    params: &AbstractionParams,
    progress: &dyn crate::exec::Work,
) -> Result<Mdp, AbstractionError> {
    build_with_extra(scenario, params, &[], progress)
}

/// The parameters an MDP was built with (to repeat the build).
pub fn params_of(mdp: &Mdp) -> AbstractionParams {
    AbstractionParams {
        method: mdp.method,
        samples: mdp.samples_per_choice,
        holdout_samples: mdp.holdout_samples,
        seed: mdp.seed,
        bins: BinCounts {
            magnitude: mdp.build.magnitude_bins,
            angle: mdp.build.angle_bins,
        },
        pool_per_region: mdp.build.pool_per_region,
        kf: mdp.kf_convergence,
        descriptor: match mdp.build.descriptor {
            1 => Descriptor::PerAxis,
            2 => Descriptor::WorkspaceMarginal,
            _ => Descriptor::Auto,
        },
        rest_bins: mdp.build.rest_bins,
        lookahead: mdp.build.lookahead,
        range: match mdp.build.range {
            0 => RangeRule::Propagation,
            _ => RangeRule::Arrivals,
        },
    }
}

/// The checks every build makes before any work.
fn check_params(scenario: &Scenario, params: &AbstractionParams) -> Result<(), AbstractionError> {
    if params.samples == 0 {
        return Err(AbstractionError::NoSamples);
    }
    if params.pool_per_region == 0 {
        return Err(AbstractionError::NoPool);
    }
    if params.bins.magnitude == 0 || params.bins.angle == 0 || params.rest_bins == 0 {
        return Err(AbstractionError::Bins {
            magnitude: params.bins.magnitude,
            angle: params.bins.angle,
            rest: params.rest_bins,
        });
    }
    if scenario.deltas.is_empty() {
        return Err(AbstractionError::NoActions);
    }
    if scenario.deltas.len() > usize::from(u16::MAX) {
        return Err(AbstractionError::TooManyActions(scenario.deltas.len()));
    }
    Ok(())
}

/// [`build`] with `extra[s][a]` more segments for state s and action index a
/// (sample allocation): the same states, pools and main segments as [`build`]
/// with the same parameters, plus the extra segments counted into their
/// choices (an extra arrival in a region without a state is `unmatched`).
pub fn build_with_extra(
    scenario: &Scenario,
    params: &AbstractionParams,
    extra: &[Vec<u32>],
    progress: &dyn crate::exec::Work,
) -> Result<Mdp, AbstractionError> {
    check_params(scenario, params)?;
    let kf = match params.method {
        Method::Discretized => None,
        Method::KfConvergence => {
            let k = params.kf.unwrap_or_else(|| default_kf_params(scenario));
            let ok = |v: f64| v.is_finite() && v > 0.0;
            if !(ok(k.eps_kf) && ok(k.eps_p)) {
                return Err(AbstractionError::KfParams {
                    eps_kf: k.eps_kf,
                    eps_p: k.eps_p,
                });
            }
            Some(k)
        }
    };
    with_dim!(scenario.dim, N => {
        let cs = CompiledScenario::<N>::new(scenario);
        layers::build::<N>(scenario, &cs, params, kf, extra, None, progress)
    })
}

/// [`build`] on given bins refined by `splits` (adaptive splitting,
/// [`split`]): the states are the regions of `bins` refined by the splits,
/// every one sampled afresh (Method 2 only; a Method 1 build ignores them).
pub fn build_split(
    scenario: &Scenario,
    params: &AbstractionParams,
    bins: &Discretization,
    splits: &[RegionSplit],
    progress: &dyn crate::exec::Work,
) -> Result<Mdp, AbstractionError> {
    check_params(scenario, params)?;
    if params.method != Method::Discretized {
        return build(scenario, params, progress);
    }
    if bins.decision_points.len() != scenario.num_legs() {
        return Err(AbstractionError::SplitBins {
            bins: bins.decision_points.len(),
            legs: scenario.num_legs(),
        });
    }
    let given = layers::Given {
        bins,
        splits,
        policy: None,
        carry_state: false,
        policy_only: false,
    };
    with_dim!(scenario.dim, N => {
        let cs = CompiledScenario::<N>::new(scenario);
        layers::build::<N>(scenario, &cs, params, None, &[], Some(&given), progress)
    })
}

/// [`build`] with pools drawn on-policy (docs/MODEL.md §7.3, `etp synthesize
/// --pool-policy`): on a strategy's `policy` — its bins and splits —, the pool of each region
/// is sampled from the arrivals weighted by the probability that the strategy
/// brings a belief there (its ω times its reach of the source state), so the
/// beliefs lumped in a region are the ones this strategy produces. Every
/// region reached keeps a pool (unweighted where the strategy never goes).
/// With `carry_state` the particles keep the true state they arrived with
/// and segments start from it (no N(x̂, P) draw after the first leg). With
/// `policy_only` each state simulates only the thresholds `strategy` uses
/// there: what predicting `strategy` needs, the same segments for them as
/// with every threshold (states are keyed by region), at a fraction of the
/// cost; such an MDP's states offer only those ([`Mdp::policy_only`]).
pub fn build_on_policy(
    scenario: &Scenario,
    params: &AbstractionParams,
    policy: &etp_shared::strategy::Policy,
    carry_state: bool,
    policy_only: bool,
    progress: &dyn crate::exec::Work,
) -> Result<Mdp, AbstractionError> {
    check_params(scenario, params)?;
    let bins = match (&policy.discretization, params.method) {
        (Some(b), Method::Discretized) => b,
        _ => return Err(AbstractionError::PoolPolicy),
    };
    if bins.decision_points.len() != scenario.num_legs() || policy.deltas != scenario.deltas {
        return Err(AbstractionError::PoolPolicy);
    }
    let omega = |dp: usize, cov: &nalgebra::DMatrix<f64>| -> Vec<f64> {
        match policy.omega(dp, cov) {
            etp_shared::strategy::OmegaChoice::Exact(w)
            | etp_shared::strategy::OmegaChoice::Nearest(w) => w.to_vec(),
            etp_shared::strategy::OmegaChoice::FullKf(i) => {
                let mut w = vec![0.0; policy.deltas.len()];
                if let Some(x) = w.get_mut(i) {
                    *x = 1.0;
                }
                w
            }
        }
    };
    let given = layers::Given {
        bins,
        splits: &policy.splits,
        policy: Some(&omega),
        carry_state,
        policy_only,
    };
    with_dim!(scenario.dim, N => {
        let cs = CompiledScenario::<N>::new(scenario);
        layers::build::<N>(scenario, &cs, params, None, &[], Some(&given), progress)
    })
}
