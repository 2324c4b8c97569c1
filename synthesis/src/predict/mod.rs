//! The prediction etp stands by, and a strategy that meets the request
//! (docs/MODEL.md §7.3, §7.4).
//!
//! * [`rebuild`] — a strategy predicted on its own beliefs: the abstraction
//!   rebuilt with pools of the strategy's own (true state, belief) pairs and
//!   only its thresholds, R times with seeds DIR's + r; the cross-fitted
//!   value is the rebuilds' mean with a Student-t ± over their spread
//!   ([`rebuild::OnPolicy`]).
//! * [`request`] — the request loop: select on the MDP, predict the
//!   selected strategy on its rebuilds, and where that prediction misses the
//!   user's request beyond its ±, tighten the request to the MDP by the
//!   measured gap and select again, a bounded number of rounds
//!   ([`request::meet_request`]).
//!
//! Pure: no I/O, no clock; progress through callbacks.

pub mod front;
pub mod rebuild;
pub mod request;

use crate::abstraction::AbstractionError;

/// Why a prediction could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PredictError {
    #[error("rebuild {replicate} on the strategy's own pools: {source}")]
    Rebuild {
        replicate: u32,
        #[source]
        source: AbstractionError,
    },
    #[error("a rebuilt MDP failed its own consistency check (a bug): {0}")]
    Inconsistent(String),
    #[error("the strategy's scenario: {0}")]
    Scenario(String),
    #[error("{0}")]
    Select(#[from] crate::pareto::select::SelectError),
    #[error("{0}")]
    Certify(#[from] crate::certify::CertifyError),
}
