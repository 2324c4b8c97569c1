//! Resolving user input: scenario names and paths.

use anyhow::{Context, Result};
use etp_shared::scenario::{BUILTIN_NAMES, Scenario, builtin_text};
use std::path::Path;

/// A `SCENARIO` argument: a built-in name (`winding-2d`, …) or a TOML path.
pub fn load_scenario(arg: &str) -> Result<Scenario> {
    if let Some(text) = builtin_text(arg) {
        return Scenario::from_toml(text).with_context(|| format!("built-in scenario `{arg}`"));
    }
    let path = Path::new(arg);
    if !path.exists() {
        anyhow::bail!(
            "`{arg}` is neither a built-in scenario ({}) nor an existing file",
            BUILTIN_NAMES.join(", ")
        );
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading scenario file {}", path.display()))?;
    Scenario::from_toml(&text).with_context(|| format!("scenario file {}", path.display()))
}

/// The TOML text of a scenario argument (for embedding into outputs).
pub fn scenario_text(arg: &str) -> Result<String> {
    if let Some(text) = builtin_text(arg) {
        return Ok(text.to_string());
    }
    std::fs::read_to_string(arg).with_context(|| format!("reading scenario file {arg}"))
}
