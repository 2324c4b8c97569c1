//! Resolving user input: scenario names and paths, and the radio options.

use anyhow::{Context, Result, bail};
use etp_shared::radio::{Estimator, Link, Radio, RadioOverride};
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

/// The scenario `text` with the radio options written into it as a
/// `[radio]` table (docs/MODEL.md §8), for runs and files that must carry
/// their channel in the text (every process of a run, and its recording,
/// read the scenario text). Only a text without a channel of its own takes
/// one ([`text_with_channel`] appends it). No options: `text` itself.
pub fn text_with_radio(text: &str, radio: &RadioArgs) -> Result<String> {
    let o = radio.to_override();
    if o.is_empty() {
        return Ok(text.to_string());
    }
    let scenario = Scenario::from_toml(text).context("scenario")?;
    if sets_a_channel(text)? {
        bail!(
            "the scenario sets a channel of its own ([radio] or a sensor's loss, retries or \
             burst); edit it there instead of giving radio options"
        );
    }
    text_with_channel(text, &radio.apply(scenario)?.radio)
}

/// The scenario `text` carrying exactly the channel `wanted` (docs/MODEL.md
/// §8), for a run whose channel is not its text's own: a strategy synthesized
/// under `--loss`, or run under radio options (a robustness study). `text`
/// itself when it already carries `wanted`; a `[radio]` table appended (the
/// text, comments and all, kept) when the text sets no channel and every link
/// is the same; else the text rewritten through TOML with its channel
/// replaced, one link per sensor. The result is parsed again and must give
/// exactly `wanted`.
pub fn text_with_channel(text: &str, wanted: &Radio) -> Result<String> {
    let scenario = Scenario::from_toml(text).context("scenario")?;
    // No links = every link ideal (`Radio::links`).
    let wanted = &if wanted.links.is_empty() {
        Radio {
            estimator: wanted.estimator,
            links: vec![Link::IDEAL; scenario.sensors.len()],
        }
    } else {
        wanted.clone()
    };
    if scenario.radio == *wanted {
        return Ok(text.to_string());
    }
    if wanted.links.len() != scenario.sensors.len() {
        bail!(
            "the channel has {} links for the {} sensors of scenario `{}`",
            wanted.links.len(),
            scenario.sensors.len(),
            scenario.name
        );
    }
    let first = wanted.link(0);
    let uniform = wanted.links.iter().all(|l| *l == first);
    let out = if uniform && !sets_a_channel(text)? {
        format!(
            "{}\n\n{}",
            text.trim_end(),
            radio_table(&first, wanted.estimator)
        )
    } else {
        rewritten_with_channel(text, wanted)?
    };
    let parsed = Scenario::from_toml(&out).context("the scenario with the run's channel")?;
    if parsed.radio != *wanted {
        bail!(
            "the channel could not be written into scenario `{}`'s text exactly",
            scenario.name
        );
    }
    Ok(out)
}

/// Whether the text has a `[radio]` table or a per-sensor channel field.
fn sets_a_channel(text: &str) -> Result<bool> {
    let v: toml::Table = toml::from_str(text).context("parsing the scenario")?;
    let per_sensor = v
        .get("sensor")
        .and_then(toml::Value::as_array)
        .is_some_and(|a| {
            a.iter().filter_map(toml::Value::as_table).any(|t| {
                ["loss", "retries", "burst"]
                    .iter()
                    .any(|k| t.contains_key(*k))
            })
        });
    Ok(v.contains_key("radio") || per_sensor)
}

/// `[radio]` for one link setting shared by every sensor.
fn radio_table(link: &Link, estimator: Estimator) -> String {
    let mut table = format!(
        "[radio]\nloss = {:?}\nretries = {}\nestimator = \"{}\"\n",
        link.loss,
        link.retries,
        estimator.name()
    );
    if let Some(b) = link.burst {
        table.push_str(&format!("burst = {b:?}\n"));
    }
    table
}

/// The text through TOML, its `[radio]` and per-sensor channel fields
/// replaced by `wanted`: the estimator in `[radio]`, each sensor's full link
/// in its own `[[sensor]]` (nothing inherited).
fn rewritten_with_channel(text: &str, wanted: &Radio) -> Result<String> {
    let mut v: toml::Table = toml::from_str(text).context("parsing the scenario")?;
    v.remove("radio");
    let sensors = v
        .get_mut("sensor")
        .and_then(toml::Value::as_array_mut)
        .context("the scenario has no [[sensor]]")?;
    for (i, s) in sensors.iter_mut().enumerate() {
        let t = s
            .as_table_mut()
            .with_context(|| format!("sensor[{i}] is not a table"))?;
        for k in ["loss", "retries", "burst"] {
            t.remove(k);
        }
        let link = wanted.link(i);
        if link == Link::IDEAL {
            continue;
        }
        t.insert("loss".into(), toml::Value::Float(link.loss));
        t.insert(
            "retries".into(),
            toml::Value::Integer(i64::from(link.retries)),
        );
        if let Some(b) = link.burst {
            t.insert("burst".into(), toml::Value::Float(b));
        }
    }
    if wanted.links.iter().any(|l| *l != Link::IDEAL) || wanted.estimator != Estimator::Aware {
        let mut radio = toml::Table::new();
        radio.insert(
            "estimator".into(),
            toml::Value::String(wanted.estimator.name().into()),
        );
        v.insert("radio".into(), toml::Value::Table(radio));
    }
    toml::to_string(&v).context("writing the scenario with the run's channel")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lossy(loss: f64, retries: u32, burst: Option<f64>, n: usize) -> Radio {
        Radio {
            estimator: Estimator::Aware,
            links: vec![
                Link {
                    loss,
                    retries,
                    burst
                };
                n
            ],
        }
    }

    #[test]
    fn a_channel_is_appended_to_a_text_without_one_comments_kept() {
        let text = builtin_text("winding-2d").expect("built-in");
        let n = Scenario::from_toml(text).expect("valid").sensors.len();
        let wanted = lossy(0.3, 1, Some(3.0), n);
        let out = text_with_channel(text, &wanted).expect("written");
        assert!(
            out.starts_with(text.trim_end()),
            "the text is kept as it was"
        );
        assert_eq!(Scenario::from_toml(&out).expect("valid").radio, wanted);
        // Its own channel: the text itself.
        assert_eq!(text_with_channel(&out, &wanted).expect("same"), out);
    }

    #[test]
    fn a_texts_own_channel_is_replaced_link_by_link_and_ideal_restores_the_hash() {
        let text = builtin_text("winding-2d").expect("built-in");
        let ideal = Scenario::from_toml(text).expect("valid");
        // A [radio] of its own and one sensor's override.
        let own = format!(
            "{}\n[radio]\nloss = 0.2\nestimator = \"naive\"\n",
            text.replacen("name = \"s1\"", "name = \"s1\"\nloss = 0.4\nretries = 2", 1)
        );
        let parsed = Scenario::from_toml(&own).expect("valid");
        assert_eq!(parsed.radio.link(1).retries, 2, "the override took");
        let mut wanted = lossy(0.1, 0, None, ideal.sensors.len());
        wanted.links[3] = Link {
            loss: 0.25,
            retries: 3,
            burst: Some(2.0),
        };
        let out = text_with_channel(&own, &wanted).expect("rewritten");
        assert_eq!(Scenario::from_toml(&out).expect("valid").radio, wanted);
        // The ideal channel written back: the scenario (and its hash) of the
        // text without a channel, so a strategy of it matches again.
        let back = text_with_channel(&own, &Radio::ideal(ideal.sensors.len())).expect("ideal");
        let back = Scenario::from_toml(&back).expect("valid");
        assert_eq!(back.radio, ideal.radio);
        assert_eq!(back.content_hash, ideal.content_hash);
        // No links at all means every link ideal.
        let none = Radio {
            estimator: Estimator::Aware,
            links: Vec::new(),
        };
        assert_eq!(
            Scenario::from_toml(&text_with_channel(&own, &none).expect("ideal"))
                .expect("valid")
                .content_hash,
            ideal.content_hash
        );
    }

    #[test]
    fn a_channel_for_another_number_of_sensors_is_refused() {
        let text = builtin_text("winding-2d").expect("built-in");
        let e = text_with_channel(text, &lossy(0.1, 0, None, 2)).expect_err("2 links");
        assert!(format!("{e:#}").contains("2 links"), "{e:#}");
    }
}
