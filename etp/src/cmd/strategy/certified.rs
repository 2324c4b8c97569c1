//! Certified bounds in `etp strategy` (docs/MODEL.md §4.1): their
//! computation on an MDP, and `--refine-gap`'s sample allocation on the
//! selection MDP before the request loop selects on it.

use super::Args;
use anyhow::{Context, Result, bail};
use etp_pipeline::output::{refuse_existing, write_new};
use etp_pipeline::progress;
use etp_pipeline::synthesis_dir::Synthesis;
use etp_synthesis::certify::intervals::interval_mdp;
use etp_synthesis::certify::refine::{Refined, prepare, refine};
use etp_synthesis::certify::select::certified_strategy;
use etp_synthesis::mdp::Mdp;
use serde_json::{Value, json};
use std::path::PathBuf;
use std::time::Instant;

/// `--refine-gap`: the selection MDP with samples added where the certified
/// strategy's gap binds (written to DIR/mdp-refined.bin).
pub struct Refinement {
    pub mdp: Mdp,
    pub refined: Refined,
    pub seconds: f64,
    pub path: PathBuf,
    pub gap: f64,
}

impl Refinement {
    pub fn json(&self) -> Value {
        let r = &self.refined;
        json!({
            "converged": r.converged,
            "added_segments": r.added_segments,
            "seconds": self.seconds,
            "mdp": self.path,
            "rounds": r.rounds.iter().map(|x| json!({"p_target": x.p_target,
                "p_target_low": x.p_target_low, "gap": x.p_target - x.p_target_low,
                "segments": x.segments, "doubled_choices": x.doubled})).collect::<Vec<_>>(),
        })
    }

    pub fn text(&self) -> String {
        let r = &self.refined;
        let mut t = format!(
            "  sample allocation on the selection MDP: {} rounds, {} extra segments, {:.1} s, gap target {} pt {}\n",
            r.rounds.len().saturating_sub(1),
            r.added_segments,
            self.seconds,
            100.0 * self.gap,
            if r.converged {
                "reached"
            } else {
                "NOT reached"
            }
        );
        for (k, x) in r.rounds.iter().enumerate() {
            t.push_str(&format!(
                "    round {k}: P_tar {:.6}  certified ≥ {:.6}  gap {:.4} pt  segments {}  doubled {}\n",
                x.p_target,
                x.p_target_low,
                100.0 * (x.p_target - x.p_target_low),
                x.segments,
                x.doubled
            ));
        }
        t.push_str(&format!("  wrote {}\n", self.path.display()));
        t
    }
}

/// Allocate samples on DIR's MDP for the certified request of `a`.
pub fn refine_selection(a: &Args, syn: &Synthesis, gap: f64, level: f64) -> Result<Refinement> {
    let Some(min_target) = a.min_target else {
        bail!("--refine-gap needs --min-target");
    };
    let mdp = &syn.mdp;
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
    let path = syn.dir.join("mdp-refined.bin");
    refuse_existing(&syn.exec, &path, a.out.force)?;
    let cost = syn.cost();
    let started = Instant::now();
    let prepared = prepare(mdp, a.refine_rounds);
    let mut p = etp_synthesis::abstraction::params_of(mdp);
    p.holdout_samples = 0;
    let units = etp_synthesis::abstraction::progress_total(&syn.scenario, &p);
    let pb = progress::bar(
        &syn.exec,
        units * u64::from(a.refine_rounds),
        "allocate",
        a.out.json,
    );
    let refined = refine(
        &syn.scenario,
        &prepared,
        gap,
        a.refine_rounds,
        &|m| {
            let im = interval_mdp(m, level, cost)?;
            let c = certified_strategy(m, &im, cost, min_target, a.max_collision)?;
            Ok((
                c.strategy.policy.clone(),
                c.strategy.predicted.p_target,
                c.certified.p_target_low,
            ))
        },
        &syn.exec.work(|k| pb.inc(k)),
    )
    .context("allocating samples")?;
    pb.finish_and_clear();
    write_new(&syn.exec, &path, &refined.mdp.encode(), a.out.force)?;
    Ok(Refinement {
        mdp: refined.mdp.clone(),
        refined,
        seconds: started.elapsed().as_secs_f64(),
        path,
        gap,
    })
}
