//! The default path of `etp strategy`: the request loop (docs/MODEL.md
//! §7.4) — or, for `--vertex`, one selection — and the prediction of the
//! strategy kept from its own on-policy rebuilds.

use super::{Args, EXIT_OUT_OF_REACH, Request, certified, report_fields};
use anyhow::{Context, Result};
use etp_pipeline::output::refuse_existing;
use etp_pipeline::predictions;
use etp_pipeline::progress::{self, Progress};
use etp_pipeline::selection::{DEFAULT_LEVEL, RequestSettings, meet_goal, standing_strategy};
use etp_pipeline::synthesis_dir::Synthesis;
use etp_shared::strategy::Strategy;
use etp_synthesis::abstraction;
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::Mdp;
use etp_synthesis::pareto::policy::{as_randomised, evaluate};
use etp_synthesis::pareto::select::{Request as FrontRequest, select};
use etp_synthesis::predict::request::{Goal, Outcome, Verdict};
use serde_json::{Value, json};
use std::time::Instant;

pub fn run(a: &Args, request: Request, exec: &Executor) -> Result<()> {
    let dir = a.dir.as_deref().context("DIR is required")?;
    let syn = Synthesis::load(dir, a.out.output.as_deref(), exec)?;
    refuse_existing(exec, &syn.output, a.out.force)?;
    let level = a.confidence.unwrap_or(DEFAULT_LEVEL);
    let certified_selection = match request {
        Request::Goal(Goal::MinTarget { .. }) => a.confidence,
        _ => None,
    };
    let label = request.label(certified_selection);
    let started = Instant::now();
    // Sample allocation first (certified selection only).
    let refined = match a.refine_gap {
        Some(g) => Some(certified::refine_selection(a, &syn, g, level)?),
        None => None,
    };
    let mdp = refined.as_ref().map_or(&syn.mdp, |r| &r.mdp);
    let (outcome, strategy, unmatched) = match request {
        Request::Goal(goal) => {
            let settings = RequestSettings {
                replicates: a.request_loop.rebuilds.replicates,
                rounds: a.request_loop.rounds,
                confidence: a.confidence,
                aggregation_check: a.check.aggregation_check,
            };
            meet_goal(&syn, mdp, goal, &settings, &Progress::new(a.out.json))?
        }
        Request::Vertex(k) => vertex(a, &syn, mdp, k, &label)?,
    };
    let seconds = started.elapsed().as_secs_f64();
    a.out.write(exec, &syn, &strategy)?;
    let explanation = explanation(&syn, request);
    let report = Report {
        syn: &syn,
        strategy: &strategy,
        outcome: &outcome,
        request,
        seconds,
        unmatched,
        explanation,
        refined: refined.as_ref(),
    };
    if a.out.json {
        println!("{}", serde_json::to_string_pretty(&report.json())?);
    } else {
        print!("{}", report.text());
    }
    match outcome.verdict {
        Verdict::Met => Ok(()),
        v => Err(etp_runtime::shell::ExitWith {
            code: EXIT_OUT_OF_REACH,
            message: format!(
                "etp strategy: the request is out of reach ({}): {}; wrote the closest strategy found to {} with its prediction",
                v.name(),
                miss_text(request, &strategy),
                syn.output.display()
            ),
        }
        .into()),
    }
}

/// `--vertex K`: the front's vertex K on `mdp`, predicted on its own
/// rebuilds (no loop: a vertex is not a request), and the strategy it
/// stands by.
fn vertex(
    a: &Args,
    syn: &Synthesis,
    mdp: &Mdp,
    k: usize,
    label: &str,
) -> Result<(Outcome, Strategy, Option<f64>)> {
    let level = a.confidence.unwrap_or(DEFAULT_LEVEL);
    let params = abstraction::params_of(&syn.mdp);
    let units = etp_synthesis::predict::rebuild::progress_units(&syn.scenario, &params);
    let pb = progress::bar(&syn.exec, 0, "rebuilds", a.out.json);
    let selection = select(&syn.front, FrontRequest::Vertex(k)).context("selecting a vertex")?;
    let v = selection.weights[0].0;
    let omega = as_randomised(mdp, &syn.front.vertices[v].policy);
    let value = evaluate(mdp, &omega, syn.cost());
    let strategy = syn.strategy_of(mdp, &omega, value, label);
    pb.inc_length(u64::from(a.request_loop.rebuilds.replicates) * units);
    let (on_policy, certified) =
        syn.predict(&strategy, a.request_loop.rebuilds.replicates, level, &pb)?;
    pb.finish_and_clear();
    let outcome = Outcome {
        omega,
        selection_time: value,
        strategy,
        on_policy,
        certified,
        rounds: Vec::new(),
        kept: 0,
        verdict: Verdict::Met,
    };
    let (strategy, unmatched) = standing_strategy(
        syn,
        mdp,
        &outcome,
        &outcome.certified,
        level,
        a.check.aggregation_check,
        &Progress::new(a.out.json),
    )?;
    Ok((outcome, strategy, unmatched))
}

/// By how much the kept strategy's prediction misses the request.
fn miss_text(request: Request, s: &Strategy) -> String {
    let (Some(p), Some(h)) = (s.predictions.predicted, s.predictions.predicted_ci95) else {
        return "no prediction".into();
    };
    match request {
        Request::Goal(Goal::MinTarget {
            min_target,
            max_collision,
        }) => {
            let mut t = format!(
                "predicted P_tar {:.4} ± {:.4} against P_tar ≥ {min_target}",
                p.p_target, h.p_target
            );
            if let Some(c) = max_collision {
                t.push_str(&format!(
                    ", P_coll {:.4} ± {:.4} against P_coll ≤ {c}",
                    p.p_collision, h.p_collision
                ));
            }
            if let Some(c) = &s.predictions.certified.filter(|c| c.covers_aggregation) {
                t.push_str(&format!(
                    " (certified P_tar ≥ {:.4}, P_coll ≤ {:.4})",
                    c.p_target_low, c.p_collision_high
                ));
            }
            t
        }
        Request::Goal(Goal::MaxEnergy { max_energy }) => format!(
            "predicted energy {:.3} ± {:.3} against energy ≤ {max_energy}",
            p.energy_mean, h.energy_mean
        ),
        Request::Vertex(_) => String::new(),
    }
}

/// The front's answer to the user's request, as an explanation.
struct Explanation {
    mixture: Option<etp_synthesis::pareto::select::Selection>,
}

fn explanation(syn: &Synthesis, request: Request) -> Explanation {
    let r = match request {
        Request::Goal(Goal::MinTarget {
            min_target,
            max_collision,
        }) => FrontRequest::MinTarget {
            min_target,
            max_collision,
        },
        Request::Goal(Goal::MaxEnergy { max_energy }) => FrontRequest::MaxEnergy { max_energy },
        Request::Vertex(k) => FrontRequest::Vertex(k),
    };
    Explanation {
        mixture: select(&syn.front, r).ok(),
    }
}

struct Report<'a> {
    syn: &'a Synthesis,
    strategy: &'a Strategy,
    outcome: &'a Outcome,
    request: Request,
    seconds: f64,
    unmatched: Option<f64>,
    explanation: Explanation,
    refined: Option<&'a certified::Refinement>,
}

impl Report<'_> {
    fn json(&self) -> Value {
        let o = self.outcome;
        let verdict = match self.request {
            Request::Vertex(_) => "vertex",
            _ => o.verdict.name(),
        };
        let mut m = report_fields(self.syn, self.strategy, verdict);
        if let Some(Value::Object(d)) = m.get_mut("diagnostics") {
            let first = o.on_policy.first();
            d.insert(
                "rebuild".into(),
                json!({
                    "states": first.mdp.states.len(),
                    "choices": first.mdp.states.iter().map(|s| s.choices.len()).sum::<usize>(),
                    "segments": o.on_policy.segments(),
                    "seconds": self.seconds,
                }),
            );
            d.insert("kept_round".into(), json!(o.kept));
            d.insert("front_epsilon".into(), json!(self.syn.front.epsilon));
            d.insert("crossfit_unmatched_mass".into(), json!(self.unmatched));
            d.insert("vertex_mixture".into(), self.explanation.mixture.as_ref().map_or(Value::Null, |m| json!({
                "predicted": {"p_target": m.predicted.p_target, "p_collision": m.predicted.p_collision, "energy_mean": m.predicted.energy},
                "vertices": m.weights.iter().map(|(k, w)| json!({"vertex": k, "weight": w})).collect::<Vec<_>>(),
            })));
            d.insert(
                "refinement".into(),
                self.refined
                    .map_or(Value::Null, certified::Refinement::json),
            );
        }
        Value::Object(m)
    }

    fn text(&self) -> String {
        let o = self.outcome;
        let s = self.strategy;
        let mut t = format!("{}\n", s.provenance.label);
        t.push_str(&predictions::text_of(s));
        match (self.request, o.verdict) {
            (Request::Vertex(_), _) => {}
            (_, Verdict::Met) => t.push_str(&format!(
                "  meets the request: round {} kept, after {} round{} of the request loop (docs/MODEL.md §7.4), {:.1} s\n",
                o.kept,
                o.rounds.len(),
                if o.rounds.len() == 1 { "" } else { "s" },
                self.seconds
            )),
            (_, v) => t.push_str(&format!(
                "  OUT OF REACH ({}): {} — the closest of {} rounds (round {}), {:.1} s\n",
                v.name(),
                miss_text(self.request, s),
                o.rounds.len(),
                o.kept,
                self.seconds
            )),
        }
        let first = o.on_policy.first();
        t.push_str(&format!(
            "  rebuilds: {} × {} states, {} segments in all\n",
            o.on_policy.replicas.len(),
            first.mdp.states.len(),
            o.on_policy.segments()
        ));
        if let Some(m) = &self.explanation.mixture {
            t.push_str(&format!(
                "  explanation: the front's mixture for the request on the selection MDP  P_tar {:.6}  P_coll {:.6}  energy {:.6}\n",
                m.predicted.p_target, m.predicted.p_collision, m.predicted.energy
            ));
            for (k, w) in &m.weights {
                let v = &self.syn.front.vertices[*k].objectives;
                t.push_str(&format!(
                    "    vertex {k:>4} weight {w:.4}  (P_tar {:.4}, P_coll {:.4}, energy {:.2})\n",
                    v.p_target, v.p_collision, v.energy
                ));
            }
        }
        if let Some(r) = self.refined {
            t.push_str(&r.text());
        }
        t.push_str(&format!("wrote {}\n", self.syn.output.display()));
        t
    }
}
