//! Sample allocation (docs/MODEL.md §4.1): more segments where they tighten
//! the bound that binds the requested strategy.
//!
//! Each round selects a strategy on the current MDP (the caller's rule, e.g.
//! the certified least-energy one), measures its certified P_tar gap
//! (selection-time P_tar − certified lower bound) and, while the gap exceeds
//! the target, doubles the segments of every (state, action) on the
//! strategy's support, by re-running the build with the extra segments
//! ([`crate::abstraction::build_with_extra`]: same states and pools, fresh
//! segment indices of the main stream). A choice's sample size is therefore
//! always `M · 2^r` with `r ≤ rounds`, and the union bound covers all those
//! sizes (`Mdp::looks = rounds + 1`), so the bounds stay valid although the
//! sizes are chosen from the data.

use super::CertifyError;
use crate::abstraction::{build_with_extra, params_of};
use crate::mdp::Mdp;
use crate::pareto::policy::{RandomisedPolicy, occupation};
use etp_shared::scenario::Scenario;

/// A choice is on the support when the strategy visits it with at least this
/// probability.
const SUPPORT: f64 = 1e-6;

/// One round of allocation.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineRound {
    /// Selection-time P_tar and certified lower bound of the round's strategy.
    pub p_target: f64,
    pub p_target_low: f64,
    /// Main and extra segments of the MDP at this round (Σ of the choices'
    /// samples; the held-out set is not counted).
    pub segments: u64,
    /// Choices whose samples were doubled after this round.
    pub doubled: usize,
}

/// The outcome of [`refine`].
#[derive(Debug, Clone)]
pub struct Refined {
    pub mdp: Mdp,
    pub rounds: Vec<RefineRound>,
    /// Extra segments simulated in total (over all re-builds; the re-builds
    /// also repeat the main segments, reported by the caller's clock).
    pub added_segments: u64,
    /// Whether the last strategy's gap is at most the target.
    pub converged: bool,
}

/// What the caller's selection rule returns: the strategy, its selection-time
/// P_tar and its certified P_tar lower bound.
pub type Selection = (RandomisedPolicy, f64, f64);

/// The MDP `mdp` prepared for `rounds` rounds of allocation: its union bound
/// covers the sample sizes allocation may reach (call before selecting).
pub fn prepare(mdp: &Mdp, rounds: u32) -> Mdp {
    let mut m = mdp.clone();
    m.looks = rounds + 1;
    m
}

/// Allocate samples until the gap is at most `target_gap` or `rounds` rounds
/// are spent. `mdp` must come from [`prepare`] with the same `rounds`.
pub fn refine(
    scenario: &Scenario,
    mdp: &Mdp,
    target_gap: f64,
    rounds: u32,
    select: &dyn Fn(&Mdp) -> Result<Selection, CertifyError>,
    progress: &dyn crate::exec::Work,
) -> Result<Refined, CertifyError> {
    if !(target_gap.is_finite() && target_gap >= 0.0) {
        return Err(CertifyError::Refine(format!(
            "the target gap must be a finite number ≥ 0, got {target_gap}"
        )));
    }
    let mut params = params_of(mdp);
    // The held-out set is copied over, not simulated again.
    params.holdout_samples = 0;
    let mut extra: Vec<Vec<u32>> = mdp
        .states
        .iter()
        .map(|s| vec![0; s.choices.len()])
        .collect();
    let mut current = mdp.clone();
    let mut out = Vec::new();
    let mut added = 0u64;
    for round in 0..=rounds {
        let (policy, p, low) = select(&current)?;
        let gap = p - low;
        let mut r = RefineRound {
            p_target: p,
            p_target_low: low,
            segments: current
                .states
                .iter()
                .flat_map(|s| &s.choices)
                .map(|c| u64::from(c.samples))
                .sum(),
            doubled: 0,
        };
        if gap <= target_gap || round == rounds {
            out.push(r);
            return Ok(Refined {
                mdp: current,
                rounds: out,
                added_segments: added,
                converged: gap <= target_gap,
            });
        }
        let occ = occupation(&current, &policy);
        for (s, row) in occ.iter().enumerate() {
            for (c, &x) in row.iter().enumerate() {
                if x >= SUPPORT {
                    // n = M + e  →  2n = M + (M + 2e).
                    let e = extra[s][c];
                    let next = mdp.samples_per_choice.saturating_add(e.saturating_mul(2));
                    added += u64::from(next - e);
                    extra[s][c] = next;
                    r.doubled += 1;
                }
            }
        }
        out.push(r);
        let mut rebuilt = build_with_extra(scenario, &params, &extra, progress)
            .map_err(|e| CertifyError::Refine(e.to_string()))?;
        if rebuilt.states.len() != mdp.states.len()
            || rebuilt
                .states
                .iter()
                .zip(&mdp.states)
                .any(|(a, b)| a.region != b.region || a.choices.len() != b.choices.len())
        {
            return Err(CertifyError::Refine(
                "the re-built MDP has other states (was mdp.bin built by this etp?)".into(),
            ));
        }
        for (a, b) in rebuilt.states.iter_mut().zip(&mdp.states) {
            for (ca, cb) in a.choices.iter_mut().zip(&b.choices) {
                ca.holdout = cb.holdout.clone();
            }
        }
        rebuilt.holdout_samples = mdp.holdout_samples;
        rebuilt.looks = mdp.looks;
        current = rebuilt;
    }
    Err(CertifyError::Refine("no round ran".into()))
}
