//! Resolving user input: scenario names and paths, and the radio and
//! trigger options (`crate::scenario_flags`, shared with the
//! multi-process launcher).

use crate::scenario_flags::RadioArgs;
use anyhow::{Context, Result, bail};
use etp_shared::scenario::{Scenario, ScenarioText};

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

/// How many episodes an in-process simulation runs, and from which seed
/// (`etp simulate`, `etp validate`).
#[derive(Debug, Clone, clap::Args)]
pub struct EpisodeArgs {
    /// Number of episodes (at least 1).
    #[arg(long, default_value_t = 3000, value_parser = crate::values::whole::<u64>(1, None))]
    pub episodes: u64,
    /// Seed of the random streams (same seed, same numbers, any thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// A `SCENARIO` argument (a built-in name or a TOML path, resolved by
/// `etp_runtime::scenario_arg` as in every process of a run) under the
/// radio options.
pub fn load_scenario_with_radio(arg: &str, radio: &RadioArgs) -> Result<Scenario> {
    radio.apply(etp_runtime::load_scenario(arg)?)
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
