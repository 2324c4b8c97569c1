//! A study's results: one [`Row`] per case (a job's synthesis and one
//! request), kept as `DIR/cases/<job>/row-<k>.json` as each finishes, and
//! the tables `study.json` and `study.csv` made from all of them at the
//! end. The tables hold no timing (`timings.csv` does), so the same SPEC
//! gives the same bytes whatever the number of ranks and threads.

use crate::error::StudyError;
use serde::{Deserialize, Serialize};

type Result<T> = std::result::Result<T, StudyError>;

/// One case's results. Probabilities as fractions, energy in the front's
/// units (expected transmissions); `_ci95` the 95 % half-widths.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Row {
    /// The job (`NN-<scenario>-<family>`) and the request's index in the SPEC.
    pub case: String,
    pub request_index: Option<usize>,
    pub scenario: String,
    pub source: String,
    pub family: String,
    pub n: usize,
    pub samples: u32,
    pub seed: u64,
    // The synthesis.
    pub states: usize,
    pub vertices: usize,
    pub front_epsilon: f64,
    // The request and the strategy `etp strategy` stands by.
    pub request: Option<String>,
    /// The full Kalman filter's simulated P_tar (`kf-…` requests).
    pub kf_p_target: Option<f64>,
    pub min_target: Option<f64>,
    pub max_collision: Option<f64>,
    /// `met`, `out-of-reach` or `rounds-spent`.
    pub verdict: Option<String>,
    pub rounds: Option<usize>,
    pub strategy: Option<String>,
    pub predicted_p_target: Option<f64>,
    pub predicted_p_target_ci95: Option<f64>,
    pub predicted_p_collision: Option<f64>,
    pub predicted_p_collision_ci95: Option<f64>,
    pub predicted_energy: Option<f64>,
    pub predicted_energy_ci95: Option<f64>,
    pub certified_p_target_low: Option<f64>,
    pub certified_p_collision_high: Option<f64>,
    pub certified_energy_high: Option<f64>,
    // The validation (`etp validate --episodes --seed`).
    pub episodes: Option<u64>,
    pub simulated_p_target: Option<f64>,
    pub simulated_p_target_ci95: Option<f64>,
    pub simulated_p_collision: Option<f64>,
    pub simulated_p_collision_ci95: Option<f64>,
    pub simulated_energy: Option<f64>,
    pub simulated_energy_ci95: Option<f64>,
    /// Predicted − simulated, with its sign (the sign of every error etp
    /// prints: positive when the prediction is above the simulation).
    pub miss_p_target: Option<f64>,
    pub miss_p_collision: Option<f64>,
    /// (predicted − simulated) / simulated.
    pub miss_energy_relative: Option<f64>,
    /// Every check of `etp validate` holds (95 % family-wise).
    pub checks_hold: Option<bool>,
    /// The checks that fail, `; `-separated.
    pub failed_checks: Option<String>,
}

/// The wall-clock side of a case (`timings.csv`): which rank did it, how long.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    pub rank: usize,
    pub threads: usize,
    pub synthesis_seconds: f64,
    pub selection_seconds: f64,
    pub validation_seconds: f64,
}

/// What `DIR/cases/<job>/row-<k>.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Finished {
    pub row: Row,
    pub timing: Timing,
}

impl Finished {
    pub fn to_json(&self) -> Result<String> {
        let text = serde_json::to_string_pretty(self)
            .map_err(StudyError::serde("a finished case as JSON"))?;
        Ok(text + "\n")
    }

    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text).map_err(StudyError::serde("a finished case's file"))
    }
}

/// `rows` as CSV (the `csv` crate: a header in the fields' order, an
/// absent value an empty cell).
pub fn csv<T: Serialize>(rows: &[T]) -> Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in rows {
        w.serialize(r).map_err(table_error("writing a CSV row"))?;
    }
    // Flushing into memory cannot fail; its error is the writer's I/O error.
    let bytes = w
        .into_inner()
        .map_err(|e| table_error("finishing the CSV table")(e.into_error()))?;
    String::from_utf8(bytes).map_err(table_error("the CSV table is UTF-8"))
}

/// A CSV table's failure under `what`.
fn table_error<E: std::error::Error + Send + Sync + 'static>(
    what: &str,
) -> impl FnOnce(E) -> StudyError {
    let what = what.to_string();
    move |e| StudyError::Table {
        what,
        source: Box::new(e),
    }
}
