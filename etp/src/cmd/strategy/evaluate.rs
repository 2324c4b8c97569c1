//! `etp strategy DIR --evaluate STRATEGY.json`: a strategy chosen elsewhere,
//! the same ω, predicted again on DIR's MDP — typically one built with
//! `etp synthesize --pool-policy STRATEGY.json`, whose pools are that
//! strategy's own beliefs, so that its prediction there carries no
//! aggregation error (docs/MODEL.md §7.3). The file written is the given
//! strategy (states, bins, splits: it behaves exactly as before) with the
//! predictions of DIR: selection-time, cross-fitted with its own sampling
//! error, certified, per-leg energy, and the aggregation check.

use super::{Args, certified};
use crate::output::write_new;
use anyhow::{Context, Result, bail};
use etp_shared::strategy::{OmegaChoice, Strategy};
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::policy::{RandomisedPolicy, evaluate, leg_energy};
use serde_json::json;
use std::path::Path;

/// ω of `strategy` on every state of `mdp` (by region; a region the strategy
/// never saw takes its nearest, as the strategy itself does at run time).
pub fn policy_on(mdp: &Mdp, strategy: &Strategy) -> RandomisedPolicy {
    let smallest = |n: usize| {
        let mut w = vec![0.0; n];
        if let Some(x) = w.first_mut() {
            *x = 1.0;
        }
        w
    };
    mdp.states
        .iter()
        .map(|s| {
            let omega = match strategy.omega_of_region(s.decision_point as usize, &s.region) {
                OmegaChoice::Exact(w) | OmegaChoice::Nearest(w) => w.to_vec(),
                OmegaChoice::FullKf(i) => {
                    let mut w = vec![0.0; strategy.deltas.len()];
                    if let Some(x) = w.get_mut(i) {
                        *x = 1.0;
                    }
                    w
                }
            };
            let mut row: Vec<f64> = s
                .choices
                .iter()
                .map(|c| omega.get(c.action as usize).copied().unwrap_or(0.0))
                .collect();
            let sum: f64 = row.iter().sum();
            if sum > 0.0 {
                row.iter_mut().for_each(|p| *p /= sum);
                row
            } else {
                // None of ω's thresholds is offered here: the first choice
                // (the smallest δ, as for a region without a state).
                smallest(row.len())
            }
        })
        .collect()
}

pub fn run(
    a: &Args,
    path: &Path,
    mdp: &Mdp,
    cost: CostModel,
    front_epsilon: f64,
    output: &Path,
    level: f64,
) -> Result<()> {
    let (mut strategy, _) = crate::cmd::validate::load_strategy(path)
        .with_context(|| format!("--evaluate {}", path.display()))?;
    if strategy.scenario_hash != mdp.scenario_hash || strategy.deltas != mdp.deltas {
        bail!(
            "--evaluate {}: a strategy of {} (hash {:.12}…), not of this MDP's {} (hash {:.12}…) with its thresholds",
            path.display(),
            strategy.scenario_name,
            strategy.scenario_hash,
            mdp.scenario_name,
            mdp.scenario_hash
        );
    }
    let omega = policy_on(mdp, &strategy);
    let predicted = evaluate(mdp, &omega, cost);
    let label = format!("{} — evaluated on {}", strategy.label, a.dir.display());
    strategy.label.clone_from(&label);
    strategy.predicted = crate::cmd::honest::prediction(&predicted);
    strategy.leg_energy = Some(leg_energy(mdp, &omega, cost));
    strategy.aggregation = None;
    let bound_level = if a.cover_aggregation {
        etp_synthesis::certify::widen::split_level(level)
    } else {
        level
    };
    let honest = certified::assess(mdp, &omega, cost, bound_level)?;
    crate::cmd::honest::attach(&mut strategy, honest.crossfit.as_ref(), &honest.certified);
    certified::check_aggregation(&mut strategy, a, level)?;
    write_new(output, strategy.to_json().as_bytes(), a.force)?;
    if a.json {
        let v = json!({
            "strategy": output, "label": label,
            "predicted": super::objectives_json(&predicted),
            "exact": false,
            "vertex_mixture": null,
            "occupation_lp_energy": null,
            "front_epsilon": front_epsilon,
            "predictions": crate::cmd::honest::json_of(&strategy),
            "crossfit_unmatched_mass": honest.crossfit.as_ref().map(|c| c.unmatched_mass),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("{label}");
        println!(
            "  predicted  P_tar {:.6}  P_coll {:.6}  energy {:.6}",
            predicted.p_target, predicted.p_collision, predicted.energy
        );
        print!("{}", crate::cmd::honest::text_of(&strategy));
        println!("wrote {}", output.display());
    }
    Ok(())
}
