//! The scenario format's one writer, beside its parser: a scenario text
//! made to carry a given channel (docs/MODEL.md §8.6).
//!
//! A run's processes, its sensor hosts and its recording all read the
//! channel from the run's copy of the scenario text, so a channel that is
//! not the text's own (a strategy synthesized under radio options, a
//! robustness study) is written into that text here, with the keys of
//! [`super::raw::keys`] — the ones the parser reads.

use super::raw::keys;
use super::{Scenario, ScenarioError};
use crate::radio::{Estimator, Link, Radio};
use crate::trigger::TriggerFamily;

type Result<T> = std::result::Result<T, ScenarioError>;

/// A scenario's TOML text and the scenario it parses to, parsed once.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioText {
    pub text: String,
    pub scenario: Scenario,
}

impl ScenarioText {
    /// Parse and validate `text` ([`Scenario::from_toml`]).
    pub fn parse(text: String) -> Result<Self> {
        let scenario = Scenario::from_toml(&text)?;
        Ok(Self { text, scenario })
    }

    /// Whether the text sets a channel of its own: a `[radio]` table or a
    /// sensor's own `loss`, `retries` or `burst`.
    pub fn sets_a_channel(&self) -> Result<bool> {
        Ok(sets_a_channel(&table(&self.text)?))
    }

    /// This text carrying exactly the channel `wanted` (no links: every
    /// link ideal). The text itself when it already carries `wanted`; a
    /// `[radio]` table appended (the text, comments and all, kept) when the
    /// text sets no channel and every link is the same; else the text
    /// rewritten through TOML with its channel replaced, one link per sensor
    /// (nothing inherited from `[radio]` but the estimator). The result is
    /// parsed again and must give exactly `wanted`.
    pub fn with_channel(self, wanted: &Radio) -> Result<Self> {
        let sensors = self.scenario.sensors.len();
        let wanted = &if wanted.links.is_empty() {
            Radio {
                estimator: wanted.estimator,
                links: vec![Link::IDEAL; sensors],
            }
        } else {
            wanted.clone()
        };
        if self.scenario.radio == *wanted {
            return Ok(self);
        }
        if wanted.links.len() != sensors {
            return Err(ScenarioError::invalid(
                keys::RADIO,
                format!(
                    "the channel has {} links for the {sensors} sensors of scenario `{}`",
                    wanted.links.len(),
                    self.scenario.name
                ),
            ));
        }
        let mut v = table(&self.text)?;
        let first = wanted.link(0);
        let uniform = wanted.links.iter().all(|l| *l == first);
        let text = if uniform && !sets_a_channel(&v) {
            format!(
                "{}\n\n{}",
                self.text.trim_end(),
                radio_table(&first, wanted.estimator)
            )
        } else {
            replace_channel(&mut v, wanted);
            toml::to_string(&v).map_err(|e| {
                ScenarioError::invalid(keys::RADIO, format!("writing the channel: {e}"))
            })?
        };
        let written = Self::parse(text)?;
        if written.scenario.radio != *wanted {
            return Err(ScenarioError::invalid(
                keys::RADIO,
                format!(
                    "the channel could not be written into scenario `{}`'s text exactly",
                    self.scenario.name
                ),
            ));
        }
        Ok(written)
    }
}

impl ScenarioText {
    /// This text with trigger family `family` (`--trigger`): the text itself
    /// when it already says so, else rewritten through TOML with
    /// `[triggering] family` set (removed for `box`, the default, so a box
    /// scenario keeps its text's hash). Parsed again and checked.
    pub fn with_trigger(self, family: TriggerFamily) -> Result<Self> {
        if self.scenario.trigger == family {
            return Ok(self);
        }
        let mut v = table(&self.text)?;
        let Some(triggering) = v
            .get_mut(keys::TRIGGERING)
            .and_then(toml::Value::as_table_mut)
        else {
            return Err(ScenarioError::invalid(
                keys::TRIGGERING,
                "the scenario text has no [triggering] table",
            ));
        };
        if family == TriggerFamily::Box {
            triggering.remove(keys::FAMILY);
        } else {
            triggering.insert(
                keys::FAMILY.into(),
                toml::Value::String(family.name().into()),
            );
        }
        let text = toml::to_string(&v).map_err(|e| {
            ScenarioError::invalid(keys::TRIGGERING, format!("writing the family: {e}"))
        })?;
        let written = Self::parse(text)?;
        if written.scenario.trigger != family {
            return Err(ScenarioError::invalid(
                "triggering.family",
                format!(
                    "the family could not be written into scenario `{}`'s text",
                    self.scenario.name
                ),
            ));
        }
        Ok(written)
    }
}

/// The text as a TOML table.
fn table(text: &str) -> Result<toml::Table> {
    toml::from_str(text).map_err(|e| ScenarioError::Parse(e.to_string()))
}

fn sets_a_channel(v: &toml::Table) -> bool {
    let per_sensor = v
        .get(keys::SENSOR)
        .and_then(toml::Value::as_array)
        .is_some_and(|a| {
            a.iter()
                .filter_map(toml::Value::as_table)
                .any(|t| keys::LINK.iter().any(|k| t.contains_key(*k)))
        });
    v.contains_key(keys::RADIO) || per_sensor
}

/// `[radio]` for one link setting shared by every sensor (its numbers as
/// Rust writes them: `{:?}` of a float is the shortest text that reads back
/// the same bits).
fn radio_table(link: &Link, estimator: Estimator) -> String {
    let mut table = format!(
        "[{}]\n{} = {:?}\n{} = {}\n{} = \"{}\"\n",
        keys::RADIO,
        keys::LOSS,
        link.loss,
        keys::RETRIES,
        link.retries,
        keys::ESTIMATOR,
        estimator.name()
    );
    if let Some(b) = link.burst {
        table.push_str(&format!("{} = {b:?}\n", keys::BURST));
    }
    table
}

/// `v`'s `[radio]` and per-sensor link fields replaced by `wanted`: the
/// estimator in `[radio]` (absent when it would say nothing), each sensor's
/// full link in its own `[[sensor]]` (absent for an ideal link).
fn replace_channel(v: &mut toml::Table, wanted: &Radio) {
    v.remove(keys::RADIO);
    let sensors = v
        .get_mut(keys::SENSOR)
        .and_then(toml::Value::as_array_mut)
        .into_iter()
        .flatten()
        .filter_map(toml::Value::as_table_mut);
    for (i, t) in sensors.enumerate() {
        for k in keys::LINK {
            t.remove(k);
        }
        let link = wanted.link(i);
        if link == Link::IDEAL {
            continue;
        }
        t.insert(keys::LOSS.into(), toml::Value::Float(link.loss));
        t.insert(
            keys::RETRIES.into(),
            toml::Value::Integer(i64::from(link.retries)),
        );
        if let Some(b) = link.burst {
            t.insert(keys::BURST.into(), toml::Value::Float(b));
        }
    }
    if wanted.links.iter().any(|l| *l != Link::IDEAL) || wanted.estimator != Estimator::Aware {
        let mut radio = toml::Table::new();
        radio.insert(
            keys::ESTIMATOR.into(),
            toml::Value::String(wanted.estimator.name().into()),
        );
        v.insert(keys::RADIO.into(), toml::Value::Table(radio));
    }
}

#[cfg(test)]
mod tests;
