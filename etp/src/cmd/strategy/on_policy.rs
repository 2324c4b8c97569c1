//! `etp strategy DIR … --on-policy [--replicates R]`: the strategy just
//! selected, predicted again on rebuilds of the abstraction whose pools are
//! its own (true state, belief) pairs and whose states simulate only its
//! own thresholds (docs/MODEL.md §7.3) — in one command what `etp synthesize
//! --pool-policy` and `etp strategy --evaluate` do in two, with DIR's own
//! settings; replicate r uses DIR's seed + r, so `--replicates 1` gives the
//! numbers of the two-step way. With R ≥ 2 (default 4) the cross-fitted value is the
//! replicates' mean and its ± a Student-t interval over their spread, which
//! covers the rebuild's whole Monte Carlo (`certify::replicates`). The
//! rebuilt MDPs are not kept.

use super::evaluate::policy_on;
use crate::progress;
use anyhow::{Context, Result, bail};
use etp_shared::strategy::{PredictionCi95, Strategy};
use etp_synthesis::abstraction;
use etp_synthesis::certify::crossfit::crossfit;
use etp_synthesis::certify::replicates::{Replicated, replicated};
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::policy::{Objectives, RandomisedPolicy, evaluate, leg_energy};
use serde_json::json;
use std::time::Instant;

/// One rebuild and the strategy evaluated on it, once.
pub struct Replica {
    pub mdp: Mdp,
    /// The strategy's ω on this rebuild's states.
    pub omega: RandomisedPolicy,
    /// Selection-time value and per-leg energy on this rebuild.
    pub predicted: Objectives,
    pub leg_energy: Vec<f64>,
}

/// The rebuilds (replicate r with DIR's seed + r) and what they cost.
pub struct Rebuilt {
    pub replicas: Vec<Replica>,
    pub seconds: f64,
    /// With two or more: each replicate's cross-fitted value, and their mean.
    pub replicated: Option<(Vec<Objectives>, Replicated)>,
}

impl Rebuilt {
    /// The first rebuild (the two-step way's).
    pub fn first(&self) -> &Replica {
        &self.replicas[0]
    }

    fn segments(&self) -> u64 {
        self.replicas.iter().map(|r| r.mdp.total_segments).sum()
    }

    /// What `--json` reports of the rebuilds.
    pub fn json(&self) -> serde_json::Value {
        let m = &self.first().mdp;
        json!({
            "states": m.states.len(),
            "choices": m.states.iter().map(|s| s.choices.len()).sum::<usize>(),
            "segments": self.segments(),
            "seconds": self.seconds,
            "replicates": self.replicas.iter().enumerate().map(|(r, x)| json!({
                "seed": x.mdp.seed,
                "crossfit": self.replicated.as_ref().and_then(|(v, _)| v.get(r)).map(|o| json!({
                    "p_target": o.p_target, "p_collision": o.p_collision, "energy_mean": o.energy})),
            })).collect::<Vec<_>>(),
        })
    }

    /// The text report's lines.
    pub fn describe(&self) -> String {
        let m = &self.first().mdp;
        let mut s = format!(
            "  on its own pools: rebuilt with {} states, {} segments in {:.1} s (docs/MODEL.md §7.3); the predictions below are the rebuild's\n",
            m.states.len(),
            self.segments(),
            self.seconds
        );
        if let Some((v, r)) = &self.replicated {
            let list: Vec<String> = v.iter().map(|o| format!("{:.4}", o.p_target)).collect();
            s.push_str(&format!(
                "  {} replicates (seeds {}…{}), cross-fitted P_tar {}: their mean, its ± Student's t over their spread (the rebuilds' whole Monte Carlo); selection-time their mean, certified the first's\n",
                r.replicates,
                m.seed,
                self.replicas.last().map_or(m.seed, |l| l.mdp.seed),
                list.join(", ")
            ));
        }
        s
    }
}

/// Rebuild `mdp`'s abstraction `replicates` times (same settings, seeds
/// DIR's + r) with the pools drawn on `strategy`, carrying the true state,
/// on its thresholds only, and evaluate `strategy` on each; with two or
/// more, the replicates' cross-fitted values combined.
pub fn rebuild(
    strategy: &Strategy,
    mdp: &Mdp,
    cost: CostModel,
    replicates: u32,
    quiet: bool,
) -> Result<Rebuilt> {
    let scenario = strategy
        .scenario()
        .context("--on-policy needs the strategy's scenario")?;
    let params = abstraction::params_of(mdp);
    let pb = progress::bar(
        abstraction::progress_total(&scenario, &params) * u64::from(replicates.max(1)),
        "on-policy rebuild",
        quiet,
    );
    let started = Instant::now();
    let mut replicas = Vec::new();
    for r in 0..replicates.max(1) {
        let mut p = params;
        p.seed = params.seed.wrapping_add(u64::from(r));
        let m = abstraction::build_on_policy(&scenario, &p, strategy, true, true, &|k| pb.inc(k))
            .with_context(|| format!("--on-policy: rebuild {r} on the strategy's own pools"))?;
        m.check()
            .context("a rebuilt MDP failed its own consistency check (a bug)")?;
        let omega = policy_on(&m, strategy);
        replicas.push(Replica {
            predicted: evaluate(&m, &omega, cost),
            leg_energy: leg_energy(&m, &omega, cost),
            omega,
            mdp: m,
        });
    }
    pb.finish_and_clear();
    let replicated = if replicas.len() >= 2 {
        let mut values = Vec::with_capacity(replicas.len());
        for x in &replicas {
            let Some(c) = crossfit(&x.mdp, &x.omega, cost) else {
                bail!("--replicates: DIR's MDP has no held-out sample to cross-fit on");
            };
            values.push(c.objectives);
        }
        let r = replicated(&values).context("--replicates: combining the rebuilds")?;
        Some((values, r))
    } else {
        None
    };
    Ok(Rebuilt {
        replicas,
        seconds: started.elapsed().as_secs_f64(),
        replicated,
    })
}

/// Replace the predictions `strategy` took from the first rebuild by the
/// replicates' (selection-time and per-leg energy: their mean; cross-fitted:
/// their mean and Student-t ±); its certified bounds stay the first's.
pub fn apply_replicates(strategy: &mut Strategy, rebuilt: &Rebuilt) {
    let Some((_, r)) = &rebuilt.replicated else {
        return;
    };
    let n = rebuilt.replicas.len() as f64;
    let mut selection = Objectives::default();
    let mut legs: Vec<f64> = Vec::new();
    for x in &rebuilt.replicas {
        selection.p_target += x.predicted.p_target / n;
        selection.p_collision += x.predicted.p_collision / n;
        selection.energy += x.predicted.energy / n;
        if legs.len() < x.leg_energy.len() {
            legs.resize(x.leg_energy.len(), 0.0);
        }
        for (l, e) in legs.iter_mut().zip(&x.leg_energy) {
            *l += e / n;
        }
    }
    strategy.predicted = crate::cmd::honest::prediction(&selection);
    strategy.leg_energy = Some(legs);
    strategy.crossfit = Some(crate::cmd::honest::prediction(&r.mean));
    strategy.crossfit_ci95 = Some(PredictionCi95 {
        p_target: r.ci95.p_target,
        p_collision: r.ci95.p_collision,
        energy_mean: r.ci95.energy,
    });
}
