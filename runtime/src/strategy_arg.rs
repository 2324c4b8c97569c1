//! A `STRATEGY` argument: a sealed `strategy.json` and the scenario it was
//! made for, read once for every command that takes one (`validate`,
//! `synthesize --pool-policy`, `strategy --evaluate`).

use etp_shared::scenario::Scenario;
use etp_shared::strategy::{Strategy, StrategyError};
use std::path::{Path, PathBuf};

/// Why a strategy file could not be loaded (the cause is the `source`).
#[derive(Debug, thiserror::Error)]
pub enum StrategyArgError {
    #[error("reading {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Not a strategy file, an edited one (seal) or another format version.
    #[error("loading strategy {}", path.display())]
    Invalid {
        path: PathBuf,
        #[source]
        source: StrategyError,
    },
    /// Its scenario (embedded or built-in) is missing or has another hash.
    #[error("strategy {}", path.display())]
    Scenario {
        path: PathBuf,
        #[source]
        source: StrategyError,
    },
}

/// The strategy of file `path` (its seal checked) and its scenario: the
/// embedded text, else the built-in of that name, hash checked, under the
/// channel the strategy was synthesized for ([`Policy::scenario`](etp_shared::strategy::Policy::scenario)).
pub fn load_strategy(path: &Path) -> Result<(Strategy, Scenario), StrategyArgError> {
    let text = std::fs::read_to_string(path).map_err(|source| StrategyArgError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let strategy =
        Strategy::from_sealed_json(&text).map_err(|source| StrategyArgError::Invalid {
            path: path.to_path_buf(),
            source,
        })?;
    let scenario = strategy
        .policy
        .scenario()
        .map_err(|source| StrategyArgError::Scenario {
            path: path.to_path_buf(),
            source,
        })?;
    Ok((strategy, scenario))
}
