//! `etp run --plot`: the run's measured per-sensor energy per episode (the
//! sensors' ledgers × cost) and outcomes with 95 % intervals, beside the
//! prediction (strategy; per sensor: `record::prediction_source`).

use super::prepare::Plan;
use super::supervise::Supervised;
use etp_figures::{Bar, RunFigure};
use etp_shared::stats::verdict::Measured;

/// The figure of a finished run.
pub fn figure(plan: &Plan, s: &Supervised) -> RunFigure {
    let r = &s.report;
    let sensors = plan
        .scenario
        .sensors
        .iter()
        .enumerate()
        .map(|(i, sensor)| {
            let xs: Vec<f64> = r
                .episode_results
                .iter()
                .map(|e| {
                    e.legs
                        .iter()
                        .filter(|l| l.sensor as usize == i)
                        .map(|l| f64::from(l.transmitted.unwrap_or(l.received)) * sensor.cost)
                        .sum()
                })
                .collect();
            Bar::of(
                &sensor.name,
                &Measured::mean_of(&xs),
                plan.sensor_energy_per_episode.get(i).copied(),
            )
        })
        .collect();
    let outcome = |name: &str, k: u64, pred: f64| {
        Bar::of(name, &Measured::Proportion { k, n: r.episodes }, Some(pred))
    };
    RunFigure {
        title: format!(
            "run {} · {} · {} · {} episodes: measured vs predicted",
            r.run_id,
            r.scenario,
            etp_figures::short_label(&r.strategy_label),
            r.episodes
        ),
        prediction_note: super::record::prediction_source(plan),
        sensors,
        outcomes: vec![
            outcome(
                "P_tar",
                r.target,
                r.predicted.map_or(f64::NAN, |p| p.p_target),
            ),
            outcome(
                "P_coll",
                r.collision,
                r.predicted.map_or(f64::NAN, |p| p.p_collision),
            ),
            outcome("P_free", r.free, r.predicted.map_or(f64::NAN, |p| p.p_free)),
        ],
    }
}
