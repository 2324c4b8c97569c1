//! What a strategy file says of the strategy's outcome: the one prediction
//! etp stands by ([`super::Strategy::predicted`]) and, apart, the values
//! that only explain it ([`Diagnostics`]).

use super::PredictionCi95;
use serde::{Deserialize, Serialize};

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
    /// The prediction meets the user's request (short of a bound by at
    /// most a quarter of its 95 % half-width).
    pub meets: bool,
    /// This round's strategy was not selected for the asked request but is
    /// the policy that transmits most (the smallest δ at every state), tried
    /// when the MDP's edge missed a P_tar request (docs/MODEL.md §7.4).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub most_transmitting: bool,
}
