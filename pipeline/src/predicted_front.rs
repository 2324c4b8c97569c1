//! The predicted front of a synthesis (docs/MODEL.md §7.5): the request
//! loop of `etp strategy` for requests spread over the P_tar range its MDP
//! reaches, under each P_coll bound asked; stored in `DIR/front.json`
//! (`predicted`) and drawn as the main curve of `DIR/front.png`.

use crate::error::{Context, Result};
use crate::output::write_new;
use crate::progress::Progress;
use crate::selection::{DEFAULT_LEVEL, RequestSettings, goal_label, standing_strategy};
use crate::synthesis_dir::Synthesis;
use etp_files::write::output_folder;
use etp_shared::strategy::{CertifiedPrediction, Strategy};
use etp_synthesis::abstraction;
use etp_synthesis::pareto::{PredictedFront, PredictedPoint};
use etp_synthesis::predict::front::predicted_front;
use etp_synthesis::predict::rebuild;
use etp_synthesis::predict::request::LoopSettings;
use std::path::{Path, PathBuf};

/// The folder of the points' strategy files in a synthesis directory.
pub const STRATEGIES: &str = "predicted-front";

/// The strategy file of point `k` of the curve under `bound`.
pub fn strategy_file(dir: &Path, bound: Option<f64>, k: usize) -> PathBuf {
    let name = match bound {
        Some(c) => format!("pcoll-{c}-point-{k}.json"),
        None => format!("point-{k}.json"),
    };
    dir.join(STRATEGIES).join(name)
}

/// The predicted front of `syn` under each bound of `bounds` (`None`: no
/// P_coll bound), `points` requests a curve, each point exactly the strategy
/// `etp strategy DIR --min-target P [--max-collision C]` returns with the
/// settings `s` (no aggregation check: a point's prediction is its
/// rebuilds'). Each point's strategy file — the bytes `etp strategy
/// --aggregation-check 0` writes for its request — goes to
/// [`strategy_file`]; `each` is told every point as it is done.
pub fn compute(
    syn: &Synthesis,
    bounds: &[Option<f64>],
    points: usize,
    s: &RequestSettings,
    progress: &Progress,
    each: &dyn Fn(Option<f64>, &PredictedPoint),
) -> Result<Vec<PredictedFront>> {
    if syn.exec.is_root() {
        output_folder(&syn.dir.join(STRATEGIES))?;
    }
    let params = abstraction::params_of(&syn.mdp);
    let units = rebuild::progress_units(&syn.scenario, &params);
    let pb = progress.bar(&syn.exec, 0, "predicted front: rebuilds");
    let mut curves = Vec::new();
    let level = s.confidence.unwrap_or(DEFAULT_LEVEL);
    for &bound in bounds {
        // The MDP's front under the bound, along which the requests spread.
        let curve: Vec<(f64, f64)> = syn
            .front
            .vertices
            .iter()
            .map(|v| &v.objectives)
            .filter(|o| bound.is_none_or(|c| o.p_collision <= c + 1e-12))
            .map(|o| (o.energy, o.p_target))
            .collect();
        let mut written: Result<()> = Ok(());
        let mut k = 0;
        let settings = LoopSettings {
            replicates: s.replicates,
            max_rounds: s.rounds,
            certified: None,
        };
        let curve = predicted_front(
            &syn.mdp,
            syn.cost(),
            &syn.scenario,
            &params,
            bound,
            points,
            &curve,
            settings,
            level,
            &|goal, omega, value| syn.strategy_of(&syn.mdp, omega, value, &goal_label(goal, None)),
            &|n| pb.inc_length(u64::from(n) * units),
            &syn.exec.work(|u| pb.inc(u)),
            &mut |_, outcome, p| {
                if written.is_ok() {
                    written = standing_strategy(
                        syn,
                        &syn.mdp,
                        outcome,
                        &outcome.certified,
                        level,
                        0,
                        &progress.silenced(),
                    )
                    .and_then(|(strategy, _)| {
                        write_new(
                            &syn.exec,
                            &strategy_file(&syn.dir, bound, k),
                            strategy.to_json().as_bytes(),
                            true,
                        )
                    });
                }
                k += 1;
                each(bound, p);
            },
        )
        .computing(match bound {
            Some(c) => format!("the predicted front under P_coll ≤ {c}"),
            None => "the predicted front".to_string(),
        })?;
        written?;
        curves.push(curve);
    }
    pb.finish_and_clear();
    Ok(curves)
}

/// The point of `syn`'s stored predicted front for the request P_tar ≥
/// `min_target` (P_coll ≤ `bound`) made with the same loop settings
/// (`replicates`, `max_rounds`), with its strategy file's certified bounds:
/// what the request loop returns for that request, read instead of run
/// again. `None` when `front.json` holds no such point, or its strategy file
/// is missing, unsealed, of another scenario or disagrees with the point (the
/// caller runs the loop then).
pub fn stored_point(
    syn: &Synthesis,
    bound: Option<f64>,
    replicates: u32,
    max_rounds: u32,
    min_target: f64,
) -> Option<(PredictedPoint, CertifiedPrediction)> {
    let curve = syn.front.predicted.iter().find(|c| {
        c.max_collision == bound && c.replicates == replicates && c.max_rounds == max_rounds
    })?;
    let k = curve
        .points
        .iter()
        .position(|p| p.min_target == min_target)?;
    let point = &curve.points[k];
    let text = std::fs::read_to_string(strategy_file(&syn.dir, bound, k)).ok()?;
    let strategy = Strategy::from_sealed_json(&text).ok()?;
    let predicted = strategy.predictions.predicted.as_ref()?;
    let agrees = strategy.policy.scenario_hash == syn.mdp.scenario_hash
        && predicted.p_target == point.predicted.p_target
        && predicted.p_collision == point.predicted.p_collision
        && predicted.energy_mean == point.predicted.energy;
    let certified = strategy.predictions.certified?;
    agrees.then(|| (point.clone(), certified))
}

/// Store `curves` in `syn`'s `front.json` (replacing the curves of the same
/// bounds, written beside and renamed) and draw `front.png`/`front.svg`
/// again; the files written.
pub fn store(syn: &mut Synthesis, curves: Vec<PredictedFront>) -> Result<Vec<PathBuf>> {
    for c in curves {
        syn.front
            .predicted
            .retain(|old| old.max_collision != c.max_collision);
        syn.front.predicted.push(c);
    }
    syn.front.predicted.sort_by(|a, b| {
        a.max_collision
            .unwrap_or(2.0)
            .total_cmp(&b.max_collision.unwrap_or(2.0))
    });
    let path = syn.dir.join("front.json");
    write_new(&syn.exec, &path, syn.front.to_json().as_bytes(), true)?;
    let stem = syn.dir.join("front");
    if syn.exec.is_root() {
        etp_figures::front_plot(&syn.front, &stem)?;
    }
    Ok(vec![
        path,
        stem.with_extension("png"),
        stem.with_extension("svg"),
    ])
}
