//! Certified bounds that cover the measured aggregation error too
//! (docs/MODEL.md §7.3, `etp strategy --cover-aggregation`).
//!
//! The certified bounds hold for the abstraction's value at their level; a
//! short simulation of the strategy measures how far the real loop is from
//! the abstraction's (cross-fitted) value: the error of lumping beliefs into
//! regions. Each bound is moved by the error's one-sided upper confidence
//! bound wherever that is on the optimistic side:
//!
//! P_tar_low' = P_tar_low − max(0, e_tar + z σ_tar), e = reference − simulated,
//! P_coll_high' = P_coll_high + max(0, −e_coll + z σ_coll), likewise energy,
//!
//! σ the error's standard error: the simulation's and the cross-fitted
//! value's own, in quadrature (`AggregationCheck::error_ci95`). With the
//! abstraction's bounds and the error's each at level (1 + L)/2
//! ([`split_level`]), the union bound gives the widened ones at level L.

use etp_shared::stats::Z95;
use etp_shared::strategy::{AggregationCheck, CertifiedPrediction};
use statrs::distribution::{ContinuousCDF, Normal};

/// The level each of the two parts is computed at so that together they
/// hold at `level` (union bound).
pub fn split_level(level: f64) -> f64 {
    0.5 * (1.0 + level)
}

/// `c` (computed at [`split_level`] of `level`) widened by the measured
/// error of `check`, stated at `level`.
pub fn widen(c: &CertifiedPrediction, check: &AggregationCheck, level: f64) -> CertifiedPrediction {
    let z = one_sided_z(split_level(level));
    let e = check.error();
    let w = check.error_ci95();
    let upper = |optimistic: f64, ci95: f64| (optimistic + z * ci95 / Z95).max(0.0);
    CertifiedPrediction {
        confidence: level,
        p_target_low: (c.p_target_low - upper(e.p_target, w.p_target)).max(0.0),
        p_collision_high: (c.p_collision_high + upper(-e.p_collision, w.p_collision)).min(1.0),
        energy_high: c.energy_high + upper(-e.energy_mean, w.energy_mean),
        covers_aggregation: true,
    }
}

/// The standard normal quantile at `p` (one-sided bound at level p).
fn one_sided_z(p: f64) -> f64 {
    // Normal::new(0, 1) cannot fail.
    Normal::new(0.0, 1.0).map_or(Z95, |n| n.inverse_cdf(p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_shared::strategy::{Prediction, SimulatedValue};

    fn check(reference: (f64, f64, f64), simulated: (f64, f64, f64)) -> AggregationCheck {
        AggregationCheck {
            episodes: 1000,
            seed: 1,
            reference: Prediction {
                p_target: reference.0,
                p_collision: reference.1,
                p_free: 1.0 - reference.0 - reference.1,
                energy_mean: reference.2,
            },
            simulated: SimulatedValue {
                p_target: simulated.0,
                p_target_ci95: 0.02,
                p_collision: simulated.1,
                p_collision_ci95: 0.01,
                energy_mean: simulated.2,
                energy_mean_ci95: 1.0,
            },
            reference_ci95: None,
        }
    }

    const BOUNDS: CertifiedPrediction = CertifiedPrediction {
        confidence: 0.975,
        p_target_low: 0.85,
        p_collision_high: 0.10,
        energy_high: 60.0,
        covers_aggregation: false,
    };

    #[test]
    fn the_two_parts_together_hold_at_the_level_asked() {
        assert!((split_level(0.95) - 0.975).abs() < 1e-15);
        // At 0.975 one-sided, z is the two-sided 95 % z.
        assert!((one_sided_z(0.975) - Z95).abs() < 1e-9);
    }

    #[test]
    fn an_optimistic_prediction_moves_every_bound_by_its_error_and_the_noise() {
        // Predicted 3 pt more P_tar, 2 pt less P_coll, 5 less energy than simulated.
        let w = widen(
            &BOUNDS,
            &check((0.90, 0.06, 50.0), (0.87, 0.08, 55.0)),
            0.95,
        );
        assert!(
            (w.p_target_low - (0.85 - 0.03 - 0.02)).abs() < 1e-12,
            "{w:?}"
        );
        assert!(
            (w.p_collision_high - (0.10 + 0.02 + 0.01)).abs() < 1e-12,
            "{w:?}"
        );
        assert!((w.energy_high - (60.0 + 5.0 + 1.0)).abs() < 1e-12, "{w:?}");
        assert!(w.covers_aggregation);
        assert_eq!(w.confidence, 0.95);
    }

    #[test]
    fn a_pessimistic_prediction_beyond_the_noise_moves_nothing() {
        let w = widen(
            &BOUNDS,
            &check((0.85, 0.10, 60.0), (0.90, 0.05, 50.0)),
            0.95,
        );
        assert_eq!(
            (w.p_target_low, w.p_collision_high, w.energy_high),
            (0.85, 0.10, 60.0)
        );
    }

    #[test]
    fn an_exact_prediction_still_pays_for_the_simulation_noise() {
        let w = widen(&BOUNDS, &check((0.9, 0.05, 50.0), (0.9, 0.05, 50.0)), 0.95);
        assert!((w.p_target_low - 0.83).abs() < 1e-12);
        assert!((w.p_collision_high - 0.11).abs() < 1e-12);
        assert!((w.energy_high - 61.0).abs() < 1e-12);
    }

    #[test]
    fn probabilities_stay_probabilities() {
        let w = widen(&BOUNDS, &check((1.0, 0.0, 0.0), (0.0, 1.0, 100.0)), 0.95);
        assert_eq!((w.p_target_low, w.p_collision_high), (0.0, 1.0));
    }
}
