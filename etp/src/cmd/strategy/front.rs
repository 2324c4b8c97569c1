//! `etp strategy front DIR`: the predicted front (docs/MODEL.md §7.5) — the
//! request loop of `etp strategy DIR --min-target P [--max-collision C]`
//! for requests spread over the P_tar range DIR's MDP reaches, each point
//! the strategy that command returns with the prediction it stands by;
//! stored in DIR/front.json (`predicted`) and drawn as the main curve of
//! DIR/front.png, over the MDP's selection-time front.

use super::FrontArgs;
use anyhow::Result;
use etp_pipeline::predicted_front::{STRATEGIES, compute, store};
use etp_pipeline::progress::Progress;
use etp_pipeline::selection::RequestSettings;
use etp_pipeline::synthesis_dir::Synthesis;
use etp_synthesis::exec::Executor;
use etp_synthesis::pareto::{PredictedFront, PredictedPoint};
use serde_json::json;
use std::time::Instant;

pub fn run(a: &FrontArgs, exec: &Executor) -> Result<()> {
    let mut syn = Synthesis::load(&a.dir, None, exec)?;
    let bounds: Vec<Option<f64>> = if a.max_collision.is_empty() {
        vec![None]
    } else {
        a.max_collision.iter().copied().map(Some).collect()
    };
    let settings = RequestSettings {
        replicates: a.request_loop.rebuilds.replicates,
        rounds: a.request_loop.rounds,
        confidence: None,
        aggregation_check: 0,
    };
    let started = Instant::now();
    let quiet = a.json;
    let curves = compute(
        &syn,
        &bounds,
        a.points,
        &settings,
        &Progress::new(quiet),
        &|bound, p| {
            if !quiet {
                eprintln!("{}", point_line(bound, p));
            }
        },
    )?;
    let seconds = started.elapsed().as_secs_f64();
    let files = store(&mut syn, curves.clone())?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({
                "dir": a.dir,
                "curves": curves,
                "seconds": seconds,
                "files": files,
                "strategies": a.dir.join(STRATEGIES),
            }))?
        );
    } else {
        print!("{}", text(&curves, seconds));
        for f in files {
            println!("wrote {}", f.display());
        }
        println!(
            "wrote each point's strategy (what `etp strategy DIR --min-target P --aggregation-check 0` writes) to {}/",
            a.dir.join(STRATEGIES).display()
        );
    }
    Ok(())
}

fn point_line(bound: Option<f64>, p: &PredictedPoint) -> String {
    let q = &p.predicted;
    let h = &p.predicted_ci95;
    format!(
        "  P_tar ≥ {:.4}{}  {:<12}  predicted P_tar {:.4} ± {:.4}  P_coll {:.4} ± {:.4}  energy {:.2} ± {:.2}  (MDP: {:.2}; {} rounds, {} rebuilds)",
        p.min_target,
        bound.map_or(String::new(), |c| format!(", P_coll ≤ {c}")),
        p.verdict,
        q.p_target,
        h.p_target,
        q.p_collision,
        h.p_collision,
        q.energy,
        h.energy,
        p.selection_time.energy,
        p.rounds,
        p.rebuilds
    )
}

fn text(curves: &[PredictedFront], seconds: f64) -> String {
    let mut t = String::new();
    for c in curves {
        t.push_str(&format!(
            "predicted front{}: {} requests over the MDP's P_tar range {:.4}–{:.4} ({} rebuilds a prediction, {} rounds at most)\n",
            c.max_collision
                .map_or(String::new(), |b| format!(" under P_coll ≤ {b}")),
            c.points.len(),
            c.range[0],
            c.range[1],
            c.replicates,
            c.max_rounds
        ));
        for p in &c.points {
            t.push_str(&point_line(c.max_collision, p));
            t.push('\n');
        }
    }
    t.push_str(&format!(
        "each point is what `etp strategy DIR --min-target P` returns for its request; {seconds:.1} s\n"
    ));
    t
}
