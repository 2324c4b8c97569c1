//! A `SCENARIO` argument, resolved once for every program: a built-in name
//! (`winding-2d`, …) or the path of a TOML file. `etp` and every process
//! of a run (the supervisor passes them the same argument) read it here.

use etp_shared::scenario::{BUILTIN_NAMES, Scenario, ScenarioError, builtin_text};
use etp_shared::trigger::TriggerFamily;
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
    #[error(
        "triggering.family = \"{family}\": the processes of a run do not implement this family \
         (its silence update needs the last delivered measurement at the agent); it runs \
         in-process (etp simulate, synthesize, strategy, validate; docs/MODEL.md §9)"
    )]
    ProcessesRefuseFamily { family: TriggerFamily },
}

/// The scenario of a run's process ([`load_scenario`]), refused when the
/// processes do not implement its trigger family ([`runs_as_processes`]).
pub fn load_process_scenario(arg: &str) -> Result<Scenario, ScenarioArgError> {
    let s = load_scenario(arg)?;
    if !runs_as_processes(s.trigger) {
        return Err(ScenarioArgError::ProcessesRefuseFamily { family: s.trigger });
    }
    Ok(s)
}

/// Whether the processes of a run implement `family`: every family whose
/// silence update is a shrink of the prior (box, stochastic, variance,
/// periodic); not send-on-delta, whose silence is a pseudo-measurement of
/// the last delivered y (docs/MODEL.md §9).
pub fn runs_as_processes(family: TriggerFamily) -> bool {
    family != TriggerFamily::SendOnDelta
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
