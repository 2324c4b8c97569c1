//! `etp replay plot FILE`: the recording's measured per-sensor energy per
//! episode (from the sensors' ledgers) and outcomes, with 95 % intervals,
//! beside the recorded prediction (`etp.prediction`, `etp.strategy`).

use crate::error::{Context, Result};
use etp_runtime::recording::{self, Contents, Recorded};
use etp_shared::stats::Z95;
use etp_shared::stats::verdict::Measured;
use etp_shared::strategy::Strategy;
use std::collections::{BTreeMap, BTreeSet};

/// One measured quantity beside its prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct Bar {
    pub name: String,
    pub measured: f64,
    /// The 95 % interval `(lo, hi)` of `measured` (`etp_shared::stats`:
    /// Wilson for a proportion, never zero width); `None` where there is
    /// none (fewer than two episodes for a mean): no bar is drawn.
    pub interval: Option<(f64, f64)>,
    pub predicted: Option<f64>,
}

impl Bar {
    /// A quantity the recording cannot measure (a channel missing): the
    /// prediction alone.
    pub fn unmeasured(name: &str, predicted: Option<f64>) -> Self {
        Self {
            name: name.into(),
            measured: f64::NAN,
            interval: None,
            predicted,
        }
    }

    /// The bar of a measurement, its 95 % interval from `etp_shared::stats`.
    pub fn of(name: &str, m: &Measured, predicted: Option<f64>) -> Self {
        let (lo, hi) = m.interval(Z95);
        Self {
            name: name.into(),
            measured: m.value(),
            interval: (lo.is_finite() && hi.is_finite() && hi > lo).then_some((lo, hi)),
            predicted,
        }
    }
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
    let has = |t: &str| c.channels.contains_key(t);
    let mut energy: BTreeMap<(u32, u64), f64> = BTreeMap::new();
    let mut episodes: BTreeSet<u64> = BTreeSet::new();
    let mut counts = crate::OutcomeCounts::default();
    for m in &c.messages {
        match m
            .decode()
            .at_message(|| format!("message at log time {}", m.log_time))?
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
            if has("ledger") && has("outcome") {
                Bar::of(name, &Measured::mean_of(&xs), per_ep.get(i).copied())
            } else {
                Bar::unmeasured(name, per_ep.get(i).copied())
            }
        })
        .collect();
    let strategy = c
        .meta(recording::META_STRATEGY, "json")
        .and_then(|t| Strategy::from_json(t).ok());
    let p = strategy.as_ref().and_then(|s| s.predictions.predicted);
    let n = episodes.len() as u64;
    let outcome = |name: &str, k: u64, pred: Option<f64>| {
        if has("outcome") {
            Bar::of(name, &Measured::Proportion { k, n }, pred)
        } else {
            Bar::unmeasured(name, pred)
        }
    };
    let outcomes = vec![
        outcome("P_tar", counts.target, p.map(|p| p.p_target)),
        outcome("P_coll", counts.collision, p.map(|p| p.p_collision)),
        outcome("P_free", counts.free, p.map(|p| p.p_free)),
    ];
    let missing = crate::summary::missing_channels(c);
    let lacking = if missing.is_empty() {
        String::new()
    } else {
        format!(" · NO {} channel: not measured", missing.join(", "))
    };
    let title = format!(
        "run {} · {} · {} · {n} episodes: measured vs predicted{lacking}",
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
    fn no_bar_has_zero_width() {
        // 10 of 10 and 0 of 10: Wilson, not 1 ± 0 or 0 ± 0.
        for k in [0, 10] {
            let b = Bar::of("P", &Measured::Proportion { k, n: 10 }, None);
            let (lo, hi) = b.interval.expect("an interval");
            assert!(hi - lo > 0.2, "{k}: {lo} {hi}");
        }
        // One episode: no interval, no bar.
        assert_eq!(
            Bar::of("e", &Measured::mean_of(&[4.0]), None).interval,
            None
        );
        let two = Bar::of("e", &Measured::mean_of(&[1.0, 3.0]), None);
        let (lo, hi) = two.interval.expect("an interval");
        assert!((hi - lo - 2.0 * Z95).abs() < 1e-12);
    }
}
