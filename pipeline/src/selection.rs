//! The strategy `etp strategy DIR --min-target P` stands by, made from a
//! loaded synthesis: the request loop's outcome (docs/MODEL.md §7.4) turned
//! into the strategy file — the prediction from its on-policy rebuilds, the
//! certified bounds of its first rebuild, the selection-MDP values as
//! diagnostics, the rounds, the aggregation check. `etp strategy` and `etp
//! study` write the same bytes through it.

use crate::error::{Context, Result};
use crate::predictions;
use crate::progress::Progress;
use crate::synthesis_dir::Synthesis;
use etp_shared::strategy::{CertifiedPrediction, Strategy};
use etp_synthesis::certify::crossfit::{CrossFit, crossfit};
use etp_synthesis::certify::intervals::interval_mdp;
use etp_synthesis::certify::robust::{Certified, certify};
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::policy::RandomisedPolicy;
use etp_synthesis::predict::request::{Goal, Outcome, Verdict};

/// Level of the certified bounds reported without `--confidence`.
pub const DEFAULT_LEVEL: f64 = 0.95;

/// Cross-fitted values and certified bounds of a strategy on one MDP.
pub struct Assessment {
    pub crossfit: Option<CrossFit>,
    pub certified: CertifiedPrediction,
}

/// The cross-fitted values (DIR synthesized with a held-out sample) and the
/// certified bounds at `level` of `policy` on `mdp`.
pub fn assess(
    mdp: &Mdp,
    policy: &RandomisedPolicy,
    cost: CostModel,
    level: f64,
) -> Result<Assessment> {
    let im = interval_mdp(mdp, level, cost).computing("building the interval MDP")?;
    let c = certify(mdp, &im, policy);
    Ok(Assessment {
        crossfit: crossfit(mdp, policy, cost),
        certified: CertifiedPrediction {
            confidence: level,
            p_target_low: c.p_target_low,
            p_collision_high: c.p_collision_high,
            energy_high: c.energy_high,
            covers_aggregation: false,
        },
    })
}

/// The strategy's label for a request (`certified`: selected on certified
/// bounds at that level).
pub fn goal_label(goal: Goal, certified: Option<f64>) -> String {
    let cert = |what: &str| match certified {
        Some(l) => format!("certified {what} at {l}"),
        None => what.to_string(),
    };
    match goal {
        Goal::MinTarget {
            min_target,
            max_collision: Some(c),
        } => format!(
            "least energy with {} and {}",
            cert(&format!("P_tar ≥ {min_target}")),
            cert(&format!("P_coll ≤ {c}"))
        ),
        Goal::MinTarget { min_target, .. } => {
            format!(
                "least energy with {}",
                cert(&format!("P_tar ≥ {min_target}"))
            )
        }
        Goal::MaxEnergy { max_energy } => format!("highest P_tar with energy ≤ {max_energy}"),
    }
}

/// The values of `omega` on the selection MDP, stored as diagnostics; the
/// cross-fit's unmatched mass when DIR has a held-out sample.
pub fn selection_diagnostics(
    strategy: &mut Strategy,
    mdp: &Mdp,
    omega: &RandomisedPolicy,
    cost: CostModel,
    level: f64,
) -> Result<Option<f64>> {
    let a = assess(mdp, omega, cost, level)?;
    let d = strategy
        .predictions
        .diagnostics
        .get_or_insert_with(Default::default);
    d.selection.crossfit = a.crossfit.as_ref().map(|c| c.objectives.prediction());
    d.selection.crossfit_ci95 = a.crossfit.as_ref().map(|c| c.ci95());
    d.selection.certified = Some(a.certified);
    Ok(a.crossfit.map(|c| c.unmatched_mass))
}

/// The strategy file of an outcome: what it stands by, its diagnostics on
/// `mdp` (the selection MDP), the rounds, "OUT OF REACH" in the label of a
/// request the loop could not meet, and the aggregation check of
/// `aggregation_check` episodes (0: none). Returns the file and the
/// cross-fit's unmatched mass.
pub fn standing_strategy(
    syn: &Synthesis,
    mdp: &Mdp,
    outcome: &Outcome,
    certified: &Certified,
    level: f64,
    aggregation_check: u64,
    progress: &Progress,
) -> Result<(Strategy, Option<f64>)> {
    let mut strategy = outcome.strategy.clone();
    outcome.on_policy.stand_by(&mut strategy, certified, level);
    let unmatched = selection_diagnostics(&mut strategy, mdp, &outcome.omega, syn.cost(), level)?;
    if let Some(d) = strategy.predictions.diagnostics.as_mut() {
        d.rounds = outcome.rounds.iter().map(|r| r.record()).collect();
    }
    if outcome.verdict != Verdict::Met {
        strategy.provenance.label = format!(
            "{} — OUT OF REACH: the closest strategy found",
            strategy.provenance.label
        );
    }
    if aggregation_check > 0 {
        strategy.predictions.aggregation =
            predictions::aggregation_check(&strategy, aggregation_check, progress, &syn.exec)?;
    }
    Ok((strategy, unmatched))
}

/// How a request is met: `etp strategy DIR --min-target P`'s options
/// (defaults: [`Default`]).
#[derive(Debug, Clone, Copy)]
pub struct RequestSettings {
    /// On-policy rebuilds of each prediction (`--replicates`).
    pub replicates: u32,
    /// Rounds of the request loop at most (`--rounds`).
    pub rounds: u32,
    /// Select on certified bounds at this level (`--confidence`; a
    /// `MinTarget` goal only); without it the bounds are reported at
    /// [`DEFAULT_LEVEL`].
    pub confidence: Option<f64>,
    /// Episodes of the selection-time aggregation check (0: none).
    pub aggregation_check: u64,
}

impl Default for RequestSettings {
    fn default() -> Self {
        Self {
            replicates: etp_synthesis::predict::rebuild::DEFAULT_REPLICATES,
            rounds: etp_synthesis::predict::request::DEFAULT_ROUNDS,
            confidence: None,
            aggregation_check: predictions::AGGREGATION_CHECK_EPISODES,
        }
    }
}

/// The selection step: the request loop for `goal` on `mdp` (`syn`'s own,
/// or a refinement of it: `etp strategy --refine-gap`) and the strategy it
/// stands by (the bytes `etp strategy DIR --min-target P` writes for the
/// same settings): the outcome, the file, the cross-fit's unmatched mass.
/// `etp strategy`, `etp demo`, `etp study` and Python all select through it.
pub fn meet_goal(
    syn: &Synthesis,
    mdp: &Mdp,
    goal: Goal,
    s: &RequestSettings,
    progress: &Progress,
) -> Result<(Outcome, Strategy, Option<f64>)> {
    let level = s.confidence.unwrap_or(DEFAULT_LEVEL);
    let certified = match goal {
        Goal::MinTarget { .. } => s.confidence,
        Goal::MaxEnergy { .. } => None,
    };
    let label = goal_label(goal, certified);
    let make = |omega: &RandomisedPolicy, value: etp_synthesis::pareto::policy::Objectives| {
        syn.strategy_of(mdp, omega, value, &label)
    };
    let pb = progress.bar(&syn.exec, 0, "rebuilds");
    let outcome = syn.meet(
        mdp,
        goal,
        etp_synthesis::predict::request::LoopSettings {
            replicates: s.replicates,
            max_rounds: s.rounds,
            certified,
        },
        level,
        &make,
        &pb,
    )?;
    pb.finish_and_clear();
    let (strategy, unmatched) = standing_strategy(
        syn,
        mdp,
        &outcome,
        &outcome.certified,
        level,
        s.aggregation_check,
        progress,
    )?;
    Ok((outcome, strategy, unmatched))
}
