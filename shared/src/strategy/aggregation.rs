//! The aggregation error of a strategy, measured (docs/MODEL.md §7.3).
//!
//! Lumping beliefs with different futures into one region biases a
//! strategy's value on an abstraction; `etp strategy` predicts on the
//! strategy's own rebuilds, whose pools remove that for it (docs/MODEL.md
//! §7.4). Only a simulation of the strategy in the real (continuous-belief)
//! loop measures what is left: `etp strategy` runs a short one at selection
//! time and stores it here, `etp validate` states it again from its own
//! episodes.

use super::Prediction;
use serde::{Deserialize, Serialize};

/// A strategy simulated in-process at selection time against the value it
/// is predicted by.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AggregationCheck {
    pub episodes: u64,
    pub seed: u64,
    /// The prediction compared: the strategy file's `predicted`, or for a
    /// `--quick` strategy its cross-fitted (else selection-time) value on
    /// the selection MDP.
    pub reference: Prediction,
    pub simulated: SimulatedValue,
    /// The reference's own 95 % half-widths (`predicted_ci95`, or the
    /// held-out sample's); absent for a selection-time reference and in
    /// older files, which compare against the simulation's alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_ci95: Option<PredictionCi95>,
}

/// Half-widths of a prediction's 95 % interval from its own sampling error
/// (the cross-fitted value's: `etp_synthesis::certify::crossfit`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PredictionCi95 {
    pub p_target: f64,
    pub p_collision: f64,
    pub energy_mean: f64,
}

/// Simulated P_tar, P_coll and mean energy with the half-widths of their
/// 95 % intervals (`etp_shared::stats`: Wilson for the probabilities, as `etp simulate` reports them).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimulatedValue {
    pub p_target: f64,
    pub p_target_ci95: f64,
    pub p_collision: f64,
    pub p_collision_ci95: f64,
    pub energy_mean: f64,
    pub energy_mean_ci95: f64,
}

/// Reference − simulated: positive on P_tar (negative on P_coll and
/// energy) means the prediction is optimistic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AggregationError {
    pub p_target: f64,
    pub p_collision: f64,
    pub energy_mean: f64,
}

impl AggregationCheck {
    pub fn error(&self) -> AggregationError {
        AggregationError {
            p_target: self.reference.p_target - self.simulated.p_target,
            p_collision: self.reference.p_collision - self.simulated.p_collision,
            energy_mean: self.reference.energy_mean - self.simulated.energy_mean,
        }
    }

    /// Half-widths of the error's combined 95 % interval: the simulation's
    /// and the reference's own sampling errors, independent, in quadrature.
    pub fn error_ci95(&self) -> PredictionCi95 {
        let r = self.reference_ci95.unwrap_or_default();
        let s = &self.simulated;
        PredictionCi95 {
            p_target: s.p_target_ci95.hypot(r.p_target),
            p_collision: s.p_collision_ci95.hypot(r.p_collision),
            energy_mean: s.energy_mean_ci95.hypot(r.energy_mean),
        }
    }

    /// Whether each error (P_tar, P_coll, energy) is larger than its
    /// combined 95 % interval ([`Self::error_ci95`]): the only errors the
    /// check can resolve; the others are within both sampling errors.
    pub fn resolved(&self) -> [bool; 3] {
        let e = self.error();
        let w = self.error_ci95();
        [
            e.p_target.abs() > w.p_target,
            e.p_collision.abs() > w.p_collision,
            e.energy_mean.abs() > w.energy_mean,
        ]
    }
}
