//! Scenarios: the system, sensors, route, target, obstacles and candidate thresholds.
//!
//! A scenario is written in TOML (see `scenarios/*.toml`). [`Scenario::from_toml`]
//! parses *and validates* it: every error names the offending field (for example
//! `sensor[2] "s2".R`) and the reason. A [`Scenario`] value is therefore always
//! usable by the maths without further checks: dimensions agree, covariances are
//! symmetric positive definite, numbers are finite.

mod builtin;
mod fields;
pub mod random;
mod raw;
mod text;
mod validate;
mod workable;
mod workspace_gain;

pub use builtin::{BUILTIN_NAMES, DEFAULT_SCENARIO, builtin_text};
pub use text::ScenarioText;
pub use workspace_gain::pseudo_inverse;

use crate::geometry::Aabb;
use crate::radio::{Radio, RadioOverride};
use crate::trigger::TriggerFamily;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Largest state dimension the fixed-size maths is instantiated for.
pub const MAX_DIM: usize = 6;

/// Why a scenario was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ScenarioError {
    /// The text is not valid TOML or does not have the scenario's shape.
    #[error("scenario is not valid TOML for the scenario format: {0}")]
    Parse(String),
    /// A field has a value the model cannot accept.
    #[error("scenario field `{field}`: {reason}")]
    Invalid { field: String, reason: String },
    /// Not the name of a built-in scenario (the list is [`BUILTIN_NAMES`],
    /// so that the message names every one).
    #[error("unknown built-in scenario `{0}` (built-ins: {names})", names = BUILTIN_NAMES.join(", "))]
    UnknownBuiltin(String),
}

impl ScenarioError {
    pub(crate) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Invalid {
            field: field.into(),
            reason: reason.into(),
        }
    }
}

/// Linear-Gaussian plant: `x' = F x + G u + w`, `w ~ N(0, Q)`, `x0 ~ N(x0, P0)`;
/// G is n×p (MODEL.md §7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plant {
    pub f: DMatrix<f64>,
    pub g: DMatrix<f64>,
    pub q: DMatrix<f64>,
    pub x0: DVector<f64>,
    pub p0: DMatrix<f64>,
}

/// The waypoint controller `u = sat(K (C⁺w − x̂), u_max)` (MODEL.md §7; K and C
/// live in [`Scenario::gain`] and [`Scenario::workspace`]) and its leg termination rule.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ControllerParams {
    /// Euclidean saturation of the input.
    pub u_max: f64,
    /// A leg ends when `‖C x̂ − w‖₂ ≤ eps_x` ...
    pub eps_x: f64,
    /// ... or after `k_max` steps in the leg.
    pub k_max: u32,
}

/// A remote sensor: `y = H x + v`, `v ~ N(0, R)`, `cost` per transmitted
/// measurement; `position` is a workspace point (R^d).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sensor {
    pub name: String,
    pub position: DVector<f64>,
    pub h: DMatrix<f64>,
    pub r: DMatrix<f64>,
    pub cost: f64,
}

impl Sensor {
    /// Measurement dimension m.
    pub fn dim(&self) -> usize {
        self.h.nrows()
    }
}

/// One leg of the route: drive to the workspace point `to` (R^d), served by
/// sensor index `sensor`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Leg {
    pub to: DVector<f64>,
    pub sensor: usize,
}

/// A named closed axis-aligned box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Obstacle {
    pub name: String,
    pub bounds: Aabb,
}

/// A validated scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    pub name: String,
    pub description: String,
    /// State dimension n (1..=6).
    pub dim: usize,
    pub plant: Plant,
    pub controller: ControllerParams,
    pub sensors: Vec<Sensor>,
    pub legs: Vec<Leg>,
    pub target: Aabb,
    pub obstacles: Vec<Obstacle>,
    /// Candidate thresholds Δ (the MDP's actions), in file order.
    pub deltas: Vec<f64>,
    /// SHA-256 (hex) of the scenario's canonical content: files made from this
    /// scenario (MDP, strategy, recording) carry it so a mismatch is refused.
    pub content_hash: String,
    /// The workspace map C (d×n, full row rank; MODEL.md §7); `None` = I_n.
    /// Legs, sensor positions, target and obstacles live in R^d.
    #[serde(default)]
    pub workspace: Option<DMatrix<f64>>,
    /// The feedback gain K (p×n; given or from `[controller.lqr]`); `None` = I.
    #[serde(default)]
    pub gain: Option<DMatrix<f64>>,
    /// Where the route starts: `w₀ = C x̂₀`.
    #[serde(default)]
    pub route_start: DVector<f64>,
    /// Valid but probably unintended settings (e.g. a reference that is not a
    /// rest point), for `etp check` to show.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The radio: one link per sensor and the agent's estimator (docs/MODEL.md
    /// §8); ideal unless the file has `[radio]` or per-sensor `loss`.
    #[serde(default)]
    pub radio: Radio,
    /// How every sensor decides to transmit (`[triggering] family`,
    /// docs/MODEL.md §9); `box`, the paper's trigger, unless the file says.
    #[serde(default)]
    pub trigger: TriggerFamily,
}

impl Scenario {
    /// Parse and validate a scenario from TOML text.
    pub fn from_toml(text: &str) -> Result<Self, ScenarioError> {
        let raw: raw::RawScenario =
            toml::from_str(text).map_err(|e| ScenarioError::Parse(e.to_string()))?;
        validate::validate(raw)
    }

    /// A built-in scenario by name (`winding-2d`, `open-2d`, `superg-3d`,
    /// `inertia-2d`, `inertia-3d`).
    pub fn builtin(name: &str) -> Result<Self, ScenarioError> {
        let text =
            builtin_text(name).ok_or_else(|| ScenarioError::UnknownBuiltin(name.to_string()))?;
        Self::from_toml(text)
    }

    /// The scenario under command-line radio settings (`--loss`, `--retries`,
    /// `--burst`, `--estimator`), which replace the file's for every link.
    /// The content hash stays the file's: the channel is a condition of use
    /// (a strategy may be evaluated under another radio, docs/MODEL.md §8).
    pub fn with_radio_override(mut self, o: &RadioOverride) -> Result<Self, ScenarioError> {
        self.radio = self
            .radio
            .for_use(None, o)
            .map_err(|e| ScenarioError::invalid(e.field, e.reason))?;
        Ok(self)
    }

    /// Number of legs (= decision points).
    pub fn num_legs(&self) -> usize {
        self.legs.len()
    }

    /// The sensor serving leg `i`.
    pub fn leg_sensor(&self, leg: usize) -> &Sensor {
        &self.sensors[self.legs[leg].sensor]
    }

    /// Where leg `i` starts, in the workspace: `C x̂₀` for leg 0, else the
    /// previous waypoint.
    pub fn leg_start(&self, leg: usize) -> &DVector<f64> {
        if leg == 0 {
            &self.route_start
        } else {
            &self.legs[leg - 1].to
        }
    }

    /// Workspace dimension d (rows of C; n without C).
    pub fn workspace_dim(&self) -> usize {
        self.workspace.as_ref().map_or(self.dim, DMatrix::nrows)
    }

    /// Input dimension p (columns of G).
    pub fn input_dim(&self) -> usize {
        self.plant.g.ncols()
    }

    /// The workspace point `C x` of a state.
    pub fn workspace_point(&self, x: &[f64]) -> DVector<f64> {
        let x = DVector::from_column_slice(x);
        match &self.workspace {
            Some(c) => c * x,
            None => x,
        }
    }

    /// The controller's reference for waypoint `w`: `C⁺ w` (MODEL.md §7).
    pub fn reference(&self, w: &DVector<f64>) -> DVector<f64> {
        match &self.workspace {
            Some(c) => pseudo_inverse(c) * w,
            None => w.clone(),
        }
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod radio_tests;

#[cfg(test)]
mod workable_tests;
