//! `etp compare DIR… --min-target P…`: the least energy each synthesis of
//! one scenario (one trigger family or radio each, docs/MODEL.md §9) needs
//! for each request, and its ratio to the paper's trigger (`box`), with
//! intervals. Each number is the prediction `etp strategy DIR --min-target
//! P` stands by: the request loop of docs/MODEL.md §7.4
//! (`predict::request::meet_request`), the strategy's mean over its own
//! on-policy rebuilds with a Student-t ± — not the biased selection-time
//! value of the MDP it was picked on. A request the loop cannot meet for a
//! family is reported out of reach, with how close it came. A request that
//! is a point of a directory's predicted front (`etp strategy front`, stored
//! in its `front.json` with the same loop settings) is read from there: the
//! same numbers, not computed twice. Nothing is written.

use anyhow::{Result, bail};
use etp_pipeline::progress;
use etp_pipeline::synthesis_dir::{Identity, Synthesis, check_one_scenario, identity, labels};
use etp_shared::stats::{Estimate, ratio};
use etp_shared::trigger::TriggerFamily;
use etp_synthesis::exec::Executor;
use etp_synthesis::pareto::policy::Objectives;
use etp_synthesis::predict::request::{Goal, LoopSettings, Verdict};
use serde_json::{Value, json};
use std::path::PathBuf;
use std::time::Instant;

/// Level of the certified bounds reported beside each prediction.
const LEVEL: f64 = 0.95;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Synthesis directories (each written by `etp synthesize`, e.g. with
    /// `--trigger FAMILY`) of one scenario; ratios are to the `box` one of
    /// the same channel.
    #[arg(required = true, num_args = 1..)]
    pub dirs: Vec<PathBuf>,
    /// The requests: least energy with P_tar ≥ P (repeat the option or
    /// separate by commas).
    #[arg(long, value_name = "P", value_delimiter = ',', required = true, value_parser = crate::input::probability)]
    pub min_target: Vec<f64>,
    /// With every request: also P_coll ≤ C.
    #[arg(long, value_name = "C", value_parser = crate::input::probability)]
    pub max_collision: Option<f64>,
    #[command(flatten)]
    pub request_loop: crate::prediction_args::RequestLoopArgs,
    /// Print the table as JSON.
    #[arg(long)]
    pub json: bool,
}

/// One (request, synthesis) cell of the table.
struct Row {
    verdict: Verdict,
    /// The kept strategy's prediction and its 95 % half-widths.
    predicted: Objectives,
    ci95: Objectives,
    /// Its certified bounds (first rebuild, at [`LEVEL`]).
    certified: etp_synthesis::certify::robust::Certified,
    rounds: usize,
    seconds: f64,
    /// Read from the directory's predicted front, or computed here.
    from_front: bool,
}

impl Row {
    fn energy(&self) -> Estimate {
        Estimate {
            value: self.predicted.energy,
            ci95: self.ci95.energy,
        }
    }
}

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    let mut syns: Vec<(Synthesis, Identity)> = Vec::new();
    for dir in &a.dirs {
        let syn = Synthesis::load(dir, None, exec)?;
        let id = identity(dir, &syn.front, syn.scenario_text.as_deref())?;
        syns.push((syn, id));
    }
    check_one_scenario(
        &syns
            .iter()
            .map(|(s, id)| (s.dir.as_path(), s.front.scenario_name.as_str(), id))
            .collect::<Vec<_>>(),
    )?;
    let labels = labels(
        &syns
            .iter()
            .map(|(s, id)| (s.dir.as_path(), id))
            .collect::<Vec<_>>(),
    );
    // The reference of each synthesis: the first `box` one of its channel.
    let reference: Vec<Option<usize>> = syns
        .iter()
        .map(|(_, id)| {
            syns.iter()
                .position(|(_, r)| r.trigger == TriggerFamily::Box && r.radio == id.radio)
        })
        .collect();
    if reference.iter().all(Option::is_none) {
        bail!(
            "no synthesis of the paper's trigger (box) among the directories: ratios are to it \
             (`etp synthesize SCENARIO --trigger box -o DIR`)"
        );
    }
    let pb = progress::bar(exec, 0, "compare", a.json);
    let mut table: Vec<Vec<Row>> = Vec::new();
    for &min_target in &a.min_target {
        let goal = Goal::MinTarget {
            min_target,
            max_collision: a.max_collision,
        };
        let mut rows = Vec::new();
        for (syn, _) in &syns {
            let started = Instant::now();
            if let Some(row) = stored_row(syn, &a, min_target, started) {
                rows.push(row);
                continue;
            }
            let make = |omega: &_, value| syn.strategy_of(&syn.mdp, omega, value, "compare");
            let settings = LoopSettings {
                replicates: a.request_loop.rebuilds.replicates,
                max_rounds: a.request_loop.rounds,
                certified: None,
            };
            let o = syn.meet(&syn.mdp, goal, settings, LEVEL, &make, &pb)?;
            rows.push(Row {
                verdict: o.verdict,
                predicted: o.on_policy.combined.mean,
                ci95: o.on_policy.combined.ci95,
                certified: o.certified,
                rounds: o.rounds.len(),
                seconds: started.elapsed().as_secs_f64(),
                from_front: false,
            });
        }
        table.push(rows);
    }
    pb.finish_and_clear();
    let ratio_of = |rows: &[Row], i: usize| -> Option<Estimate> {
        let r = reference[i]?;
        if rows[i].verdict != Verdict::Met || rows[r].verdict != Verdict::Met {
            return None;
        }
        if r == i {
            // The reference itself: 1 exactly, no uncertainty.
            return Some(Estimate {
                value: 1.0,
                ci95: 0.0,
            });
        }
        ratio(rows[i].energy(), rows[r].energy())
    };
    let scenario = &syns[0].0.front.scenario_name;
    if a.json {
        let est = |m: &mut serde_json::Map<String, Value>, k: &str, v: f64, h: f64| {
            m.insert(k.into(), json!(v));
            m.insert(format!("{k}_ci95"), json!(h));
        };
        let requests: Vec<Value> = a
            .min_target
            .iter()
            .zip(&table)
            .map(|(t, rows)| {
                let rows: Vec<Value> = rows
                    .iter()
                    .enumerate()
                    .map(|(i, r)| {
                        let (syn, id) = &syns[i];
                        let mut m = serde_json::Map::new();
                        m.insert("dir".into(), json!(syn.dir));
                        m.insert("label".into(), json!(labels[i]));
                        m.insert("trigger".into(), json!(id.trigger.name()));
                        m.insert("radio".into(), json!(id.radio));
                        m.insert("verdict".into(), json!(r.verdict.name()));
                        est(&mut m, "energy", r.predicted.energy, r.ci95.energy);
                        est(&mut m, "p_target", r.predicted.p_target, r.ci95.p_target);
                        est(
                            &mut m,
                            "p_collision",
                            r.predicted.p_collision,
                            r.ci95.p_collision,
                        );
                        m.insert(
                            "certified".into(),
                            json!({
                                "confidence": LEVEL,
                                "p_target_low": r.certified.p_target_low,
                                "p_collision_high": r.certified.p_collision_high,
                                "energy_high": r.certified.energy_high,
                            }),
                        );
                        m.insert(
                            "reference".into(),
                            json!(reference[i].map(|k| &syns[k].0.dir)),
                        );
                        let q = ratio_of(rows, i);
                        m.insert("ratio".into(), json!(q.map(|q| q.value)));
                        m.insert("ratio_ci95".into(), json!(q.map(|q| q.ci95)));
                        m.insert(
                            "source".into(),
                            json!(if r.from_front {
                                "front.json"
                            } else {
                                "request loop"
                            }),
                        );
                        m.insert("rounds".into(), json!(r.rounds));
                        m.insert("seconds".into(), json!(r.seconds));
                        Value::Object(m)
                    })
                    .collect();
                json!({"min_target": t, "max_collision": a.max_collision, "rows": rows})
            })
            .collect();
        let v = json!({
            "scenario": scenario,
            "replicates": a.request_loop.rebuilds.replicates,
            "requests": requests,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{scenario}: least energy per request, predicted on {} on-policy rebuilds (the request loop of `etp strategy`), ± 95 %",
        a.request_loop.rebuilds.replicates
    );
    let width = labels
        .iter()
        .map(|l| l.chars().count())
        .max()
        .unwrap_or(6)
        .max(6);
    for (t, rows) in a.min_target.iter().zip(&table) {
        match a.max_collision {
            Some(c) => println!("\nP_tar ≥ {t}, P_coll ≤ {c}:"),
            None => println!("\nP_tar ≥ {t}:"),
        }
        println!(
            "  {:<width$}  {:>20}  {:>17}  {:>17}  {:>17}  {:>12}",
            "", "energy", "ratio to box", "P_tar", "P_coll", "certified E ≤"
        );
        for (i, r) in rows.iter().enumerate() {
            let ratio = match (r.verdict, ratio_of(rows, i)) {
                (Verdict::Met, Some(q)) => format!("{:.3} ± {:.3}", q.value, q.ci95),
                (Verdict::Met, None) => "n/a".into(),
                _ => "OUT OF REACH".into(),
            };
            println!(
                "  {:<width$}  {:>11.2} ± {:<6.2}  {:>17}  {:>8.4} ± {:.4}  {:>8.4} ± {:.4}  {:>12.2}{}",
                labels[i],
                r.predicted.energy,
                r.ci95.energy,
                ratio,
                r.predicted.p_target,
                r.ci95.p_target,
                r.predicted.p_collision,
                r.ci95.p_collision,
                r.certified.energy_high,
                if r.from_front { "  *" } else { "" },
            );
        }
    }
    if table.iter().flatten().any(|r| r.from_front) {
        println!(
            "\n  * a point of the directory's predicted front (front.json), read, not recomputed"
        );
    }
    Ok(())
}

/// The row of `syn` for the request P_tar ≥ `min_target` when it is a point
/// of its stored predicted front made with the same loop settings and
/// certified at [`LEVEL`].
fn stored_row(syn: &Synthesis, a: &Args, min_target: f64, started: Instant) -> Option<Row> {
    let (point, certified) = etp_pipeline::predicted_front::stored_point(
        syn,
        a.max_collision,
        a.request_loop.rebuilds.replicates,
        a.request_loop.rounds,
        min_target,
    )?;
    if certified.confidence != LEVEL {
        return None;
    }
    Some(Row {
        verdict: Verdict::from_name(&point.verdict)?,
        predicted: point.predicted,
        ci95: point.predicted_ci95,
        certified: etp_synthesis::certify::robust::Certified {
            p_target_low: certified.p_target_low,
            p_collision_high: certified.p_collision_high,
            energy_high: certified.energy_high,
        },
        rounds: point.rounds,
        seconds: started.elapsed().as_secs_f64(),
        from_front: true,
    })
}
