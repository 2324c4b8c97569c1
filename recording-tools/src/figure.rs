//! `etp replay plot FILE`: the recording's measured per-sensor energy per
//! episode (from the sensors' ledgers) and outcomes, with 95 % intervals,
//! beside the recorded prediction (`etp.prediction`, `etp.strategy`).

use anyhow::{Context, Result};
use etp_runtime::recording::{self, Contents, Recorded};
use etp_shared::strategy::Strategy;
use std::collections::{BTreeMap, BTreeSet};

/// One measured quantity beside its prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct Bar {
    pub name: String,
    pub measured: f64,
    /// 95 % half-width of `measured`.
    pub ci95: f64,
    pub predicted: Option<f64>,
}

/// What the figure shows.
#[derive(Debug, Clone, PartialEq)]
pub struct RunFigure {
    /// `run r1 · open-2d · constant δ = 1.05 · 200 episodes`.
    pub title: String,
    /// Where the per-sensor prediction comes from.
    pub prediction_note: String,
    pub sensors: Vec<Bar>,
    pub outcomes: Vec<Bar>,
}

/// Mean and 95 % half-width (normal approximation) of `xs`.
pub fn mean_ci(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    if xs.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = xs.iter().sum::<f64>() / n;
    if xs.len() < 2 {
        return (m, 0.0);
    }
    let var = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, 1.96 * (var / n).sqrt())
}

/// A proportion `k / n` with its 95 % half-width (normal approximation).
pub fn proportion(k: u64, n: u64) -> (f64, f64) {
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let p = k as f64 / n as f64;
    (p, 1.96 * (p * (1.0 - p) / n as f64).sqrt())
}

/// A strategy label without its parenthesised details, at most 50 characters.
pub fn short_label(label: &str) -> String {
    let head = label.split(" (").next().unwrap_or(label);
    short_to(head, 50)
}

/// `s` cut to `n` characters (with `…` when cut).
pub fn short_to(s: &str, n: usize) -> String {
    let t: String = s.chars().take(n).collect();
    if t.len() < s.len() {
        format!("{t}…")
    } else {
        t
    }
}

/// The figure of a recording (its selection, if any).
pub fn figure(c: &Contents, names: &[String]) -> Result<RunFigure> {
    let mut energy: BTreeMap<(u32, u64), f64> = BTreeMap::new();
    let mut episodes: BTreeSet<u64> = BTreeSet::new();
    let mut counts = crate::OutcomeCounts::default();
    for m in &c.messages {
        match m
            .decode()
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
    let p = strategy.as_ref().and_then(|s| s.predictions.predicted);
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
                short_label(&s.provenance.label)
            }),
    );
    Ok(RunFigure {
        title,
        prediction_note: note,
        sensors,
        outcomes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals() {
        let (m, h) = mean_ci(&[1.0, 3.0]);
        assert_eq!(m, 2.0);
        assert!((h - 1.96 * (2.0f64 / 2.0).sqrt()).abs() < 1e-12);
        assert_eq!(mean_ci(&[5.0]), (5.0, 0.0));
        let (p, h) = proportion(50, 100);
        assert_eq!(p, 0.5);
        assert!((h - 0.098).abs() < 1e-12);
    }
}
