//! Adaptive splitting of regions (issue 25 item 3; docs/MODEL.md §7.3,
//! "Adaptive splitting"): start from the descriptor's regions, split the
//! ones the aggregation test flags, re-estimate, repeat.
//!
//! One **round**: episodes with uniformly random thresholds on the real
//! belief dynamics (the aggregation check's sampler, [`super::aggregation`],
//! from this module's own stream [`SPLIT_STREAM`] + round, so neither the
//! main, held-out and validation samples nor the aggregation check reported
//! after splitting share a number with the rounds) record, per decision
//! point, each belief's state, its covariance features and the leg's outcome.
//! Per (decision point, state, action) the segments are split at the median
//! of each covariance feature and the halves' outcomes tested for
//! homogeneity (χ², Benjamini–Hochberg at level α over the round's tests,
//! [`super::aggregation::test_segments`]; "where the samples allow": only
//! groups whose halves hold ≥ [`super::aggregation::MIN_HALF`] segments are
//! tested). Every flagged state is split once, on the feature and at the
//! median of its strongest flag (smallest p; the split point is a pure
//! function of the round's samples), strongest states first, until the
//! budget of splits is spent.
//!
//! **Re-estimation.** The MDP is built again on the *first* build's bins,
//! refined by all splits so far ([`super::build_split`]): every state —
//! split or not — gets its `samples` main and held-out segments afresh from
//! the pool particles of its (sub-)region, so transitions, costs and the
//! held-out (cross-fitted) estimates are consistent with the refined states
//! by construction. Keeping the first bins fixes what a split's parent
//! region means across rounds.
//!
//! Stops when a round flags nothing, the budget of splits is spent or the
//! rounds are done. Only covariance features are split on: the coordinator
//! classifies a belief from its covariance, so the estimate's drift (which
//! the aggregation check also tests) cannot define a region.
//!
//! Pure: no clock, no I/O; the caller times the rounds through `on_round`.

use super::aggregation::{Flag, MEAN_FEATURES, sample_segments_on, test_segments};
use super::{AbstractionError, AbstractionParams, build_split};
use crate::mdp::{Mdp, Method};
use etp_shared::discretization::{Region, RegionSplit};
use etp_shared::scenario::Scenario;
use serde::Serialize;

/// The random stream of round 0's episodes; round r uses `SPLIT_STREAM + r`.
pub const SPLIT_STREAM: u64 = 0x5B17_0000;

/// Settings of adaptive splitting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitSettings {
    /// At most this many splits over all rounds (each adds at most one state).
    pub budget: u32,
    /// At most this many rounds.
    pub rounds: u32,
    /// Episodes per round.
    pub episodes: u64,
    /// False discovery rate of a round's tests.
    pub alpha: f64,
}

impl Default for SplitSettings {
    /// Off (budget 0); two rounds of 20 000 episodes at a 5 % false discovery
    /// rate once a budget is given.
    fn default() -> Self {
        Self {
            budget: 0,
            rounds: 2,
            episodes: 20_000,
            alpha: 0.05,
        }
    }
}

/// What one round found and did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RoundReport {
    pub round: u32,
    /// (decision point, state, action) groups tested, tests run, groups too thin.
    pub groups_tested: usize,
    pub tests: usize,
    pub groups_thin: usize,
    /// Significant splits (on covariance features) and the states they flag.
    pub flags: usize,
    pub flagged_states: usize,
    /// Splits made this round.
    pub splits: usize,
    /// States of the MDP before and after this round.
    pub states_before: usize,
    pub states_after: usize,
}

/// The splits a round's flags ask for: per flagged state the strongest flag
/// (`flags` sorted strongest first, as [`test_segments`] returns them), in
/// that order, at most `budget`. `region_of(state)` is the state's decision
/// point and region (`None`: no such state, skipped).
pub fn splits_from_flags(
    flags: &[Flag],
    region_of: &dyn Fn(u32) -> Option<(u32, Region)>,
    budget: usize,
) -> Vec<RegionSplit> {
    let mut taken: Vec<u32> = Vec::new();
    let mut out = Vec::new();
    for f in flags {
        if out.len() >= budget {
            break;
        }
        if taken.contains(&f.state) {
            continue;
        }
        let (Some((dp, region)), Ok(feature)) = (region_of(f.state), u16::try_from(f.feature))
        else {
            continue;
        };
        taken.push(f.state);
        out.push(RegionSplit {
            decision_point: dp,
            region,
            feature,
            threshold: f.threshold,
        });
    }
    out
}

/// One round on `mdp`: sample, test, and the splits it asks for (at most
/// `budget`). `None` when the MDP has no regions (Method 1).
pub fn plan_round(
    scenario: &Scenario,
    mdp: &Mdp,
    round: u32,
    settings: &SplitSettings,
    budget: usize,
    progress: &dyn crate::exec::Work,
) -> Result<Option<(RoundReport, Vec<RegionSplit>)>, crate::exec::ExecError> {
    let Some(mut segments) = sample_segments_on(
        scenario,
        mdp,
        settings.episodes,
        mdp.seed,
        SPLIT_STREAM + u64::from(round),
        progress,
    )?
    else {
        return Ok(None);
    };
    for s in &mut segments {
        let keep = s.features.len().saturating_sub(MEAN_FEATURES);
        s.features.truncate(keep);
    }
    let (flags, groups_tested, tests, groups_thin) =
        test_segments(&segments, settings.alpha, &|_, _| None);
    let region_of = |state: u32| {
        let s = mdp.states.get(state as usize)?;
        Some((s.decision_point, s.region.clone()))
    };
    let splits = splits_from_flags(&flags, &region_of, budget);
    let mut flagged: Vec<u32> = flags.iter().map(|f| f.state).collect();
    flagged.sort_unstable();
    flagged.dedup();
    let report = RoundReport {
        round,
        groups_tested,
        tests,
        groups_thin,
        flags: flags.len(),
        flagged_states: flagged.len(),
        splits: splits.len(),
        states_before: mdp.states.len(),
        states_after: mdp.states.len(),
    };
    Ok(Some((report, splits)))
}

/// Split `first` (built by [`super::build`] with `params`) adaptively (see
/// the module doc). `on_round` sees each round's report once its MDP is
/// built. A Method 1 MDP, or `budget` or `rounds` 0, is returned as it is.
pub fn split_adaptively(
    scenario: &Scenario,
    params: &AbstractionParams,
    first: Mdp,
    settings: &SplitSettings,
    progress: &dyn crate::exec::Work,
    on_round: &mut dyn FnMut(&RoundReport),
) -> Result<Mdp, AbstractionError> {
    if first.method != Method::Discretized {
        return Ok(first);
    }
    let Some(bins) = first.discretization.clone() else {
        return Ok(first);
    };
    let mut splits = first.splits.clone();
    let mut mdp = first;
    for round in 0..settings.rounds {
        let left = (settings.budget as usize).saturating_sub(splits.len());
        if left == 0 {
            break;
        }
        let Some((mut report, new)) = plan_round(scenario, &mdp, round, settings, left, progress)?
        else {
            break;
        };
        if new.is_empty() {
            on_round(&report);
            break;
        }
        splits.extend(new);
        mdp = build_split(scenario, params, &bins, &splits, progress)?;
        report.states_after = mdp.states.len();
        on_round(&report);
    }
    Ok(mdp)
}

#[cfg(test)]
#[path = "split_tests.rs"]
mod tests;
