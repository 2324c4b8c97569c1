//! Predictions that hold (docs/MODEL.md §4.1): the optimiser's bias removed by
//! cross-fitting, and bounds certified from the sampling confidence.
//!
//! * [`crossfit`] — a strategy's value on held-out transitions (independent
//!   stream `HOLDOUT`), beside its selection-time value.
//! * [`intervals`] — the interval MDP: Clopper–Pearson per observed outcome, a
//!   bound on the unseen mass, empirical Bernstein on the energy, union bound
//!   over the whole MDP at level 1 − α ([`beta`] holds the special functions).
//! * [`robust`] — exact robust backward induction: certified lower P_tar,
//!   upper P_coll and upper energy of any strategy.
//! * [`select`] — the least-energy strategy found whose certified bounds meet
//!   a request (conservative iterative tightening).
//! * [`front`] — the certified front beside the nominal one.
//! * [`refine`] — sample allocation: more segments on the strategy's support
//!   until the certified P_tar gap is below a target.
//! * [`replicates`] — the cross-fitted value of R independent rebuilds and a
//!   Student-t interval over their spread: the rebuild's whole Monte Carlo.
//!
//! What is certified: sampling error in the abstraction's transition and
//! cost estimates. The aggregation of beliefs into regions is covered only
//! for the strategy whose own beliefs fill the pools: bounds certified on
//! its on-policy rebuild (`crate::predict`, docs/MODEL.md §7.4).
//!
//! Pure maths: no I/O, no clock; randomness only from seeded streams.

pub mod beta;
pub mod crossfit;
pub mod front;
pub mod intervals;
pub mod refine;
pub mod replicates;
pub mod robust;
pub mod select;

#[cfg(test)]
mod tests;

/// Why a certified computation failed.
#[derive(Debug, thiserror::Error)]
pub enum CertifyError {
    #[error("--confidence must lie strictly between 0 and 1, got {0}")]
    Confidence(f64),
    #[error(
        "no strategy has certified P_tar ≥ {min_target}{} at confidence {confidence}: the largest certified P_tar lower bound of any strategy is {best_target_low:.6}",
        max_collision.map(|c| format!(" and certified P_coll ≤ {c}")).unwrap_or_default()
    )]
    Infeasible {
        min_target: f64,
        max_collision: Option<f64>,
        best_target_low: f64,
        confidence: f64,
    },
    #[error("the nominal LP failed: {0}")]
    Lp(String),
    #[error("sample allocation: {0}")]
    Refine(String),
}
