//! What a strategy file says of the strategy's outcome ([`Predictions`]):
//! the one prediction etp stands by ([`Predictions::predicted`]) and,
//! apart, the values that only explain it ([`Diagnostics`]).

use super::{AggregationCheck, PredictionCi95, StrategyError};
use crate::scenario::Scenario;
use serde::{Deserialize, Serialize};

/// What etp predicts of a strategy and how it knows: reported by `etp
/// run`, `etp validate` and the run report, never needed to run it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Predictions {
    /// The prediction etp stands by (docs/MODEL.md §7.4): for a strategy of
    /// `etp strategy`, the mean cross-fitted value of its on-policy rebuilds
    /// (its own beliefs in the pools, so no aggregation error), with
    /// [`Predictions::predicted_ci95`]; for a constant δ of `etp run
    /// --scenario … --delta`, an in-process simulation. `None` for a
    /// `--quick` strategy, whose only values are the biased ones of
    /// [`Diagnostics`].
    pub predicted: Option<Prediction>,
    /// The 95 % half-widths of [`Predictions::predicted`] (Student's t over
    /// the rebuilds, or the simulation's interval).
    pub predicted_ci95: Option<PredictionCi95>,
    /// How [`Predictions::predicted`] was obtained, in words.
    pub prediction_basis: String,
    /// Certified bounds at a confidence level (for a strategy of `etp
    /// strategy`: from the first on-policy rebuild's own transitions).
    pub certified: Option<CertifiedPrediction>,
    /// Selection-time expected energy spent on each leg (the MDP's
    /// occupation measure × mean segment energy, transmissions × cost): the
    /// per-sensor prediction of `etp run` and `etp validate` (a sensor's
    /// share = the legs it serves). Absent in older files and for strategies
    /// made without an MDP.
    pub leg_energy: Option<Vec<f64>>,
    /// The aggregation error measured at selection time (`etp strategy
    /// --aggregation-check N`, on by default): the strategy simulated
    /// against its prediction. Absent in older files and with N = 0.
    pub aggregation: Option<AggregationCheck>,
    /// Every other value, for diagnosis only: the selection-time and
    /// cross-fitted values on the MDP it was selected on (biased), each
    /// rebuild's, and the rounds of the request loop.
    pub diagnostics: Option<Diagnostics>,
}

impl Predictions {
    /// Predicted energy per episode of each of `scenario`'s sensors, from
    /// [`Predictions::leg_energy`]; `None` without it (or if it does not
    /// match the scenario's legs).
    pub fn sensor_energy(&self, scenario: &Scenario) -> Option<Vec<f64>> {
        let legs = self.leg_energy.as_ref()?;
        if legs.len() != scenario.legs.len() {
            return None;
        }
        let mut out = vec![0.0; scenario.sensors.len()];
        for (leg, e) in scenario.legs.iter().zip(legs) {
            *out.get_mut(leg.sensor)? += e;
        }
        Some(out)
    }

    pub(super) fn check_consistent(&self) -> Result<(), StrategyError> {
        if let Some(i) = self
            .leg_energy
            .iter()
            .flatten()
            .position(|e| !(e.is_finite() && *e >= 0.0))
        {
            return Err(StrategyError::Invalid(format!(
                "leg_energy[{i}] must be finite and ≥ 0"
            )));
        }
        Ok(())
    }
}

/// P_tar, P_coll, P_free and the expected energy of one episode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    pub p_target: f64,
    pub p_collision: f64,
    pub p_free: f64,
    pub energy_mean: f64,
}

/// Certified bounds of a strategy (docs/MODEL.md §4.1): with probability at
/// least `confidence` over the abstraction's sampling, the abstraction's true
/// P_tar ≥ `p_target_low`, P_coll ≤ `p_collision_high`, energy ≤ `energy_high`.
/// Computed on an on-policy rebuild (the strategy's own beliefs in the
/// pools) they hold for the loop that runs, up to that rebuild's Monte Carlo.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CertifiedPrediction {
    pub confidence: f64,
    pub p_target_low: f64,
    pub p_collision_high: f64,
    pub energy_high: f64,
    /// Computed on an on-policy rebuild of the strategy (its own beliefs and
    /// true states in the pools): they cover its aggregation error, not only
    /// the abstraction's sampling. Absent (false) for bounds on the
    /// selection MDP (`--quick`) and in version 1 files.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub covers_aggregation: bool,
}

/// Values kept to explain a strategy's prediction, never to be used as it.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Diagnostics {
    /// The strategy's values on the MDP it was selected on: biased (the
    /// optimiser's choice and the aggregation of other strategies' beliefs).
    pub selection: SelectionValues,
    /// Each on-policy rebuild of the final strategy (seeds DIR's + r).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rebuilds: Vec<RebuildValue>,
    /// The rounds of the request loop (docs/MODEL.md §7.4), first to last.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rounds: Vec<RequestRound>,
}

/// Values on the selection MDP.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SelectionValues {
    /// Its exact value on that MDP (optimistic by the optimiser's bias).
    pub selection_time: Option<Prediction>,
    /// On that MDP's held-out transitions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crossfit: Option<Prediction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crossfit_ci95: Option<PredictionCi95>,
    /// Certified bounds on that MDP (sampling error only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub certified: Option<CertifiedPrediction>,
}

/// One on-policy rebuild's values of the strategy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RebuildValue {
    pub seed: u64,
    /// Exact value on the rebuild.
    pub selection_time: Prediction,
    /// On the rebuild's held-out transitions, with the delta method's ±
    /// (which misses the pools' share of its Monte Carlo).
    pub crossfit: Option<Prediction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crossfit_ci95: Option<PredictionCi95>,
}

/// One round of the request loop: what the MDP was asked, what the strategy
/// it gave is worth on its rebuilds, and whether that meets the user's request.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RequestRound {
    /// The request put to the selection MDP (the user's, tightened by the
    /// gaps measured in the rounds before).
    pub asked_p_target: Option<f64>,
    pub asked_p_collision: Option<f64>,
    pub asked_energy: Option<f64>,
    /// The selected strategy's value on the selection MDP.
    pub selection_time: Prediction,
    /// Its prediction from this round's rebuilds, and their number.
    pub predicted: Prediction,
    pub predicted_ci95: PredictionCi95,
    pub rebuilds: u32,
    /// The prediction meets the user's request (each bound holds for the
    /// prediction itself).
    pub meets: bool,
    /// This round's strategy was not selected for the asked request but is
    /// the policy that transmits most (the smallest δ at every state), tried
    /// when the MDP's edge missed a P_tar request (docs/MODEL.md §7.4).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub most_transmitting: bool,
}
