//! The predicted front's data in `front.json` (computed by
//! `predict::front`; kept here so `pareto` imports nothing of `predict`).

use super::policy::Objectives;
use serde::{Deserialize, Serialize};

/// One curve of the predicted front: the request loop's answers under one
/// P_coll bound (or none).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PredictedFront {
    /// The P_coll bound of every request of the curve.
    pub max_collision: Option<f64>,
    /// On-policy rebuilds of each prediction, and rounds of the loop at most.
    pub replicates: u32,
    pub max_rounds: u32,
    /// The P_tar range the MDP offers under the bound: its least-energy
    /// strategy's P_tar and its highest P_tar (selection-time values).
    pub range: [f64; 2],
    /// By increasing requested P_tar.
    pub points: Vec<PredictedPoint>,
}

/// The strategy the request loop returns for one request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PredictedPoint {
    /// The request: least energy with P_tar ≥ `min_target` (and P_coll ≤
    /// the curve's bound).
    pub min_target: f64,
    /// `met`, `out-of-reach` or `rounds-spent` (as `etp strategy`).
    pub verdict: String,
    /// The prediction etp stands by (mean of the rebuilds' cross-fitted
    /// values) and its 95 % half-width.
    pub predicted: Objectives,
    pub predicted_ci95: Objectives,
    /// The same strategy's value on the selection MDP.
    pub selection_time: Objectives,
    /// Rounds the loop ran and rebuilds it made.
    pub rounds: usize,
    pub rebuilds: u32,
}

impl PredictedPoint {
    /// Whether the loop met the request.
    pub fn met(&self) -> bool {
        self.verdict == "met"
    }
}
