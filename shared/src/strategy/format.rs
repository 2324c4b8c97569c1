//! The layout of `strategy.json`. [`StrategyFile`] is the file's one flat
//! object, its keys in the order every strategy file has been written in;
//! [`Strategy`] reads and writes through it, so splitting the strategy into
//! its policy, predictions and provenance changes no byte of the file (the
//! parts interleave in it: serde's `flatten` would write them part by part).
//!
//! Version 1 (before the request loop): its `predicted` was the
//! selection-time value and `crossfit`/`crossfit_ci95` stood beside it. A
//! version 1 file is read as version 2 with those under
//! `diagnostics.selection` and its `predicted` kept as what etp then stood
//! by, said so in `prediction_basis` (its recordings still replay and
//! compare against the number they were run with).

use super::{
    AggregationCheck, CertifiedPrediction, Diagnostics, Policy, Prediction, PredictionCi95,
    Predictions, Provenance, STRATEGY_FORMAT_VERSION, SelectionValues, Strategy, StrategyError,
    StrategyState,
};
use crate::discretization::{Discretization, RegionSplit};
use crate::radio::Radio;
use serde::{Deserialize, Serialize};

/// `strategy.json` as written (without its seal, appended by
/// [`Strategy::to_json`]). Do not reorder: the order of the fields is the
/// order of the keys, and the seal hashes the text.
#[derive(Serialize, Deserialize)]
pub(super) struct StrategyFile {
    format_version: u32,
    scenario_name: String,
    scenario_hash: String,
    label: String,
    deltas: Vec<f64>,
    discretization: Option<Discretization>,
    states: Vec<StrategyState>,
    predicted: Option<Prediction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    predicted_ci95: Option<PredictionCi95>,
    #[serde(default)]
    prediction_basis: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    certified: Option<CertifiedPrediction>,
    #[serde(default)]
    scenario_toml: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    leg_energy: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    radio: Option<Radio>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    splits: Vec<RegionSplit>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    aggregation: Option<AggregationCheck>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    diagnostics: Option<Diagnostics>,
}

impl From<StrategyFile> for Strategy {
    fn from(f: StrategyFile) -> Self {
        Self {
            provenance: Provenance {
                format_version: f.format_version,
                label: f.label,
            },
            policy: Policy {
                scenario_name: f.scenario_name,
                scenario_hash: f.scenario_hash,
                deltas: f.deltas,
                discretization: f.discretization,
                states: f.states,
                scenario_toml: f.scenario_toml,
                radio: f.radio,
                splits: f.splits,
            },
            predictions: Predictions {
                predicted: f.predicted,
                predicted_ci95: f.predicted_ci95,
                prediction_basis: f.prediction_basis,
                certified: f.certified,
                leg_energy: f.leg_energy,
                aggregation: f.aggregation,
                diagnostics: f.diagnostics,
            },
        }
    }
}

impl From<Strategy> for StrategyFile {
    fn from(s: Strategy) -> Self {
        let Strategy {
            provenance:
                Provenance {
                    format_version,
                    label,
                },
            policy:
                Policy {
                    scenario_name,
                    scenario_hash,
                    deltas,
                    discretization,
                    states,
                    scenario_toml,
                    radio,
                    splits,
                },
            predictions:
                Predictions {
                    predicted,
                    predicted_ci95,
                    prediction_basis,
                    certified,
                    leg_energy,
                    aggregation,
                    diagnostics,
                },
        } = s;
        Self {
            format_version,
            scenario_name,
            scenario_hash,
            label,
            deltas,
            discretization,
            states,
            predicted,
            predicted_ci95,
            prediction_basis,
            certified,
            scenario_toml,
            leg_energy,
            radio,
            splits,
            aggregation,
            diagnostics,
        }
    }
}

/// What a version 1 file's `predicted` was.
pub const VERSION_1_BASIS: &str =
    "selection-time value (a strategy file of format 1, before the request loop)";

pub(super) fn from_version_1(text: &str) -> Result<Strategy, StrategyError> {
    let parse = |e: serde_json::Error| StrategyError::Parse(e.to_string());
    let mut v: serde_json::Value = serde_json::from_str(text).map_err(parse)?;
    let Some(m) = v.as_object_mut() else {
        return Err(StrategyError::Parse("not a JSON object".into()));
    };
    let take = |m: &mut serde_json::Map<String, serde_json::Value>, k: &str| m.remove(k);
    let predicted: Prediction = serde_json::from_value(
        take(m, "predicted").ok_or_else(|| StrategyError::Parse("no `predicted`".into()))?,
    )
    .map_err(parse)?;
    let crossfit: Option<Prediction> = take(m, "crossfit")
        .map(serde_json::from_value)
        .transpose()
        .map_err(parse)?;
    let crossfit_ci95: Option<PredictionCi95> = take(m, "crossfit_ci95")
        .map(serde_json::from_value)
        .transpose()
        .map_err(parse)?;
    m.insert("format_version".into(), STRATEGY_FORMAT_VERSION.into());
    let mut s: Strategy = serde_json::from_value(v).map_err(parse)?;
    s.predictions.predicted = Some(predicted);
    s.predictions.prediction_basis = VERSION_1_BASIS.into();
    s.predictions.diagnostics = Some(Diagnostics {
        selection: SelectionValues {
            selection_time: Some(predicted),
            crossfit,
            crossfit_ci95,
            certified: None,
        },
        ..Diagnostics::default()
    });
    Ok(s)
}
