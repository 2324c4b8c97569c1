//! The flags that change a `SCENARIO` argument, for every command that
//! takes one (`etp simulate`, `synthesize`, `validate`, `run`, `bench`):
//! the radio (`--loss`, `--retries`, `--burst`, `--estimator`,
//! docs/MODEL.md §8) and the trigger family (`--trigger`, §9). Parsed here
//! and handed to the libraries as typed values (a [`RadioOverride`], an
//! `Option<TriggerFamily>`).

use anyhow::{Context, Result};
use etp_shared::radio::{Estimator, RadioOverride};
use etp_shared::scenario::Scenario;
use etp_shared::trigger::TriggerFamily;

/// The radio options of `simulate`, `synthesize`, `validate` and `run`
/// (docs/MODEL.md §8): each one given replaces the scenario's setting on every
/// sensor link.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct RadioArgs {
    /// Probability that one transmission attempt is lost, in [0, 1) (0 = ideal radio).
    #[arg(long, value_name = "P", allow_negative_numbers = true, value_parser = crate::values::loss)]
    pub loss: Option<f64>,
    /// Further attempts in the same step after a lost one (acknowledged
    /// link), 0 to 1000; needs a loss (`--loss` or the scenario's).
    #[arg(long, value_name = "R", allow_negative_numbers = true,
          value_parser = crate::values::whole::<i64>(0, Some(etp_shared::radio::MAX_RETRIES as u64)))]
    pub retries: Option<i64>,
    /// Gilbert–Elliott channel with this mean burst length in steps (≥ 1).
    #[arg(long, value_name = "B", allow_negative_numbers = true, value_parser = crate::values::burst)]
    pub burst: Option<f64>,
    /// The agent's silence update: `aware` (β_q, knows packets get lost) or `naive` (β).
    #[arg(long, value_parser = ["aware", "naive"])]
    pub estimator: Option<String>,
}

impl RadioArgs {
    /// The settings as an override of the scenario's radio.
    pub fn to_override(&self) -> RadioOverride {
        RadioOverride {
            loss: self.loss,
            retries: self.retries,
            burst: self.burst,
            estimator: self.estimator.as_deref().and_then(Estimator::parse),
        }
    }

    /// `scenario` under these settings (errors name the option, as
    /// `etp run`'s do: the channel's own error, not a scenario field's).
    pub fn apply(&self, mut scenario: Scenario) -> Result<Scenario> {
        scenario.radio = scenario
            .radio
            .for_use(None, &self.to_override())
            .context("radio options")?;
        Ok(scenario)
    }
}

/// `--trigger FAMILY` of `simulate`, `synthesize`, `run` and `bench`: the
/// trigger family every sensor uses, over the scenario's `[triggering]
/// family` (docs/MODEL.md §9). On `validate` (and `run` with a strategy) it
/// can only confirm the strategy's own family (`etp validate`: the
/// validation request's `trigger`).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct TriggerArgs {
    /// Trigger family over the scenario's own: box (the paper's ∞-norm trigger), stochastic,
    /// send-on-delta, variance or periodic (docs/MODEL.md §9).
    #[arg(long, value_name = "FAMILY", value_parser = parse_family)]
    pub trigger: Option<TriggerFamily>,
}

/// A family name on the command line (`--trigger`, `--families`): the error names it.
pub fn parse_family(s: &str) -> std::result::Result<TriggerFamily, String> {
    TriggerFamily::parse(s).map_err(|e| e.to_string())
}

impl TriggerArgs {
    /// The scenario with the family applied (for runs that write no file
    /// carrying the scenario).
    pub fn apply(&self, mut s: Scenario) -> Scenario {
        if let Some(family) = self.trigger {
            s.trigger = family;
        }
        s
    }
}
