//! A `SCENARIO` argument, resolved once for every program: a built-in name
//! (`winding-2d`, …) or the path of a TOML file. `etp` and every process
//! of a run (the supervisor passes them the same argument) read it here.

use etp_shared::scenario::{BUILTIN_NAMES, Scenario, ScenarioError, builtin_text};
use std::path::{Path, PathBuf};

/// Why a scenario argument could not be resolved (the cause is the
/// `source`: `{:#}` of an `anyhow` error shows it after a colon).
#[derive(Debug, thiserror::Error)]
pub enum ScenarioArgError {
    #[error("built-in scenario `{name}`")]
    Builtin {
        name: String,
        #[source]
        source: ScenarioError,
    },
    #[error("`{arg}` is neither a built-in scenario ({}) nor an existing file", BUILTIN_NAMES.join(", "))]
    NotFound { arg: String },
    #[error("reading scenario file {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("scenario file {}", path.display())]
    Invalid {
        path: PathBuf,
        #[source]
        source: ScenarioError,
    },
}

/// The scenario of a `SCENARIO` argument: a built-in name or a TOML path.
pub fn load_scenario(arg: &str) -> Result<Scenario, ScenarioArgError> {
    if let Some(text) = builtin_text(arg) {
        return Scenario::from_toml(text).map_err(|source| ScenarioArgError::Builtin {
            name: arg.to_string(),
            source,
        });
    }
    let path = Path::new(arg);
    if !path.exists() {
        return Err(ScenarioArgError::NotFound {
            arg: arg.to_string(),
        });
    }
    let text = std::fs::read_to_string(path).map_err(|source| ScenarioArgError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    Scenario::from_toml(&text).map_err(|source| ScenarioArgError::Invalid {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_ins_load_and_a_missing_file_is_named() {
        assert!(load_scenario("winding-2d").is_ok());
        let e = load_scenario("/nonexistent/x.toml").expect_err("missing");
        assert!(
            e.to_string()
                .starts_with("`/nonexistent/x.toml` is neither a built-in scenario (winding-2d"),
            "{e}"
        );
    }
}
