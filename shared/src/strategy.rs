//! A threshold strategy: at decision point i, the belief's covariance region s
//! selects a distribution ω(s) over the thresholds Δ (docs/MODEL.md §5).
//!
//! Stored as `strategy.json`. A [`Strategy`] has three parts: its
//! [`Policy`] (what running it needs: the scenario's name and content hash,
//! so it is never applied to another scenario, Δ, its own discretization, so
//! the coordinator and the in-process validator classify beliefs
//! identically, and ω), its [`Predictions`] (what etp predicts of it, for
//! reports), and its [`Provenance`] (how it was obtained). The file is one
//! flat object whose keys interleave the parts ([`format`]).
//!
//! The file is sealed by its own hash: its last key, `content_sha256`, is the
//! SHA-256 of the file's exact text without that key ([`Strategy::to_json`]).
//! Any edit — a value (`scenario_name`, `predicted`, `leg_energy`, …), a key
//! added or removed, or a reformatting — is refused by
//! [`Strategy::from_sealed_json`] (the loader of strategy files). Files
//! written before the seal are refused too, with a message to re-run `etp
//! strategy`; [`Strategy::from_json`] (strategies embedded in recordings)
//! checks the seal when present and accepts old, unsealed ones.

use crate::discretization::Region;
use crate::scenario::Scenario;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

mod aggregation;
mod format;
mod policy;
mod prediction;
pub use aggregation::{AggregationCheck, AggregationError, PredictionCi95, SimulatedValue};
pub use policy::{OmegaChoice, Policy, sample_index};
pub use prediction::{
    CertifiedPrediction, Diagnostics, Prediction, Predictions, RebuildValue, RequestRound,
    SelectionValues,
};

/// Version of the `strategy.json` layout. Version 2: `predicted` is the
/// prediction etp stands by (with `predicted_ci95` and `prediction_basis`),
/// every other value under `diagnostics`; version 1 files (whose `predicted`
/// was the selection-time value) are read and converted ([`format`]).
pub const STRATEGY_FORMAT_VERSION: u32 = 2;

/// Why a strategy cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum StrategyError {
    #[error("strategy file is not valid JSON for a strategy: {0}")]
    Parse(String),
    #[error(
        "strategy format version {found} is not supported (this etp reads versions 1 to {expected})"
    )]
    Version { found: u32, expected: u32 },
    #[error(
        "strategy was made for scenario `{strategy_name}` (hash {strategy_hash:.12}…), not for `{scenario_name}` (hash {scenario_hash:.12}…)"
    )]
    ScenarioMismatch {
        strategy_name: String,
        strategy_hash: String,
        scenario_name: String,
        scenario_hash: String,
    },
    #[error("strategy is inconsistent: {0}")]
    Invalid(String),
    #[error(
        "strategy file has no `content_sha256` (written before strategy files were sealed by their hash, or the key was removed); re-create it with `etp strategy` (or `etp run --scenario NAME --delta D` for a constant δ)"
    )]
    Unsealed,
    #[error(
        "strategy file was changed after it was written: {0}; a strategy file is used only as `etp strategy` wrote it (re-create it with `etp strategy`)"
    )]
    Tampered(String),
}

/// The key of the seal, the file's last (see the module doc).
const SEAL_KEY: &str = "content_sha256";

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The seal of a strategy file's text: `Ok(None)` without one, `Ok(Some(()))`
/// when it matches, an error naming what is wrong otherwise.
fn check_seal(text: &str) -> Result<Option<()>, StrategyError> {
    let t = text.trim_end();
    let marker = format!(",\n  \"{SEAL_KEY}\": \"");
    let Some(at) = t.rfind(&marker) else {
        return if t.contains(&format!("\"{SEAL_KEY}\"")) {
            Err(StrategyError::Tampered(format!(
                "`{SEAL_KEY}` is not the file's last key as written (the file was reformatted or keys were moved)"
            )))
        } else {
            Ok(None)
        };
    };
    let rest = &t[at + marker.len()..];
    let Some(hex) = rest.strip_suffix("\"\n}") else {
        return Err(StrategyError::Tampered(format!(
            "keys follow `{SEAL_KEY}`, which is the file's last key as written"
        )));
    };
    let body = format!("{}\n}}", &t[..at]);
    let actual = sha256_hex(body.as_bytes());
    if hex != actual {
        return Err(StrategyError::Tampered(format!(
            "its text hashes to {actual:.12}…, not to the `{SEAL_KEY}` {hex:.12}… it was written with (a field such as `scenario_name`, `predicted`, `leg_energy` or `states` was edited)"
        )));
    }
    Ok(Some(()))
}

/// ω for one abstract state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StrategyState {
    pub decision_point: usize,
    pub region: Region,
    /// Probability of each threshold (same order as [`Policy::deltas`]); sums to 1.
    pub omega: Vec<f64>,
}

/// Where a strategy came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Provenance {
    /// The layout it was read in or is written in: [`STRATEGY_FORMAT_VERSION`]
    /// once read (older layouts are converted).
    pub format_version: u32,
    /// How it was obtained (e.g. "min energy s.t. P_tar ≥ 0.95", "constant δ = 0").
    pub label: String,
}

/// A memoryless randomised threshold strategy: the policy that runs, what
/// etp predicts of it, and where it came from. Read and written as
/// `strategy.json` through [`format::StrategyFile`], which keeps the file's
/// keys and their order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "format::StrategyFile", into = "format::StrategyFile")]
pub struct Strategy {
    pub provenance: Provenance,
    pub policy: Policy,
    pub predictions: Predictions,
}

impl Strategy {
    /// The same δ on every leg (region-free), predicted as `predicted`.
    pub fn constant(
        scenario: &Scenario,
        delta_index: usize,
        predicted: Option<Prediction>,
    ) -> Self {
        Self {
            provenance: Provenance {
                format_version: STRATEGY_FORMAT_VERSION,
                label: format!("constant δ = {}", scenario.deltas[delta_index]),
            },
            policy: Policy::constant(scenario, delta_index),
            predictions: Predictions {
                predicted,
                ..Predictions::default()
            },
        }
    }

    /// A strategy file: the seal must be present and match (see the module
    /// doc), then as [`Strategy::from_json`].
    pub fn from_sealed_json(text: &str) -> Result<Self, StrategyError> {
        if check_seal(text)?.is_none() {
            // Not JSON at all is a parse error, not a missing seal.
            serde_json::from_str::<serde_json::Value>(text)
                .map_err(|e| StrategyError::Parse(e.to_string()))?;
            return Err(StrategyError::Unsealed);
        }
        Self::from_json(text)
    }

    /// Parse and check internal consistency; the seal is checked when the
    /// text has one (strategies recorded before it was introduced have none).
    pub fn from_json(text: &str) -> Result<Self, StrategyError> {
        #[derive(Deserialize)]
        struct Versioned {
            format_version: u32,
        }
        let v: Versioned =
            serde_json::from_str(text).map_err(|e| StrategyError::Parse(e.to_string()))?;
        if !(1..=STRATEGY_FORMAT_VERSION).contains(&v.format_version) {
            return Err(StrategyError::Version {
                found: v.format_version,
                expected: STRATEGY_FORMAT_VERSION,
            });
        }
        check_seal(text)?;
        let s: Self = match v.format_version {
            STRATEGY_FORMAT_VERSION => {
                serde_json::from_str(text).map_err(|e| StrategyError::Parse(e.to_string()))?
            }
            1 => format::from_version_1(text)?,
            found => {
                return Err(StrategyError::Version {
                    found,
                    expected: STRATEGY_FORMAT_VERSION,
                });
            }
        };
        s.policy.check_consistent()?;
        s.predictions.check_consistent()?;
        Ok(s)
    }

    /// The sealed text of a strategy file: pretty JSON whose last key,
    /// `content_sha256`, hashes the text without it.
    pub fn to_json(&self) -> String {
        let body = serde_json::to_string_pretty(self).unwrap_or_default();
        let hash = sha256_hex(body.as_bytes());
        match body.strip_suffix("\n}") {
            Some(head) => format!("{head},\n  \"{SEAL_KEY}\": \"{hash}\"\n}}"),
            None => body,
        }
    }
}

#[cfg(test)]
mod tests;
