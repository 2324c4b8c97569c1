//! The scenario file's shape, exactly as written in TOML (before validation).

use serde::{Deserialize, Serialize};

pub(crate) type RawMatrix = Vec<Vec<f64>>;

/// The channel's keys as this shape reads them: the `[radio]` table
/// ([`RawRadio`]), the `[[sensor]]` array and the link fields a sensor may
/// set for itself ([`RawSensor`]). The writer of [`super::text`] uses them;
/// a test checks them against the serde names of the structs below.
pub(crate) mod keys {
    pub const RADIO: &str = "radio";
    pub const SENSOR: &str = "sensor";
    pub const LOSS: &str = "loss";
    pub const RETRIES: &str = "retries";
    pub const BURST: &str = "burst";
    pub const ESTIMATOR: &str = "estimator";
    pub const TRIGGERING: &str = "triggering";
    pub const FAMILY: &str = "family";
    /// A link's settings: in `[radio]` for every link, in a `[[sensor]]` for its own.
    pub const LINK: [&str; 3] = [LOSS, RETRIES, BURST];
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawScenario {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub dim: usize,
    pub model: RawModel,
    pub controller: RawController,
    #[serde(rename = "sensor", default)]
    pub sensors: Vec<RawSensor>,
    #[serde(rename = "leg", default)]
    pub legs: Vec<RawLeg>,
    pub target: RawBox,
    #[serde(rename = "obstacle", default)]
    pub obstacles: Vec<RawObstacle>,
    pub triggering: RawTriggering,
    /// The lossy radio (docs/MODEL.md §8); absent = ideal. Skipped when absent
    /// so the content hash of a scenario without it is what it was before §8.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radio: Option<RawRadio>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRadio {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retries: Option<i64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub burst: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimator: Option<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawModel {
    #[serde(rename = "F")]
    pub f: RawMatrix,
    #[serde(rename = "G")]
    pub g: RawMatrix,
    #[serde(rename = "Q")]
    pub q: RawMatrix,
    pub x0: Vec<f64>,
    #[serde(rename = "P0")]
    pub p0: RawMatrix,
    /// Workspace map (MODEL.md §7); absent = I_n. Skipped when absent so the
    /// content hash of a scenario without it is what it was before §7.
    #[serde(rename = "C", default, skip_serializing_if = "Option::is_none")]
    pub c: Option<RawMatrix>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawController {
    pub u_max: f64,
    pub eps_x: f64,
    pub k_max: i64,
    /// Feedback gain p×n (MODEL.md §7); absent = I (p = n) unless `lqr` is given.
    #[serde(rename = "K", default, skip_serializing_if = "Option::is_none")]
    pub k: Option<RawMatrix>,
    /// LQR weights from which K is computed (MODEL.md §7).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lqr: Option<RawLqr>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLqr {
    /// n×n, symmetric positive semi-definite.
    pub state: RawMatrix,
    /// p×p, symmetric positive definite.
    pub input: RawMatrix,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSensor {
    pub name: String,
    pub position: Vec<f64>,
    #[serde(rename = "H")]
    pub h: RawMatrix,
    #[serde(rename = "R")]
    pub r: RawMatrix,
    #[serde(default = "one")]
    pub cost: f64,
    /// This link's radio settings, overriding `[radio]` (docs/MODEL.md §8);
    /// skipped when absent (content hash unchanged).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retries: Option<i64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub burst: Option<f64>,
}

fn one() -> f64 {
    1.0
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLeg {
    pub to: Vec<f64>,
    pub sensor: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawBox {
    pub min: Vec<f64>,
    pub max: Vec<f64>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawObstacle {
    #[serde(default)]
    pub name: Option<String>,
    pub min: Vec<f64>,
    pub max: Vec<f64>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTriggering {
    pub deltas: Vec<f64>,
    /// The trigger family (docs/MODEL.md §9); absent = `box`. Skipped when
    /// absent (and `box` is read as absent) so a scenario's content hash is
    /// what it was before the families.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub family: Option<String>,
}
