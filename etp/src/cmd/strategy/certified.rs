//! `etp strategy --min-target P [--max-collision C] --confidence L
//! [--refine-gap G]`: the least-energy strategy found whose certified bounds
//! meet the request (docs/MODEL.md §4.1), with optional sample allocation.

use super::{Args, COVER_ROUNDS};
use crate::cmd::honest;
use crate::output::{refuse_existing, write_new};
use crate::progress;
use anyhow::{Context, Result, bail};
use etp_shared::strategy::Strategy;
use etp_synthesis::certify::crossfit::{CrossFit, crossfit};
use etp_synthesis::certify::intervals::interval_mdp;
use etp_synthesis::certify::refine::{Refined, prepare, refine};
use etp_synthesis::certify::robust::{Certified, certify};
use etp_synthesis::certify::select::{METHOD, certified_strategy};
use etp_synthesis::certify::widen::{split_level, widen};
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::ParetoFront;
use etp_synthesis::pareto::optimal::{LpRequest, optimal_strategy};
use etp_synthesis::pareto::policy::RandomisedPolicy;
use etp_synthesis::pareto::to_strategy;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// Level of the certified bounds reported without `--confidence`.
pub const DEFAULT_LEVEL: f64 = 0.95;

/// Cross-fitted values and certified bounds of a strategy.
pub struct Assessment {
    pub crossfit: Option<CrossFit>,
    pub certified: etp_shared::strategy::CertifiedPrediction,
}

pub fn assess(
    mdp: &Mdp,
    policy: &RandomisedPolicy,
    cost: CostModel,
    level: f64,
) -> Result<Assessment> {
    let im = interval_mdp(mdp, level, cost).context("building the interval MDP")?;
    let c = certify(mdp, &im, policy);
    Ok(Assessment {
        crossfit: crossfit(mdp, policy, cost),
        certified: honest::certified_prediction(&c, level),
    })
}

/// The selection-time aggregation check of `strategy` (unless
/// `--aggregation-check 0`), stored in it; with `--cover-aggregation` its
/// certified bounds (computed at [`split_level`] of `level`) widened by it.
pub fn check_aggregation(strategy: &mut Strategy, a: &Args, level: f64) -> Result<()> {
    if a.aggregation_check == 0 {
        return Ok(());
    }
    let check = honest::aggregation_check(strategy, a.aggregation_check, a.json)?;
    strategy.aggregation = Some(check);
    if a.cover_aggregation
        && let Some(c) = &strategy.certified
    {
        strategy.certified = Some(widen(c, &check, level));
    }
    Ok(())
}

pub fn run(
    a: &Args,
    mdp: &Mdp,
    scenario_text: Option<String>,
    front: &ParetoFront,
    output: &Path,
    level: f64,
    refine_gap: Option<f64>,
) -> Result<()> {
    let Some(min_target) = a.min_target else {
        bail!("--confidence selects a certified strategy with --min-target only");
    };
    if !(0.0..=1.0).contains(&min_target) {
        bail!("--min-target must be a probability in [0, 1], got {min_target}");
    }
    if let Some(c) = a.max_collision
        && !(0.0..=1.0).contains(&c)
    {
        bail!("--max-collision must be a probability in [0, 1], got {c}");
    }
    refuse_existing(output, a.force)?;
    let cost = front.cost_model;
    // Under --cover-aggregation the abstraction's part is certified at
    // (1 + level)/2 and the measured error's at the same, so both hold at level.
    let bound_level = if a.cover_aggregation {
        split_level(level)
    } else {
        level
    };
    let select_for = |m: &Mdp, target: f64, collision: Option<f64>| {
        let im = interval_mdp(m, bound_level, cost)?;
        certified_strategy(m, &im, cost, target, collision)
    };
    let select = |m: &Mdp| select_for(m, min_target, a.max_collision);
    // Sample allocation first, if asked.
    let started = Instant::now();
    let mut refined: Option<Refined> = None;
    let mut work = mdp.clone();
    if let Some(g) = refine_gap {
        if mdp.build.merge_alpha > 0.0 {
            bail!(
                "--refine-gap needs an MDP built without --merge (its extra samples are \
                 allocated per state of the unmerged build)"
            );
        }
        if !mdp.splits.is_empty() {
            bail!(
                "--refine-gap needs an MDP built without --split-budget (its extra samples \
                 are allocated per state of the unsplit build)"
            );
        }
        let refined_path = a.dir.join("mdp-refined.bin");
        refuse_existing(&refined_path, a.force)?;
        let text = scenario_text
            .as_deref()
            .context("sample allocation needs DIR/scenario.toml (written by `etp synthesize`)")?;
        let mut scenario =
            etp_shared::scenario::Scenario::from_toml(text).context("parsing DIR/scenario.toml")?;
        // The extra segments are sampled under the channel of the first ones.
        if let Some(r) = &front.radio {
            scenario.radio = r.clone();
        }
        let prepared = prepare(mdp, a.refine_rounds);
        let mut p = etp_synthesis::abstraction::params_of(mdp);
        p.holdout_samples = 0;
        let units = etp_synthesis::abstraction::progress_total(&scenario, &p);
        let pb = progress::bar(units * u64::from(a.refine_rounds), "allocate", a.json);
        let r = refine(
            &scenario,
            &prepared,
            g,
            a.refine_rounds,
            &|m| {
                let c = select(m)?;
                Ok((
                    c.strategy.policy.clone(),
                    c.strategy.predicted.p_target,
                    c.certified.p_target_low,
                ))
            },
            &|k| pb.inc(k),
        )
        .context("allocating samples")?;
        pb.finish_and_clear();
        write_new(&refined_path, &r.mdp.encode(), a.force)?;
        work = r.mdp.clone();
        refined = Some(r);
    }
    let refine_seconds = started.elapsed().as_secs_f64();
    // The nominal optimum of the same request, for the price of certification.
    let nominal = optimal_strategy(
        &work,
        cost,
        LpRequest::MinEnergy {
            min_target,
            max_collision: a.max_collision,
        },
    )
    .ok();
    let label = match a.max_collision {
        Some(c) => {
            format!("least energy with certified P_tar ≥ {min_target} and P_coll ≤ {c} at {level}")
        }
        None => format!("least energy with certified P_tar ≥ {min_target} at {level}"),
    };
    let label = if a.cover_aggregation {
        format!("{label}, covering the measured aggregation error")
    } else {
        label
    };
    // Select, check the aggregation error and (covering it) widen; while the
    // widened bounds miss the request, ask the abstraction for what they lost.
    let (mut target, mut collision) = (min_target, a.max_collision);
    let mut cover_rounds = Vec::new();
    let (chosen, strategy, xf) = loop {
        let chosen = select_for(&work, target, collision).with_context(|| {
            format!("selecting a certified strategy (certified P_tar ≥ {target})")
        })?;
        let policy = &chosen.strategy.policy;
        let mut strategy = to_strategy(&work, policy, label.clone(), chosen.strategy.predicted);
        strategy.scenario_toml = scenario_text.clone();
        strategy.radio = front.radio.clone();
        let xf = crossfit(&work, policy, cost);
        honest::attach(
            &mut strategy,
            xf.as_ref(),
            &honest::certified_prediction(&chosen.certified, bound_level),
        );
        check_aggregation(&mut strategy, a, level)?;
        let Some(c) = strategy.certified.filter(|_| a.cover_aggregation) else {
            break (chosen, strategy, xf);
        };
        let short_target = min_target - c.p_target_low;
        let over_collision = a.max_collision.map_or(0.0, |m| c.p_collision_high - m);
        cover_rounds.push(json!({"requested_p_target": target, "requested_p_collision": collision,
            "widened_p_target_low": c.p_target_low, "widened_p_collision_high": c.p_collision_high}));
        if short_target <= 0.0 && over_collision <= 0.0 {
            break (chosen, strategy, xf);
        }
        if cover_rounds.len() == COVER_ROUNDS {
            bail!(
                "no strategy found whose bounds, widened by the measured aggregation error, meet the request \
                 after {COVER_ROUNDS} rounds (last: certified P_tar ≥ {:.6}, P_coll ≤ {:.6}); \
                 ask for less, or synthesize with more samples or --split-budget",
                c.p_target_low,
                c.p_collision_high
            );
        }
        target += short_target.max(0.0);
        collision = collision.map(|m| m - over_collision.max(0.0));
        if target > 1.0 || collision.is_some_and(|m| m < 0.0) {
            bail!(
                "the measured aggregation error ({:+.2} pt on P_tar) leaves no strategy of this MDP \
                 whose widened bounds meet the request",
                100.0 * strategy.aggregation.map_or(0.0, |g| g.error().p_target)
            );
        }
    };
    write_new(output, strategy.to_json().as_bytes(), a.force)?;
    let nominal_cert: Option<Certified> = nominal.as_ref().and_then(|n| {
        interval_mdp(&work, level, cost)
            .ok()
            .map(|im| certify(&work, &im, &n.policy))
    });
    let energy_paid = nominal
        .as_ref()
        .map(|n| chosen.strategy.predicted.energy - n.predicted.energy);
    if a.json {
        let v = json!({
            "strategy": output, "label": label,
            "method": METHOD,
            "exact": false,
            "confidence": level,
            "margins": {"p_target": chosen.margins.0, "p_collision": chosen.margins.1},
            "nominal_lp_solves": chosen.solves,
            "predictions": honest::json_of(&strategy),
            "crossfit_unmatched_mass": xf.as_ref().map(|c| c.unmatched_mass),
            "nominal_same_request": nominal.as_ref().map(|n| json!({
                "p_target": n.predicted.p_target, "p_collision": n.predicted.p_collision,
                "energy_mean": n.predicted.energy,
                "certified": nominal_cert.map(|c| json!({"p_target_low": c.p_target_low,
                    "p_collision_high": c.p_collision_high, "energy_high": c.energy_high}))})),
            "energy_paid_for_certification": energy_paid,
            "cover_aggregation_rounds": cover_rounds,
            "refinement": refined.as_ref().map(|r| json!({
                "converged": r.converged,
                "added_segments": r.added_segments,
                "seconds": refine_seconds,
                "mdp": a.dir.join("mdp-refined.bin"),
                "rounds": r.rounds.iter().map(|x| json!({"p_target": x.p_target,
                    "p_target_low": x.p_target_low, "gap": x.p_target - x.p_target_low,
                    "segments": x.segments, "doubled_choices": x.doubled})).collect::<Vec<_>>(),
            })),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!("{label}");
    println!("  method: {METHOD}");
    println!(
        "  nominal thresholds tightened by {:.3e} (P_tar){}; {} nominal LPs solved",
        chosen.margins.0,
        if a.max_collision.is_some() {
            format!(", {:.3e} (P_coll)", chosen.margins.1)
        } else {
            String::new()
        },
        chosen.solves
    );
    print!("{}", honest::text_of(&strategy));
    if cover_rounds.len() > 1 {
        println!(
            "  covering the aggregation error took {} selections: the request to the abstraction was raised to certified P_tar ≥ {target:.6}{}",
            cover_rounds.len(),
            collision
                .map(|c| format!(", P_coll ≤ {c:.6}"))
                .unwrap_or_default()
        );
    }
    if let Some(n) = &nominal {
        println!(
            "  nominal optimum of the same request: P_tar {:.6}  P_coll {:.6}  energy {:.4}{}",
            n.predicted.p_target,
            n.predicted.p_collision,
            n.predicted.energy,
            nominal_cert
                .map(|c| format!(" (certified P_tar ≥ {:.6})", c.p_target_low))
                .unwrap_or_default()
        );
        if let Some(p) = energy_paid {
            println!("  energy paid for certification: {p:+.4}");
        }
    }
    if let Some(r) = &refined {
        println!(
            "  sample allocation: {} rounds, {} extra segments, {:.1} s (each round re-runs the main abstraction), gap target {} pt {}",
            r.rounds.len().saturating_sub(1),
            r.added_segments,
            refine_seconds,
            100.0 * refine_gap.unwrap_or(0.0),
            if r.converged {
                "reached"
            } else {
                "NOT reached"
            }
        );
        for (k, x) in r.rounds.iter().enumerate() {
            println!(
                "    round {k}: P_tar {:.6}  certified ≥ {:.6}  gap {:.4} pt  segments {}  doubled {}",
                x.p_target,
                x.p_target_low,
                100.0 * (x.p_target - x.p_target_low),
                x.segments,
                x.doubled
            );
        }
        println!("  wrote {}", a.dir.join("mdp-refined.bin").display());
    }
    println!("wrote {}", output.display());
    Ok(())
}
