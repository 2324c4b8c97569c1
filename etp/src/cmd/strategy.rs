//! `etp strategy DIR (--min-target P [--max-collision C] | --max-energy E | --vertex K)`:
//! the exact least-energy (or highest-target) strategy meeting the constraints —
//! the whole-MDP occupation-measure LP realised as a memoryless randomised
//! strategy (docs/MODEL.md §5) — written as `strategy.json`. The mixture of
//! front vertices closest to it is printed beside it as an explanation.
//!
//! Every strategy is reported with its selection-time value, its cross-fitted
//! value (held-out transitions) and their gap, and its certified bounds
//! (docs/MODEL.md §4.1). `--confidence` with `--min-target` selects on the
//! certified bounds instead; `--refine-gap` allocates samples first.

use crate::output::{read_front, read_mdp, refuse_existing, write_new};
use anyhow::{Context, Result, bail};
use clap::ArgGroup;
use etp_synthesis::pareto::optimal::{LpRequest, UNVISITED, optimal_strategy};
use etp_synthesis::pareto::policy::{Objectives, as_randomised, evaluate};
use etp_synthesis::pareto::select::{Request, select};
use etp_synthesis::pareto::to_strategy;
use serde_json::json;
use std::path::PathBuf;

mod certified;
mod evaluate;
mod on_policy;

#[derive(Debug, clap::Args)]
#[command(group(ArgGroup::new("request").required(true).args(["min_target", "max_energy", "vertex", "evaluate"])))]
pub struct Args {
    /// Output directory of `etp synthesize` (holds mdp.bin and front.json).
    pub dir: PathBuf,
    /// Least energy with P_tar ≥ P.
    #[arg(long, value_name = "P")]
    pub min_target: Option<f64>,
    /// With --min-target: also P_coll ≤ C.
    #[arg(long, value_name = "C", requires = "min_target")]
    pub max_collision: Option<f64>,
    /// Highest P_tar with expected energy ≤ E.
    #[arg(long, value_name = "E")]
    pub max_energy: Option<f64>,
    /// Vertex K of the front (0 = least energy; see front.json).
    #[arg(long, value_name = "K")]
    pub vertex: Option<usize>,
    /// The strategy of this file (same ω, same states) predicted again on
    /// DIR's MDP, e.g. one built with `etp synthesize --pool-policy FILE`
    /// (its own beliefs in the pools: no aggregation error, docs/MODEL.md §7.3).
    #[arg(long, value_name = "STRATEGY.json")]
    pub evaluate: Option<PathBuf>,
    /// Where to write the strategy (default DIR/strategy.json).
    #[arg(short = 'o', long = "out", alias = "output")]
    pub output: Option<PathBuf>,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
    /// Print the selection as JSON.
    #[arg(long)]
    pub json: bool,
    /// With --min-target: choose the least-energy strategy found whose
    /// *certified* bounds (at this confidence, e.g. 0.95) meet the request.
    /// Otherwise only the level of the reported certified bounds (default 0.95).
    #[arg(long, value_name = "LEVEL")]
    pub confidence: Option<f64>,
    /// With --confidence and --min-target: add samples on the strategy's
    /// support (doubling them, at most --refine-rounds times) until the
    /// certified P_tar gap (selection-time − certified lower bound) is ≤ G;
    /// writes DIR/mdp-refined.bin.
    #[arg(long, value_name = "G", requires_all = ["confidence", "min_target"])]
    pub refine_gap: Option<f64>,
    /// Rounds of sample allocation at most (each re-runs the abstraction).
    #[arg(long, default_value_t = 3, requires = "refine_gap")]
    pub refine_rounds: u32,
    /// Episodes of the selection-time aggregation check: the strategy is
    /// simulated in-process and its cross-fitted value compared (stored in
    /// strategy.json, printed, re-measured by `etp validate`); 0 = no check.
    #[arg(long, value_name = "N", default_value_t = super::honest::AGGREGATION_CHECK_EPISODES)]
    pub aggregation_check: u64,
    /// Widen the certified bounds by the measured aggregation error, so that
    /// they cover it too (each part at (1 + level)/2, union bound). With
    /// --confidence and --min-target the strategy is chosen on the widened
    /// bound (the request is raised by what the check takes, and selection
    /// repeated, at most 4 times).
    #[arg(long)]
    pub cover_aggregation: bool,
    /// Predict the selected strategy again on a rebuild of DIR's abstraction
    /// (same settings and seed) whose pools are its own beliefs and true
    /// states, simulating only its thresholds: its aggregation error removed
    /// (docs/MODEL.md §7.3) for about 1/|Δ| of a synthesis per rebuild
    /// (--replicates). With --replicates 1, the numbers of `etp synthesize
    /// --pool-policy` + `etp strategy --evaluate`.
    #[arg(long, conflicts_with_all = ["evaluate", "refine_gap"])]
    pub on_policy: bool,
    /// With --on-policy: R rebuilds (seeds DIR's + 0 … R − 1); from 2 on,
    /// the cross-fitted value is their mean and its ± a Student-t interval
    /// over their spread, which covers the rebuild's whole Monte Carlo (one
    /// rebuild's ± counts only its held-out sample: docs/MODEL.md §7.3).
    /// 1: a single rebuild, a quarter of the time, a ± that is too narrow.
    #[arg(long, value_name = "R", default_value_t = 4, requires = "on_policy",
          value_parser = clap::value_parser!(u32).range(1..=64))]
    pub replicates: u32,
}

/// Rounds of re-selection under `--cover-aggregation` with `--confidence`.
const COVER_ROUNDS: usize = 4;

fn probability(name: &str, v: f64) -> Result<f64> {
    if !(0.0..=1.0).contains(&v) {
        bail!("{name} must be a probability in [0, 1], got {v}");
    }
    Ok(v)
}

fn objectives_json(o: &Objectives) -> serde_json::Value {
    json!({"p_target": o.p_target, "p_collision": o.p_collision, "energy_mean": o.energy})
}

/// `--evaluate`: the given strategy predicted on DIR's MDP.
fn evaluate_elsewhere_chosen(a: &Args, path: &std::path::Path) -> Result<()> {
    if a.confidence.is_some() && a.refine_gap.is_some() {
        bail!("--evaluate takes no --refine-gap (the strategy is given)");
    }
    let level = match a.confidence {
        Some(c) if !(c > 0.0 && c < 1.0) => {
            bail!("--confidence must lie strictly between 0 and 1, got {c}")
        }
        Some(c) => c,
        None => certified::DEFAULT_LEVEL,
    };
    if a.cover_aggregation && a.aggregation_check == 0 {
        bail!("--cover-aggregation needs the aggregation check (--aggregation-check N > 0)");
    }
    let (mdp, _) = read_mdp(&a.dir)?;
    let front = read_front(&a.dir, &mdp)?;
    let output = a
        .output
        .clone()
        .unwrap_or_else(|| a.dir.join("strategy.json"));
    evaluate::run(
        a,
        path,
        &mdp,
        front.cost_model,
        front.epsilon,
        &output,
        level,
    )
}

pub fn run(a: Args) -> Result<()> {
    if let Some(path) = &a.evaluate {
        return evaluate_elsewhere_chosen(&a, path);
    }
    let request = match (a.min_target, a.max_energy, a.vertex) {
        (Some(p), None, None) => Request::MinTarget {
            min_target: probability("--min-target", p)?,
            max_collision: a
                .max_collision
                .map(|c| probability("--max-collision", c))
                .transpose()?,
        },
        (None, Some(e), None) => {
            if !(e.is_finite() && e >= 0.0) {
                bail!("--max-energy must be a finite number ≥ 0, got {e}");
            }
            Request::MaxEnergy { max_energy: e }
        }
        (None, None, Some(k)) => Request::Vertex(k),
        _ => bail!("give exactly one of --min-target, --max-energy, --vertex"),
    };
    let (mdp, scenario_text) = read_mdp(&a.dir)?;
    if mdp.policy_only() {
        bail!(
            "{}: this MDP offers at its states only the thresholds of the strategy its pools \
             were drawn on (`etp synthesize --pool-policy` without --all-actions), so its front \
             is not the scenario's; predict that strategy with --evaluate STRATEGY.json, or \
             rebuild with --all-actions to select others on these pools",
            a.dir.display()
        );
    }
    let front = read_front(&a.dir, &mdp)?;
    let output = a
        .output
        .clone()
        .unwrap_or_else(|| a.dir.join("strategy.json"));
    let cost = front.cost_model;
    let lp_request = match request {
        Request::MinTarget {
            min_target,
            max_collision,
        } => Some(LpRequest::MinEnergy {
            min_target,
            max_collision,
        }),
        Request::MaxEnergy { max_energy } => Some(LpRequest::MaxTarget { max_energy }),
        Request::Vertex(_) => None,
    };
    let level = match a.confidence {
        Some(c) if !(c > 0.0 && c < 1.0) => {
            bail!("--confidence must lie strictly between 0 and 1, got {c}")
        }
        Some(c) => c,
        None => certified::DEFAULT_LEVEL,
    };
    if a.cover_aggregation && a.aggregation_check == 0 {
        bail!("--cover-aggregation needs the aggregation check (--aggregation-check N > 0)");
    }
    if a.confidence.is_some() && a.refine_gap.is_none() && a.min_target.is_some() {
        if a.on_policy {
            bail!(
                "--on-policy with --confidence --min-target: a strategy chosen on its certified \
                 bounds would be reported with other ones; select it first (-o FILE), then \
                 `etp synthesize --pool-policy FILE` and `etp strategy --evaluate FILE`"
            );
        }
        return certified::run(&a, &mdp, scenario_text, &front, &output, level, None);
    }
    if let Some(g) = a.refine_gap {
        return certified::run(&a, &mdp, scenario_text, &front, &output, level, Some(g));
    }
    // The exact optimum (a vertex is its own deterministic policy).
    let (omega, predicted, exact) = match lp_request {
        Some(r) => {
            let opt = optimal_strategy(&mdp, cost, r).context("solving the occupation LP")?;
            (opt.policy.clone(), opt.predicted, Some(opt))
        }
        None => {
            let selection = select(&front, request).context("selecting a vertex")?;
            let k = selection.weights[0].0;
            let omega = as_randomised(&mdp, &front.vertices[k].policy);
            let predicted = evaluate(&mdp, &omega, cost);
            (omega, predicted, None)
        }
    };
    // The explanation: the least-energy mixture of front vertices. It may be
    // infeasible by up to the front's ε where the exact request is not.
    let mixture = select(&front, request).ok();
    let label = match request {
        Request::MinTarget {
            min_target,
            max_collision,
        } => match max_collision {
            Some(c) => format!("least energy with P_tar ≥ {min_target} and P_coll ≤ {c}"),
            None => format!("least energy with P_tar ≥ {min_target}"),
        },
        Request::MaxEnergy { max_energy } => format!("highest P_tar with energy ≤ {max_energy}"),
        Request::Vertex(k) => format!("vertex {k} of the front"),
    };
    let mut strategy = to_strategy(&mdp, &omega, label.clone(), predicted);
    strategy.scenario_toml = scenario_text;
    strategy.radio = front.radio.clone();
    let bound_level = if a.cover_aggregation {
        etp_synthesis::certify::widen::split_level(level)
    } else {
        level
    };
    // --on-policy: every prediction from here on is the rebuild's.
    let rebuilt = if a.on_policy {
        refuse_existing(&output, a.force)?;
        Some(on_policy::rebuild(
            &strategy,
            &mdp,
            cost,
            a.replicates,
            a.json,
        )?)
    } else {
        None
    };
    let (mdp, omega) = match &rebuilt {
        Some(r) => {
            let first = r.first();
            strategy.predicted = super::honest::prediction(&first.predicted);
            strategy.leg_energy = Some(first.leg_energy.clone());
            strategy.label = format!("{label} — predicted on its own pools");
            (&first.mdp, &first.omega)
        }
        None => (&mdp, &omega),
    };
    let honest = certified::assess(mdp, omega, cost, bound_level)?;
    super::honest::attach(&mut strategy, honest.crossfit.as_ref(), &honest.certified);
    if let Some(r) = &rebuilt {
        on_policy::apply_replicates(&mut strategy, r);
    }
    certified::check_aggregation(&mut strategy, &a, level)?;
    write_new(&output, strategy.to_json().as_bytes(), a.force)?;
    let p = &predicted;
    let gap = mixture.as_ref().map(|m| match request {
        Request::MaxEnergy { .. } => p.p_target - m.predicted.p_target,
        _ => m.predicted.energy - p.energy,
    });
    if a.json {
        let v = json!({
            "strategy": output, "label": label,
            "predicted": objectives_json(p),
            "exact": exact.as_ref().map(|o| json!({
                "method": "occupation-measure LP over the whole MDP",
                "lp_objective": o.lp_objective, "margin": o.margin,
                "randomised_states": o.randomised_states, "unvisited_states": UNVISITED})),
            "vertex_mixture": mixture.as_ref().map(|m| json!({
                "predicted": objectives_json(&m.predicted),
                "vertices": m.weights.iter().map(|(k, w)| json!({"vertex": k, "weight": w})).collect::<Vec<_>>(),
                "gap": gap})),
            "occupation_lp_energy": exact.as_ref().filter(|_| matches!(request, Request::MinTarget { .. })).map(|o| o.lp_objective),
            "front_epsilon": front.epsilon,
            "predictions": super::honest::json_of(&strategy),
            "crossfit_unmatched_mass": honest.crossfit.as_ref().map(|c| c.unmatched_mass),
            "on_policy": rebuilt.as_ref().map(on_policy::Rebuilt::json),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("{label}");
        println!(
            "  predicted  P_tar {:.6}  P_coll {:.6}  energy {:.6}",
            p.p_target, p.p_collision, p.energy
        );
        let mut ci = super::honest::HELD_OUT_CI.to_string();
        if let Some(r) = &rebuilt {
            print!("{}", r.describe());
            let q = &strategy.predicted;
            println!(
                "  predicted on its own pools  P_tar {:.6}  P_coll {:.6}  energy {:.6}",
                q.p_target, q.p_collision, q.energy_mean
            );
            if r.replicated.is_some() {
                ci = format!("Student's t over the {} rebuilds", r.replicas.len());
            }
        }
        print!("{}", super::honest::text_with_ci(&strategy, &ci));
        if let Some(o) = &exact {
            println!(
                "  exact: occupation-measure LP over the whole MDP, realised as ω ({} randomising states; unvisited states: {UNVISITED}){}",
                o.randomised_states,
                if o.margin > 0.0 {
                    format!(
                        "; bounds tightened by {:e} so that ω meets them in its own evaluation",
                        o.margin
                    )
                } else {
                    String::new()
                }
            );
        }
        if let Some(m) = &mixture {
            println!(
                "  explanation: mixture of front vertices  P_tar {:.6}  P_coll {:.6}  energy {:.6}",
                m.predicted.p_target, m.predicted.p_collision, m.predicted.energy
            );
            for (k, w) in &m.weights {
                let o = &front.vertices[*k].objectives;
                println!(
                    "    vertex {k:>4} weight {w:.4}  (P_tar {:.4}, P_coll {:.4}, energy {:.2})",
                    o.p_target, o.p_collision, o.energy
                );
            }
            if let Some(g) = gap {
                let what = if matches!(request, Request::MaxEnergy { .. }) {
                    "P_tar"
                } else {
                    "energy"
                };
                println!(
                    "    gap to the exact optimum: {g:.3e} in {what} (the front is certified to ε = {:.2e} scaled, {:.3e} in energy)",
                    front.epsilon, front.epsilon_energy
                );
            }
        } else if lp_request.is_some() {
            println!(
                "  explanation: no mixture of front vertices meets the request (the front is certified to ε = {:.2e}); the exact LP does",
                front.epsilon
            );
        }
        println!("wrote {}", output.display());
    }
    Ok(())
}
