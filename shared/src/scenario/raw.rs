//! The scenario file's shape, exactly as written in TOML (before validation).

use serde::{Deserialize, Serialize};

pub(crate) type RawMatrix = Vec<Vec<f64>>;

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
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawController {
    pub u_max: f64,
    pub eps_x: f64,
    pub k_max: i64,
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
}
