//! The least-energy strategy whose *certified* bounds meet a request
//! (docs/MODEL.md §4.1): iterative conservative tightening of the nominal
//! occupation LP.
//!
//! Each round solves the exact nominal LP (`pareto::optimal`) with the
//! request's thresholds tightened by margins `(m_t, m_c)`, certifies the
//! result by exact robust backward induction, and raises each margin by its
//! shortfall (`p − P_tar_low`, `P_coll_high − c`). The first certified strategy
//! is then improved by bisection between the last failing and the first
//! succeeding margins. When the tightened request is nominally infeasible
//! the robust max-P_tar policy (exact for P_tar alone) is the candidate. The bounds of the returned strategy are exact for it
//! and meet the request; the strategy is *conservative*, not proven optimal:
//! the least-energy strategy over the interval MDP with several objectives
//! (each against its own adversary) is a non-convex problem this does not solve.

use super::CertifyError;
use super::intervals::IntervalMdp;
use super::robust::{Certified, best_certified_target, certify};
use crate::mdp::{CostModel, Mdp};
use crate::pareto::optimal::{LpRequest, OptimalStrategy, optimal_strategy};
use crate::pareto::policy::{as_randomised, evaluate};

/// How [`certified_strategy`] solves: reported beside the result.
pub const METHOD: &str = "iterative conservative tightening of the nominal occupation LP \
     (falling back to the robust max-P_tar policy when the tightened request is nominally \
     infeasible), each candidate certified by exact robust backward induction on the \
     interval MDP (bounds exact for the returned strategy; its energy is an upper estimate \
     of the certified optimum, not proven least)";

/// Rounds of margin raising, then of bisection.
const RAISE_ROUNDS: usize = 40;
const BISECTION_ROUNDS: usize = 8;

/// A strategy whose certified bounds meet the request.
#[derive(Debug, Clone, PartialEq)]
pub struct CertifiedStrategy {
    pub strategy: OptimalStrategy,
    pub certified: Certified,
    /// The nominal thresholds' tightening that produced it (P_tar, P_coll).
    pub margins: (f64, f64),
    /// Nominal LPs solved.
    pub solves: usize,
}

struct Candidate {
    opt: OptimalStrategy,
    cert: Certified,
    margins: (f64, f64),
}

/// The least-energy strategy found with certified `P_tar ≥ min_target` (and
/// certified `P_coll ≤ max_collision`).
pub fn certified_strategy(
    mdp: &Mdp,
    im: &IntervalMdp,
    cost: CostModel,
    min_target: f64,
    max_collision: Option<f64>,
) -> Result<CertifiedStrategy, CertifyError> {
    let mut solves = 0;
    let mut attempt = |m: (f64, f64)| -> Result<Option<Candidate>, CertifyError> {
        let request = LpRequest::MinEnergy {
            min_target: (min_target + m.0).min(1.0),
            max_collision: max_collision.map(|c| (c - m.1).max(0.0)),
        };
        solves += 1;
        match optimal_strategy(mdp, cost, request) {
            Ok(opt) => {
                let cert = certify(mdp, im, &opt.policy);
                Ok(Some(Candidate {
                    opt,
                    cert,
                    margins: m,
                }))
            }
            Err(crate::pareto::select::SelectError::Infeasible { .. }) => Ok(None),
            Err(e) => Err(CertifyError::Lp(e.to_string())),
        }
    };
    let meets = |c: &Certified| {
        c.p_target_low >= min_target && max_collision.is_none_or(|mc| c.p_collision_high <= mc)
    };
    let infeasible = || {
        let (_, best) = best_certified_target(mdp, im);
        CertifyError::Infeasible {
            min_target,
            max_collision,
            best_target_low: best,
            confidence: im.confidence,
        }
    };
    let mut failing = (0.0, 0.0);
    let mut found: Option<Candidate> = None;
    let mut m = (0.0, 0.0);
    for _ in 0..RAISE_ROUNDS {
        let Some(c) = attempt(m)? else {
            // The tightened nominal request is infeasible: the robust
            // max-P_tar policy is the candidate left (exact for P_tar alone).
            let (det, _) = best_certified_target(mdp, im);
            let policy = as_randomised(mdp, &det);
            let cert = certify(mdp, im, &policy);
            if meets(&cert) {
                let predicted = evaluate(mdp, &policy, cost);
                found = Some(Candidate {
                    opt: OptimalStrategy {
                        policy,
                        predicted,
                        lp_objective: predicted.energy,
                        margin: 0.0,
                        randomised_states: 0,
                    },
                    cert,
                    margins: m,
                });
            }
            break;
        };
        if meets(&c.cert) {
            found = Some(c);
            break;
        }
        failing = m;
        let short_t = (min_target - c.cert.p_target_low).max(0.0);
        let short_c = max_collision.map_or(0.0, |mc| (c.cert.p_collision_high - mc).max(0.0));
        // A small floor so that a stalled round still moves.
        m = (
            m.0 + if short_t > 0.0 { short_t + 1e-6 } else { 0.0 },
            m.1 + if short_c > 0.0 { short_c + 1e-6 } else { 0.0 },
        );
    }
    let Some(mut best) = found else {
        return Err(infeasible());
    };
    // Bisection on the segment between the failing and the succeeding margins.
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let top = best.margins;
    for _ in 0..BISECTION_ROUNDS {
        let mid = 0.5 * (lo + hi);
        let mm = (
            failing.0 + mid * (top.0 - failing.0),
            failing.1 + mid * (top.1 - failing.1),
        );
        match attempt(mm)? {
            Some(c) if meets(&c.cert) => {
                if c.opt.predicted.energy <= best.opt.predicted.energy {
                    best = c;
                }
                hi = mid;
            }
            _ => lo = mid,
        }
    }
    Ok(CertifiedStrategy {
        strategy: best.opt,
        certified: best.cert,
        margins: best.margins,
        solves,
    })
}
