//! Resolving user input: scenario names and paths, and the radio options.

use anyhow::{Context, Result, bail};
use etp_shared::radio::{Estimator, RadioOverride};
use etp_shared::scenario::{Scenario, ScenarioText, builtin_text};
use etp_shared::trigger::TriggerFamily;

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

/// The radio options of `simulate`, `synthesize`, `validate` and `run`
/// (docs/MODEL.md §8): each one given replaces the scenario's setting on every
/// sensor link.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct RadioArgs {
    /// Probability that one transmission attempt is lost, in [0, 1) (0 = ideal radio).
    #[arg(long, value_name = "P", allow_negative_numbers = true)]
    pub loss: Option<f64>,
    /// Further attempts in the same step after a lost one (acknowledged link).
    #[arg(long, value_name = "R", allow_negative_numbers = true)]
    pub retries: Option<i64>,
    /// Gilbert–Elliott channel with this mean burst length in steps (≥ 1).
    #[arg(long, value_name = "B", allow_negative_numbers = true)]
    pub burst: Option<f64>,
    /// The agent's silence update: `aware` (β_q, knows packets get lost) or `naive` (β).
    #[arg(long, value_parser = ["aware", "naive"])]
    pub estimator: Option<String>,
}

/// `--trigger FAMILY` of `simulate`, `synthesize`, `run` and `bench`: the
/// trigger family every sensor uses, over the scenario's `[triggering]
/// family` (docs/MODEL.md §9). On `validate` (and `run` with a strategy) it
/// can only confirm the strategy's own family ([`TriggerArgs::confirm`]).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct TriggerArgs {
    /// Trigger family over the scenario's own: box (the paper's ∞-norm trigger), stochastic,
    /// send-on-delta, variance or periodic (docs/MODEL.md §9).
    #[arg(long, value_name = "FAMILY", value_parser = parse_family)]
    pub trigger: Option<TriggerFamily>,
}

/// A command-line probability (`--min-target`, `--max-collision`): a
/// number in [0, 1], else the error clap prints after the flag's name.
pub fn probability(s: &str) -> std::result::Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("must be a probability in [0, 1], got {v}"))
    }
}

/// A family name on the command line (`--trigger`, `--families`): the error names it.
pub fn parse_family(s: &str) -> std::result::Result<TriggerFamily, String> {
    TriggerFamily::parse(s).map_err(|e| e.to_string())
}

impl TriggerArgs {
    /// The scenario `text` with the family written into it (the text itself
    /// without the option or when it already says so).
    pub fn apply_to_text(&self, text: String) -> Result<String> {
        let Some(family) = self.trigger else {
            return Ok(text);
        };
        let own = ScenarioText::parse(text).context("scenario")?;
        Ok(own.with_trigger(family).context("--trigger")?.text)
    }

    /// A strategy's family, confirmed: a strategy is made for its scenario's
    /// family (its thresholds and predictions mean nothing under another), so
    /// `--trigger` naming another is refused by name.
    pub fn confirm(&self, strategy_family: TriggerFamily) -> Result<()> {
        match self.trigger {
            Some(family) if family != strategy_family => bail!(
                "--trigger {family}: the strategy was made for trigger family `{strategy_family}` \
                 (its thresholds and predictions hold for that family only); synthesize with \
                 --trigger {family} for a strategy of that family"
            ),
            _ => Ok(()),
        }
    }

    /// The scenario with the family applied (for runs that write no file
    /// carrying the scenario).
    pub fn apply(&self, mut s: Scenario) -> Scenario {
        if let Some(family) = self.trigger {
            s.trigger = family;
        }
        s
    }
}

/// How many episodes an in-process simulation runs, and from which seed
/// (`etp simulate`, `etp validate`).
#[derive(Debug, Clone, clap::Args)]
pub struct EpisodeArgs {
    /// Number of episodes (at least 1).
    #[arg(long, default_value_t = 3000, value_parser = clap::value_parser!(u64).range(1..))]
    pub episodes: u64,
    /// Seed of the random streams (same seed, same numbers, any thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
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

    /// `scenario` under these settings (errors name the option).
    pub fn apply(&self, scenario: Scenario) -> Result<Scenario> {
        scenario
            .with_radio_override(&self.to_override())
            .context("radio options")
    }
}

/// A `SCENARIO` argument under the radio options.
pub fn load_scenario_with_radio(arg: &str, radio: &RadioArgs) -> Result<Scenario> {
    radio.apply(load_scenario(arg)?)
}

/// The scenario `text` with the radio options written into it
/// (docs/MODEL.md §8.6; `etp scenario radio`), for runs and files that must
/// carry their channel in the text. Only a text without a channel of its own
/// takes one. No options: `text` itself.
pub fn text_with_radio(text: &str, radio: &RadioArgs) -> Result<String> {
    let own = ScenarioText::parse(text.to_string()).context("scenario")?;
    let o = radio.to_override();
    if o.is_empty() {
        return Ok(own.text);
    }
    if own.sets_a_channel()? {
        bail!(
            "the scenario sets a channel of its own ([radio] or a sensor's loss, retries or \
             burst); edit it there instead of giving radio options"
        );
    }
    let wanted = own
        .scenario
        .radio
        .for_use(None, &o)
        .context("radio options")?;
    Ok(own.with_channel(&wanted)?.text)
}
