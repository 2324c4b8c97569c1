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

impl CertifiedFront {
    /// The certified least-energy curve at a bound on P_coll: the corners of
    /// the lower convex hull of `(p_target_low, energy_high)` over the points
    /// with `p_collision_high ≤ max_collision`, from the least energy up to
    /// the highest certified P_tar, increasing in both. A mixture of
    /// strategies (drawn once per episode) has bounds no worse than the
    /// mixture of their bounds (a worst case of a sum is at least the sum of
    /// worst cases), so every point on a segment between two corners is
    /// certified too, at the front's confidence. Empty when no point
    /// respects the bound.
    pub fn least_energy(&self, max_collision: Option<f64>) -> Vec<(f64, f64)> {
        let mut pts: Vec<(f64, f64)> = self
            .points
            .iter()
            .filter(|p| max_collision.is_none_or(|c| p.p_collision_high <= c + 1e-12))
            .filter(|p| p.p_target_low.is_finite() && p.energy_high.is_finite())
            .map(|p| (p.p_target_low, p.energy_high))
            .collect();
        // By energy, then the higher P_tar first: the least-energy point
        // starts the curve; each next corner must raise P_tar.
        pts.sort_by(|a, b| a.1.total_cmp(&b.1).then(b.0.total_cmp(&a.0)));
        let mut pareto: Vec<(f64, f64)> = Vec::new();
        for p in pts {
            if pareto.last().is_none_or(|l| p.0 > l.0) {
                pareto.push(p);
            }
        }
        // Lower convex hull of energy over P_tar (mixtures).
        let mut hull: Vec<(f64, f64)> = Vec::new();
        for p in pareto {
            while hull.len() >= 2 {
                let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
                // b lies on or above the chord a→p: a mixture of a and p beats it.
                let cross = (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0);
                if cross <= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(p);
        }
        hull
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(vertex: usize, t: f64, c: f64, e: f64) -> CertifiedPoint {
        CertifiedPoint {
            vertex,
            p_target_low: t,
            p_collision_high: c,
            energy_high: e,
            crossfit: None,
            dominated: false,
        }
    }

    #[test]
    fn the_certified_curve_is_the_lower_hull_within_the_bound() {
        let f = CertifiedFront {
            confidence: 0.95,
            union_events: 1,
            per_event_level: 0.05,
            points: vec![
                point(0, 0.50, 0.01, 10.0),
                // Dominated: more energy, less P_tar.
                point(1, 0.45, 0.01, 12.0),
                // Above the chord 0 → 3: a mixture is cheaper.
                point(2, 0.70, 0.01, 40.0),
                point(3, 0.90, 0.02, 50.0),
                // Beyond the bound 0.05.
                point(4, 0.95, 0.10, 60.0),
            ],
        };
        assert_eq!(f.least_energy(Some(0.05)), vec![(0.50, 10.0), (0.90, 50.0)]);
        assert_eq!(
            f.least_energy(None),
            vec![(0.50, 10.0), (0.90, 50.0), (0.95, 60.0)]
        );
        assert!(f.least_energy(Some(0.001)).is_empty());
    }
}
