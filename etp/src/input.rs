//! Resolving user input: scenario names and paths.

use anyhow::{Context, Result};
use etp_shared::scenario::{Scenario, builtin_text};

/// A `SCENARIO` argument: a built-in name (`winding-2d`, …) or a TOML path
/// (resolved by `etp_runtime`, as in every process of a run).
pub fn load_scenario(arg: &str) -> Result<Scenario> {
    Ok(etp_runtime::load_scenario(arg)?)
}

/// The TOML text of a scenario argument (for embedding into outputs).
pub fn scenario_text(arg: &str) -> Result<String> {
    if let Some(text) = builtin_text(arg) {
        return Ok(text.to_string());
    }
    std::fs::read_to_string(arg).with_context(|| format!("reading scenario file {arg}"))
}
