//! `etp replay FILE --plot`: the recording's measured per-sensor energy per
//! episode (from the sensors' ledgers) and outcomes, with 95 % intervals,
//! beside the recorded prediction (`etp.prediction`, `etp.strategy`).

use crate::report_plot::{Bar, RunFigure, mean_ci, proportion};
use anyhow::{Context, Result};
use etp_runtime::recording::{self, Contents, Recorded};
use etp_shared::strategy::Strategy;
use std::collections::{BTreeMap, BTreeSet};

/// The figure of a recording (its selection, if any).
pub fn figure(c: &Contents, names: &[String]) -> Result<RunFigure> {
    let mut energy: BTreeMap<(u32, u64), f64> = BTreeMap::new();
    let mut episodes: BTreeSet<u64> = BTreeSet::new();
    let mut counts = super::OutcomeCounts::default();
    for m in &c.messages {
        match recording::decode(&m.topic, &m.data)
            .with_context(|| format!("message at log time {}", m.log_time))?
        {
            Recorded::Ledger(l) => {
                *energy
                    .entry((l.header.sender, l.header.episode))
                    .or_default() += l.energy;
            }
            Recorded::Outcome(o) => {
                episodes.insert(o.header.episode);
                counts.add(&o);
            }
            _ => {}
        }
    }
    let prediction: Option<serde_json::Value> = c
        .meta(recording::META_PREDICTION, "json")
        .and_then(|t| serde_json::from_str(t).ok());
    let per_ep: Vec<f64> = prediction
        .as_ref()
        .and_then(|p| p.get("sensor_energy_per_episode"))
        .and_then(|s| serde_json::from_value(s.clone()).ok())
        .unwrap_or_default();
    let note = prediction
        .as_ref()
        .and_then(|p| p.get("from").and_then(|f| f.as_str()).map(str::to_string))
        .or_else(|| {
            prediction
                .as_ref()
                .and_then(|p| p.get("predict_episodes"))
                .map(|n| format!("in-process simulation, {n} episodes"))
        })
        .unwrap_or_else(|| "none recorded".into());
    let sensors = names
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let xs: Vec<f64> = episodes
                .iter()
                .map(|&ep| energy.get(&(i as u32, ep)).copied().unwrap_or(0.0))
                .collect();
            let (measured, ci95) = mean_ci(&xs);
            Bar {
                name: name.clone(),
                measured,
                ci95,
                predicted: per_ep.get(i).copied(),
            }
        })
        .collect();
    let strategy = c
        .meta(recording::META_STRATEGY, "json")
        .and_then(|t| Strategy::from_json(t).ok());
    let p = strategy.as_ref().map(|s| s.predicted);
    let n = episodes.len() as u64;
    let outcome = |name: &str, k: u64, pred: Option<f64>| {
        let (measured, ci95) = proportion(k, n);
        Bar {
            name: name.into(),
            measured,
            ci95,
            predicted: pred,
        }
    };
    let outcomes = vec![
        outcome("P_tar", counts.target, p.map(|p| p.p_target)),
        outcome("P_coll", counts.collision, p.map(|p| p.p_collision)),
        outcome("P_free", counts.free, p.map(|p| p.p_free)),
    ];
    let title = format!(
        "run {} · {} · {} · {n} episodes: measured vs predicted",
        c.meta(recording::META_RUN, "run_id").unwrap_or("unknown"),
        c.meta(recording::META_RUN, "scenario_name")
            .unwrap_or("unknown"),
        strategy
            .as_ref()
            .map_or("strategy unknown".to_string(), |s| {
                crate::report_plot::short_label(&s.label)
            }),
    );
    Ok(RunFigure {
        title,
        prediction_note: note,
        sensors,
        outcomes,
    })
}
