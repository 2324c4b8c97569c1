//! `etpareto.load_scenario`: a built-in name or a TOML path, resolved by
//! `etp_runtime::load_scenario` (the one resolver of `etp` and of every
//! process of a run).

use crate::errors::{ScenarioError, chain};
use etp_shared::scenario::{BUILTIN_NAMES, Scenario};
use pyo3::prelude::*;

/// A validated scenario (`etpareto.load_scenario`).
#[pyclass(name = "Scenario", module = "etpareto", frozen)]
pub struct PyScenario {
    /// The argument it was loaded from (built-in name or path).
    pub arg: String,
    pub scenario: Scenario,
}

#[pymethods]
impl PyScenario {
    /// The scenario's name (`name` in its TOML).
    #[getter]
    fn name(&self) -> String {
        self.scenario.name.clone()
    }
    /// Its one-line description.
    #[getter]
    fn description(&self) -> String {
        self.scenario.description.clone()
    }
    /// The built-in name or path it was loaded from.
    #[getter]
    fn source(&self) -> String {
        self.arg.clone()
    }
    /// State dimension n.
    #[getter]
    fn dim(&self) -> usize {
        self.scenario.dim
    }
    /// SHA-256 of the scenario's canonical content (what files made from it carry).
    #[getter]
    fn content_hash(&self) -> String {
        self.scenario.content_hash.clone()
    }
    /// The sensors' names, in file order.
    #[getter]
    fn sensors(&self) -> Vec<String> {
        self.scenario
            .sensors
            .iter()
            .map(|s| s.name.clone())
            .collect()
    }
    /// The sensor serving each leg, by name.
    #[getter]
    fn legs(&self) -> Vec<String> {
        (0..self.scenario.num_legs())
            .map(|i| self.scenario.leg_sensor(i).name.clone())
            .collect()
    }
    /// The candidate thresholds Δ (the MDP's actions), in file order.
    #[getter]
    fn deltas(&self) -> Vec<f64> {
        self.scenario.deltas.clone()
    }
    /// The trigger family (`box`, `stochastic`, …).
    #[getter]
    fn trigger(&self) -> String {
        self.scenario.trigger.name().to_string()
    }
    /// Valid but probably unintended settings, as `etp check` lists them.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.scenario.warnings.clone()
    }
    fn __repr__(&self) -> String {
        format!(
            "Scenario(name={:?}, source={:?}, dim={}, sensors={}, legs={})",
            self.scenario.name,
            self.arg,
            self.scenario.dim,
            self.scenario.sensors.len(),
            self.scenario.num_legs()
        )
    }
}

/// The scenario of `arg` (a built-in name or a TOML path), or the
/// `ScenarioError` `etp check ARG` prints.
pub fn load(arg: &str) -> PyResult<PyScenario> {
    let scenario =
        etp_runtime::load_scenario(arg).map_err(|e| ScenarioError::new_err(chain(&e)))?;
    Ok(PyScenario {
        arg: arg.to_string(),
        scenario,
    })
}

/// Load and validate a scenario: a built-in name (`winding-2d`, …) or the
/// path of a scenario TOML. Raises `ScenarioError` with `etp check`'s message.
#[pyfunction]
pub fn load_scenario(name_or_path: &str) -> PyResult<PyScenario> {
    load(name_or_path)
}

/// The built-in scenarios' names.
#[pyfunction]
pub fn builtin_scenarios() -> Vec<String> {
    BUILTIN_NAMES.iter().map(|s| s.to_string()).collect()
}

/// A scenario argument from Python: a `Scenario` or a name/path string.
pub fn resolve(obj: &Bound<'_, PyAny>) -> PyResult<Scenario> {
    if let Ok(s) = obj.cast::<PyScenario>() {
        return Ok(s.get().scenario.clone());
    }
    let arg: String = obj.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "scenario: an etpareto.Scenario, a built-in name or a TOML path",
        )
    })?;
    Ok(load(&arg)?.scenario)
}
