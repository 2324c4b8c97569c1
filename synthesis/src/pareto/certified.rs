//! The certified front's data, a field of [`super::ParetoFront`]
//! (`front.json` field `certified`, docs/MODEL.md §4.1). It is computed by
//! [`crate::certify::front::certified_front`]; the types live here, beside
//! the front that holds them, so that `pareto` needs nothing of `certify`.

use super::policy::Objectives;
use serde::{Deserialize, Serialize};

/// One vertex of the nominal front, certified.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CertifiedPoint {
    /// Index into `ParetoFront::vertices`.
    pub vertex: usize,
    pub p_target_low: f64,
    pub p_collision_high: f64,
    pub energy_high: f64,
    /// Cross-fitted values (held-out transitions), when the MDP has them.
    pub crossfit: Option<Objectives>,
    /// Another certified point is at least as good in all three bounds and
    /// better in one.
    pub dominated: bool,
}

/// The certified front of `front.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CertifiedFront {
    pub confidence: f64,
    /// Intervals the union bound runs over, and each one's error level.
    pub union_events: u64,
    pub per_event_level: f64,
    pub points: Vec<CertifiedPoint>,
}
