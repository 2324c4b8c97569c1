//! A strategy predicted on its own beliefs: R on-policy rebuilds of the
//! abstraction (docs/MODEL.md §7.3). Replicate r uses the selection MDP's
//! settings with seed + r, pools drawn from the strategy's own (true state,
//! belief) arrivals and only the thresholds it takes; the strategy is then
//! evaluated on each. Their cross-fitted values are independent draws of the
//! rebuild's whole Monte Carlo, so their mean with a Student-t ± over their
//! spread ([`crate::certify::replicates`]) is the prediction etp stands by.

use super::PredictError;
use crate::abstraction::{self, AbstractionParams};
use crate::certify::crossfit::{CrossFit, crossfit};
use crate::certify::intervals::interval_mdp;
use crate::certify::replicates::{Replicated, replicated};
use crate::certify::robust::{Certified, certify};
use crate::mdp::{CostModel, Mdp};
use crate::pareto::policy::{Objectives, RandomisedPolicy, evaluate, leg_energy};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::{OmegaChoice, Policy, Strategy};

/// The fewest rebuilds a prediction is made of (the Student-t interval needs
/// a spread).
pub const MIN_REPLICATES: u32 = 2;

/// Rebuilds of a prediction by default: a half-width of about 2 standard
/// errors of one rebuild (docs/MODEL.md §7.3).
pub const DEFAULT_REPLICATES: u32 = 4;

/// One rebuild and the strategy evaluated on it, once.
pub struct Replica {
    pub mdp: Mdp,
    /// The strategy's ω on this rebuild's states.
    pub omega: RandomisedPolicy,
    /// Its exact value on the rebuild.
    pub value: Objectives,
    pub leg_energy: Vec<f64>,
    /// Its value on the rebuild's held-out transitions (none when the
    /// selection MDP was built without a held-out sample).
    pub crossfit: Option<CrossFit>,
}

impl Replica {
    /// What this rebuild predicts: the cross-fitted value, or the exact one
    /// without a held-out sample (no optimiser's bias either way: the
    /// strategy was not chosen on this rebuild).
    pub fn prediction(&self) -> Objectives {
        self.crossfit.as_ref().map_or(self.value, |c| c.objectives)
    }
}

/// The rebuilds of one strategy and the prediction they make.
pub struct OnPolicy {
    pub replicas: Vec<Replica>,
    /// The replicates' cross-fitted mean and its 95 % Student-t half-width.
    pub combined: Replicated,
    /// The replicates' mean exact value.
    pub value: Objectives,
    /// Per-leg energy: the shares of the replicates' mean exact per-leg
    /// energy, scaled to add up to the predicted energy (`combined`), so
    /// the per-sensor predictions of `etp run`/`validate` sum to the one
    /// prediction etp stands by.
    pub leg_energy: Vec<f64>,
}

impl OnPolicy {
    /// The first rebuild (seed DIR's + 0), whose certified bounds are reported.
    pub fn first(&self) -> &Replica {
        &self.replicas[0]
    }

    pub fn segments(&self) -> u64 {
        self.replicas.iter().map(|r| r.mdp.total_segments).sum()
    }

    /// The strategy's bounds certified at `level` on its first rebuild's own
    /// transitions (they cover its aggregation error: docs/MODEL.md §7.4).
    pub fn certify_first(&self, level: f64, cost: CostModel) -> Result<Certified, PredictError> {
        self.first().certify(level, cost)
    }
}

impl Replica {
    /// The strategy's bounds certified at `level` on this rebuild.
    pub fn certify(&self, level: f64, cost: CostModel) -> Result<Certified, PredictError> {
        let im = interval_mdp(&self.mdp, level, cost)?;
        Ok(certify(&self.mdp, &im, &self.omega))
    }
}

/// ω of a strategy's `policy` on every state of `mdp` (by region; a region
/// the strategy never saw takes its nearest, as the strategy itself does at
/// run time).
pub fn policy_on(mdp: &Mdp, policy: &Policy) -> RandomisedPolicy {
    mdp.states
        .iter()
        .map(|s| {
            let omega = match policy.omega_of_region(s.decision_point as usize, &s.region) {
                OmegaChoice::Exact(w) | OmegaChoice::Nearest(w) => w.to_vec(),
                OmegaChoice::FullKf(i) => {
                    let mut w = vec![0.0; policy.deltas.len()];
                    if let Some(x) = w.get_mut(i) {
                        *x = 1.0;
                    }
                    w
                }
            };
            let mut row: Vec<f64> = s
                .choices
                .iter()
                .map(|c| omega.get(c.action as usize).copied().unwrap_or(0.0))
                .collect();
            let sum: f64 = row.iter().sum();
            if sum > 0.0 {
                row.iter_mut().for_each(|p| *p /= sum);
            } else if let Some(x) = row.first_mut() {
                // None of ω's thresholds is offered here: the first choice
                // (the smallest δ, as for a region without a state).
                *x = 1.0;
            }
            row
        })
        .collect()
}

/// The settings of rebuild `replicate`: the selection MDP's, seed + r, and
/// always a held-out sample (the selection MDP may have none, and by default
/// has none): a rebuild's prediction is cross-fitted.
pub fn rebuild_params(params: &AbstractionParams, replicate: u32) -> AbstractionParams {
    let mut p = *params;
    p.seed = params.seed.wrapping_add(u64::from(replicate));
    if p.holdout_samples == 0 {
        p.holdout_samples = p.samples;
    }
    p
}

/// Progress units of one rebuild at most (every threshold simulated; a
/// rebuild simulates only the strategy's own, so it may end short of it).
pub fn progress_units(scenario: &Scenario, params: &AbstractionParams) -> u64 {
    abstraction::progress_total(scenario, &rebuild_params(params, 0))
}

/// Rebuild `replicate` (seed `params.seed + replicate`) on a strategy's `policy`:
/// its own
/// pools and thresholds, and evaluate it there.
pub fn rebuild_one(
    scenario: &Scenario,
    params: &AbstractionParams,
    policy: &Policy,
    replicate: u32,
    cost: CostModel,
    progress: &dyn crate::exec::Work,
) -> Result<Replica, PredictError> {
    let p = rebuild_params(params, replicate);
    let mdp = abstraction::build_on_policy(scenario, &p, policy, true, true, progress)
        .map_err(|source| PredictError::Rebuild { replicate, source })?;
    mdp.check()
        .map_err(|e| PredictError::Inconsistent(e.to_string()))?;
    let omega = policy_on(&mdp, policy);
    let crossfit = crossfit(&mdp, &omega, cost);
    Ok(Replica {
        value: evaluate(&mdp, &omega, cost),
        leg_energy: leg_energy(&mdp, &omega, cost),
        crossfit,
        omega,
        mdp,
    })
}

/// Combine rebuilds (at least [`MIN_REPLICATES`]) into one prediction.
pub fn combine(replicas: Vec<Replica>) -> Result<OnPolicy, PredictError> {
    let values: Vec<Objectives> = replicas.iter().map(Replica::prediction).collect();
    let combined = replicated(&values).ok_or_else(|| {
        PredictError::Inconsistent(format!(
            "{} rebuilds; a prediction needs at least {MIN_REPLICATES}",
            replicas.len()
        ))
    })?;
    let n = replicas.len() as f64;
    let mut value = Objectives::default();
    let mut legs: Vec<f64> = Vec::new();
    for x in &replicas {
        value.p_target += x.value.p_target / n;
        value.p_collision += x.value.p_collision / n;
        value.energy += x.value.energy / n;
        if legs.len() < x.leg_energy.len() {
            legs.resize(x.leg_energy.len(), 0.0);
        }
        for (l, e) in legs.iter_mut().zip(&x.leg_energy) {
            *l += e / n;
        }
    }
    let total: f64 = legs.iter().sum();
    if total > 0.0 {
        let scale = combined.mean.energy / total;
        legs.iter_mut().for_each(|l| *l *= scale);
    }
    Ok(OnPolicy {
        replicas,
        combined,
        value,
        leg_energy: legs,
    })
}

/// A strategy's `policy` predicted on `replicates` rebuilds (seeds `params.seed + r`),
/// reusing `done` (the first rebuilds, already made).
pub fn predict(
    scenario: &Scenario,
    params: &AbstractionParams,
    policy: &Policy,
    replicates: u32,
    cost: CostModel,
    mut done: Vec<Replica>,
    progress: &dyn crate::exec::Work,
) -> Result<OnPolicy, PredictError> {
    for r in done.len() as u32..replicates.max(MIN_REPLICATES) {
        done.push(rebuild_one(scenario, params, policy, r, cost, progress)?);
    }
    combine(done)
}

/// The scenario a rebuild of `mdp` simulates: the policy's own (hash
/// checked, under its own channel).
pub fn scenario_of(policy: &Policy) -> Result<Scenario, PredictError> {
    policy
        .scenario()
        .map_err(|e| PredictError::Scenario(e.to_string()))
}

/// What [`OnPolicy::stand_by`] says a prediction is.
pub fn basis(replicas: &[Replica]) -> String {
    let first = replicas.first().map_or(0, |r| r.mdp.seed);
    let last = replicas.last().map_or(first, |r| r.mdp.seed);
    let held_out = replicas.iter().all(|r| r.crossfit.is_some());
    format!(
        "the mean {} value of {} on-policy rebuilds (seeds {first}…{last}: the strategy's own \
         beliefs and true states in the pools, only its thresholds), ± Student's t at 95 % over \
         their spread",
        if held_out { "cross-fitted" } else { "exact" },
        replicas.len()
    )
}

impl OnPolicy {
    /// Make this the prediction `strategy` stands by: `predicted` with its
    /// ±, the per-leg energy, the certified bounds of the first rebuild
    /// (`certified`, at `level`) and every rebuild under `diagnostics`.
    pub fn stand_by(&self, strategy: &mut Strategy, certified: &Certified, level: f64) {
        strategy.predictions.predicted = Some(self.combined.mean.prediction());
        strategy.predictions.predicted_ci95 = Some(self.combined.ci95.ci95());
        strategy.predictions.prediction_basis = basis(&self.replicas);
        strategy.predictions.leg_energy = Some(self.leg_energy.clone());
        strategy.predictions.certified = Some(etp_shared::strategy::CertifiedPrediction {
            confidence: level,
            p_target_low: certified.p_target_low,
            p_collision_high: certified.p_collision_high,
            energy_high: certified.energy_high,
            covers_aggregation: true,
        });
        let d = strategy
            .predictions
            .diagnostics
            .get_or_insert_with(Default::default);
        d.rebuilds = self
            .replicas
            .iter()
            .map(|r| etp_shared::strategy::RebuildValue {
                seed: r.mdp.seed,
                selection_time: r.value.prediction(),
                crossfit: r.crossfit.as_ref().map(|c| c.objectives.prediction()),
                crossfit_ci95: r.crossfit.as_ref().map(CrossFit::ci95),
            })
            .collect();
    }
}
