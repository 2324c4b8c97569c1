//! `etp strategy evaluate STRATEGY DIR`: a given strategy (the same ω,
//! states, bins and splits: it behaves exactly as before) predicted on its
//! own beliefs — DIR's abstraction rebuilt R times with the strategy's own
//! pools and thresholds (docs/MODEL.md §7.3) — with every prediction of
//! `etp strategy`: `predicted` with its ±, certified bounds on the first
//! rebuild, the aggregation check.

use super::{EvaluateArgs, report_fields};
use anyhow::{Context, Result, bail};
use etp_pipeline::output::refuse_existing;
use etp_pipeline::predictions;
use etp_pipeline::progress;
use etp_pipeline::synthesis_dir::Synthesis;
use etp_synthesis::abstraction;
use etp_synthesis::exec::Executor;
use serde_json::json;
use std::time::Instant;

pub fn run(a: &EvaluateArgs, exec: &Executor) -> Result<()> {
    a.out.check_folder()?;
    let syn = Synthesis::load(
        &a.dir,
        Some(a.out.output.as_deref().unwrap_or(&a.strategy)),
        exec,
    )?;
    let (mut strategy, _) = etp_runtime::strategy_arg::load_strategy(&a.strategy)
        .with_context(|| format!("etp strategy evaluate {}", a.strategy.display()))?;
    if strategy.policy.scenario_hash != syn.mdp.scenario_hash
        || strategy.policy.deltas != syn.mdp.deltas
    {
        bail!(
            "{}: a strategy of {} (hash {:.12}…), not of {}'s {} (hash {:.12}…) with its thresholds",
            a.strategy.display(),
            strategy.policy.scenario_name,
            strategy.policy.scenario_hash,
            a.dir.display(),
            syn.mdp.scenario_name,
            syn.mdp.scenario_hash
        );
    }
    if a.out.output.is_none() && !a.out.force {
        bail!(
            "etp strategy evaluate writes the strategy with its prediction: give -o FILE, or \
             --force to replace {} itself",
            a.strategy.display()
        );
    }
    refuse_existing(exec, &syn.output, a.out.force)?;
    let params = abstraction::params_of(&syn.mdp);
    let units = etp_synthesis::predict::rebuild::progress_units(&syn.scenario, &params);
    let pb = progress::bar(
        exec,
        units * u64::from(a.rebuilds.replicates),
        "rebuilds",
        a.out.json,
    );
    let started = Instant::now();
    // The rebuilds simulate the strategy under DIR's channel.
    strategy.policy.radio.clone_from(&syn.front.radio);
    let (on_policy, certified) =
        syn.predict(&strategy, a.rebuilds.replicates, a.confidence, &pb)?;
    pb.finish_and_clear();
    let first = on_policy.first();
    on_policy.stand_by(&mut strategy, &certified, a.confidence);
    if let Some(d) = strategy.predictions.diagnostics.as_mut() {
        d.rounds.clear();
    }
    strategy.provenance.label = format!(
        "{} — predicted on {}",
        strategy.provenance.label,
        a.dir.display()
    );
    strategy.predictions.aggregation = None;
    a.check
        .store_aggregation_check(&mut strategy, a.out.json, exec)?;
    a.out.write(exec, &syn, &strategy)?;
    let seconds = started.elapsed().as_secs_f64();
    if a.out.json {
        let mut m = report_fields(&syn, &strategy, "evaluated");
        if let Some(serde_json::Value::Object(d)) = m.get_mut("diagnostics") {
            d.insert(
                "rebuild".into(),
                json!({"states": first.mdp.states.len(),
                    "choices": first.mdp.states.iter().map(|s| s.choices.len()).sum::<usize>(),
                    "segments": on_policy.segments(), "seconds": seconds}),
            );
        }
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::Value::Object(m))?
        );
    } else {
        println!("{}", strategy.provenance.label);
        print!("{}", predictions::text_of(&strategy));
        println!(
            "  rebuilds: {} × {} states, {} segments, {seconds:.1} s",
            on_policy.replicas.len(),
            first.mdp.states.len(),
            on_policy.segments()
        );
        println!("wrote {}", syn.output.display());
    }
    Ok(())
}
