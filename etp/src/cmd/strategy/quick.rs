//! `etp strategy DIR … --quick`: the fast exploration path. Select on DIR's
//! MDP (the exact occupation LP, a vertex, or with `--confidence` the
//! certified selection) and stop: no rebuild, so no prediction etp stands
//! by. The file's `predicted` is null; its values on the selection MDP —
//! biased by the optimiser's pick and by other strategies' beliefs in the
//! pools (docs/MODEL.md §7.3) — are kept under `diagnostics` and printed as
//! such. `etp strategy evaluate FILE DIR` predicts it later.

use super::{Args, Request, report_fields};
use anyhow::{Context, Result};
use etp_pipeline::output::refuse_existing;
use etp_pipeline::predictions;
use etp_pipeline::selection::{DEFAULT_LEVEL, selection_diagnostics};
use etp_pipeline::synthesis_dir::Synthesis;
use etp_synthesis::certify::intervals::interval_mdp;
use etp_synthesis::certify::select::certified_strategy;
use etp_synthesis::exec::Executor;
use etp_synthesis::pareto::optimal::{LpRequest, optimal_strategy};
use etp_synthesis::pareto::policy::{as_randomised, evaluate};
use etp_synthesis::pareto::select::{Request as FrontRequest, select};
use etp_synthesis::predict::request::Goal;
use serde_json::json;

pub fn run(a: &Args, request: Request, exec: &Executor) -> Result<()> {
    let dir = a.dir.as_deref().context("DIR is required")?;
    let syn = Synthesis::load(dir, a.out.output.as_deref(), exec)?;
    refuse_existing(exec, &syn.output, a.out.force)?;
    let cost = syn.cost();
    let mdp = &syn.mdp;
    let level = a.confidence.unwrap_or(DEFAULT_LEVEL);
    // The whole-MDP LP's objective, where the request is one (a cross-check
    // of the realised ω's exact value).
    let mut lp_objective = None;
    let (omega, value) = match (request, a.confidence) {
        (
            Request::Goal(Goal::MinTarget {
                min_target,
                max_collision,
            }),
            Some(l),
        ) => {
            let im = interval_mdp(mdp, l, cost).context("building the interval MDP")?;
            let c = certified_strategy(mdp, &im, cost, min_target, max_collision)
                .context("selecting a certified strategy")?;
            (c.strategy.policy, c.strategy.predicted)
        }
        (Request::Goal(goal), _) => {
            let r = match goal {
                Goal::MinTarget {
                    min_target,
                    max_collision,
                } => LpRequest::MinEnergy {
                    min_target,
                    max_collision,
                },
                Goal::MaxEnergy { max_energy } => LpRequest::MaxTarget { max_energy },
            };
            let o = optimal_strategy(mdp, cost, r).context("solving the occupation LP")?;
            lp_objective = Some(o.lp_objective);
            (o.policy, o.predicted)
        }
        (Request::Vertex(k), _) => {
            let s = select(&syn.front, FrontRequest::Vertex(k)).context("selecting a vertex")?;
            let omega = as_randomised(mdp, &syn.front.vertices[s.weights[0].0].policy);
            let value = evaluate(mdp, &omega, cost);
            (omega, value)
        }
    };
    let label = format!(
        "{} — quick: selected on the MDP, not predicted",
        request.label(
            a.confidence
                .filter(|_| matches!(request, Request::Goal(Goal::MinTarget { .. })))
        )
    );
    let mut strategy = syn.strategy_of(mdp, &omega, value, &label);
    let unmatched = selection_diagnostics(&mut strategy, mdp, &omega, cost, level)?;
    a.check
        .store_aggregation_check(&mut strategy, a.out.json, exec)?;
    a.out.write(exec, &syn, &strategy)?;
    if a.out.json {
        let mut m = report_fields(&syn, &strategy, "quick");
        if let Some(serde_json::Value::Object(d)) = m.get_mut("diagnostics") {
            d.insert("front_epsilon".into(), json!(syn.front.epsilon));
            d.insert("crossfit_unmatched_mass".into(), json!(unmatched));
            d.insert("lp_objective".into(), json!(lp_objective));
        }
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::Value::Object(m))?
        );
    } else {
        println!("{}", strategy.provenance.label);
        println!(
            "  QUICK: no prediction — the values below are the strategy's on the MDP it was selected on, BIASED (the optimiser's pick, other strategies' beliefs in the pools); `etp strategy evaluate {} {}` predicts it",
            syn.output.display(),
            syn.dir.display()
        );
        print!("{}", predictions::text_of(&strategy));
        println!("wrote {}", syn.output.display());
    }
    Ok(())
}
