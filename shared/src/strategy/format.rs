//! Reading version 1 of `strategy.json` (before the request loop): its
//! `predicted` was the selection-time value and `crossfit`/`crossfit_ci95`
//! stood beside it. A version 1 file is read as version 2 with those under
//! `diagnostics.selection` and its `predicted` kept as what etp then stood
//! by, said so in `prediction_basis` (its recordings still replay and
//! compare against the number they were run with).

use super::{
    Diagnostics, Prediction, PredictionCi95, STRATEGY_FORMAT_VERSION, SelectionValues, Strategy,
    StrategyError,
};

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
    s.predicted = Some(predicted);
    s.prediction_basis = VERSION_1_BASIS.into();
    s.diagnostics = Some(Diagnostics {
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
