//! Adaptive splitting in `etp synthesize` (its `SplitSettings`: `--split-budget`,
//! `--split-rounds`, `--split-episodes`, `--split-alpha`; docs/MODEL.md §7.3
//! and `etp_synthesis::abstraction::split`): regions the aggregation test
//! flags are split and the MDP re-estimated, round by round.

use crate::error::{Context, Error, Result};
use crate::progress::Progress;
use etp_shared::scenario::Scenario;
use etp_synthesis::abstraction::split::{RoundReport, SplitSettings, split_adaptively};
use etp_synthesis::abstraction::{self, AbstractionParams};
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::{Mdp, Method};
use serde::Serialize;
use std::fmt::Write;
use std::time::Instant;

/// One round in the report: what the library found, and its wall time.
#[derive(Debug, Clone, Serialize)]
pub struct TimedRound {
    #[serde(flatten)]
    pub round: RoundReport,
    pub seconds: f64,
}

/// What splitting did.
#[derive(Debug, Clone, Serialize)]
pub struct SplitSummary {
    pub budget: u32,
    pub alpha: f64,
    pub episodes_per_round: u64,
    /// States of the first build (the descriptor's regions) and after splitting.
    pub states_before: usize,
    pub states_after: usize,
    pub states_per_decision_point_before: Vec<usize>,
    /// Regions split (all rounds).
    pub splits: usize,
    /// Wall time of the first build and of the splitting rounds.
    pub first_build_seconds: f64,
    pub seconds: f64,
    pub rounds: Vec<TimedRound>,
}

/// Refuse impossible settings before any work.
pub fn check(a: &SplitSettings, method: Method) -> Result<()> {
    if a.budget == 0 {
        return Ok(());
    }
    if method != Method::Discretized {
        return Err(Error::request(
            "--split-budget applies to --method discretized only (Method 1 has no regions)",
        ));
    }
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        return Err(Error::request(format!(
            "--split-alpha must lie in (0, 1) (got {})",
            a.alpha
        )));
    }
    if a.episodes == 0 || a.rounds == 0 {
        return Err(Error::request(
            "--split-episodes and --split-rounds must be at least 1 with --split-budget",
        ));
    }
    Ok(())
}

/// Split `first` adaptively when `--split-budget` asks for it.
pub fn apply(
    scenario: &Scenario,
    params: &AbstractionParams,
    first: Mdp,
    first_build_seconds: f64,
    a: &SplitSettings,
    progress: &Progress,
    exec: &Executor,
) -> Result<(Mdp, Option<SplitSummary>)> {
    if a.budget == 0 || first.method != Method::Discretized {
        return Ok((first, None));
    }
    let per_round = a.episodes + abstraction::progress_total(scenario, params);
    let pb = progress.bar(exec, per_round * u64::from(a.rounds), "splitting");
    let (states_before, per_dp_before) = (first.states.len(), first.states_per_decision_point());
    let started = Instant::now();
    let mut last = Instant::now();
    let mut rounds = Vec::new();
    let mdp = split_adaptively(
        scenario,
        params,
        first,
        a,
        &exec.work(|k| pb.inc(k)),
        &mut |r| {
            rounds.push(TimedRound {
                round: r.clone(),
                seconds: last.elapsed().as_secs_f64(),
            });
            last = Instant::now();
        },
    )
    .computing("splitting regions")?;
    pb.finish_and_clear();
    mdp.check()
        .computing("the split MDP failed its own consistency check (a bug)")?;
    let summary = SplitSummary {
        budget: a.budget,
        alpha: a.alpha,
        episodes_per_round: a.episodes,
        states_before,
        states_after: mdp.states.len(),
        states_per_decision_point_before: per_dp_before,
        splits: mdp.splits.len(),
        first_build_seconds,
        seconds: started.elapsed().as_secs_f64(),
        rounds,
    };
    Ok((mdp, Some(summary)))
}

/// The text report.
pub fn describe(s: &SplitSummary) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "  splitting (budget {}, FDR {}, {} episodes per round): {} regions split, states {} → {} ({:?} per decision point before) · first build {:.2} s, splitting {:.2} s",
        s.budget,
        s.alpha,
        s.episodes_per_round,
        s.splits,
        s.states_before,
        s.states_after,
        s.states_per_decision_point_before,
        s.first_build_seconds,
        s.seconds
    );
    for r in &s.rounds {
        let _ = writeln!(
            o,
            "    round {}: {} significant splits in {} states ({} groups tested, {} too thin) → {} split, states {} → {} ({:.2} s)",
            r.round.round,
            r.round.flags,
            r.round.flagged_states,
            r.round.groups_tested,
            r.round.groups_thin,
            r.round.splits,
            r.round.states_before,
            r.round.states_after,
            r.seconds
        );
    }
    o
}
