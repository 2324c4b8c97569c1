//! Resolving user input: scenario names and paths, and the radio options.

use anyhow::{Context, Result, bail};
use etp_shared::radio::{Estimator, RadioOverride};
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

/// The scenario `text` with the radio options written into it as a
/// `[radio]` table (docs/MODEL.md §8), for runs and files that must carry
/// their channel in the text (every process of a run, and its recording,
/// read the scenario text). Only a text without a lossy radio of its own
/// takes one; the result is parsed again and must give exactly the channel
/// the options give. No options: `text` itself.
pub fn text_with_radio(text: &str, radio: &RadioArgs) -> Result<String> {
    let o = radio.to_override();
    if o.is_empty() {
        return Ok(text.to_string());
    }
    let scenario = Scenario::from_toml(text).context("scenario")?;
    if !scenario.radio.is_ideal() || text.lines().any(|l| l.trim() == "[radio]") {
        bail!(
            "the scenario has a [radio] of its own; edit it there instead of giving radio options"
        );
    }
    let wanted = radio.apply(scenario)?.radio;
    let link = wanted.link(0);
    let mut table = format!(
        "\n[radio]\nloss = {:?}\nretries = {}\nestimator = \"{}\"\n",
        link.loss,
        link.retries,
        wanted.estimator.name()
    );
    if let Some(b) = link.burst {
        table.push_str(&format!("burst = {b:?}\n"));
    }
    let out = format!("{}\n{table}", text.trim_end());
    let parsed = Scenario::from_toml(&out).context("the scenario with its [radio]")?;
    if parsed.radio != wanted {
        bail!(
            "the radio options cannot be written into this scenario's text (it sets a link of \
             its own): edit its [radio] or [[sensor]] entries instead"
        );
    }
    Ok(out)
}
