//! A channel schedule: changes of sensors' links during a run, for
//! experiments on a channel that drifts (docs/MODEL.md §8.8).
//!
//! The schedule is the physical channel's, applied where the radio is, on
//! the sensor side: from episode `episode` on, sensor `sensor`'s attempts
//! meet the changed link. The agent's estimator and the prediction keep the
//! channel the strategy was synthesized for, as in the field a drift is not
//! announced. An episode before the first change draws exactly what it draws
//! without a schedule (the link's own stream is the same).
//!
//! ```toml
//! [[change]]
//! sensor = "s6"
//! episode = 50
//! loss = 0.3      # and the other [radio] keys: retries, burst
//! ```
//!
//! A key a change leaves out keeps the value in force before it; a change is
//! checked like a scenario's link, errors naming `change[i].<key>`.

use super::{Link, LinkFields, Radio, RadioError, refuse};
use serde::{Deserialize, Serialize};

/// One change: from `episode` on, `sensor`'s link is `link`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ChannelChange {
    pub sensor: usize,
    pub episode: u64,
    pub link: Link,
}

/// The changes of a run, ordered by episode (a file's order among changes of
/// the same episode and sensor: the later wins).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ChannelSchedule {
    pub changes: Vec<ChannelChange>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSchedule {
    #[serde(default)]
    change: Vec<RawChange>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawChange {
    sensor: String,
    episode: i64,
    loss: Option<f64>,
    retries: Option<i64>,
    burst: Option<f64>,
}

impl ChannelSchedule {
    /// Read a schedule file's text for a run whose channel is `radio` and
    /// whose sensors are `names`. `source` names the file in errors.
    pub fn parse(
        text: &str,
        source: &str,
        radio: &Radio,
        names: &[String],
    ) -> Result<Self, RadioError> {
        let raw: RawSchedule = toml::from_str(text)
            .map_err(|e| refuse(source, e.to_string().lines().collect::<Vec<_>>().join(" ")))?;
        let mut order: Vec<(usize, RawChange)> = raw.change.into_iter().enumerate().collect();
        // Stable: the file's order within an episode.
        order.sort_by_key(|(_, c)| c.episode);
        let mut schedule = Self::default();
        for (i, c) in order {
            let field = |key: &str| format!("{source}: change[{i}].{key}");
            let sensor = names.iter().position(|n| *n == c.sensor).ok_or_else(|| {
                refuse(
                    &field("sensor"),
                    format!(
                        "no sensor `{}` in the scenario (sensors: {})",
                        c.sensor,
                        names.join(", ")
                    ),
                )
            })?;
            let episode = u64::try_from(c.episode).map_err(|_| {
                refuse(
                    &field("episode"),
                    format!("must be a whole number >= 0, got {}", c.episode),
                )
            })?;
            let before = schedule.link(radio, sensor, episode);
            let (loss, retries, burst) = (field("loss"), field("retries"), field("burst"));
            let link = Link::checked(
                c.loss.unwrap_or(before.loss),
                c.retries.unwrap_or(i64::from(before.retries)),
                c.burst.or(before.burst),
                LinkFields {
                    loss: &loss,
                    retries: &retries,
                    burst: &burst,
                },
            )?;
            schedule.changes.push(ChannelChange {
                sensor,
                episode,
                link,
            });
        }
        Ok(schedule)
    }

    pub fn is_empty(&self) -> bool {
        self.changes.is_empty()
    }

    /// Sensor `sensor`'s link in episode `episode`: the last change of that
    /// sensor at or before it, else the run's channel.
    pub fn link(&self, radio: &Radio, sensor: usize, episode: u64) -> Link {
        self.changes
            .iter()
            .rev()
            .find(|c| c.sensor == sensor && c.episode <= episode)
            .map_or_else(|| radio.link(sensor), |c| c.link)
    }

    /// The schedule as a file (every key of every change written out), as a
    /// recording keeps it; [`Self::parse`] of it gives the schedule back.
    pub fn to_toml(&self, names: &[String]) -> String {
        let mut out = String::new();
        for c in &self.changes {
            let name = names
                .get(c.sensor)
                .cloned()
                .unwrap_or_else(|| format!("#{}", c.sensor));
            out.push_str(&format!(
                "[[change]]\nsensor = {}\nepisode = {}\nloss = {:?}\nretries = {}\n",
                toml_string(&name),
                c.episode,
                c.link.loss,
                c.link.retries
            ));
            if let Some(b) = c.link.burst {
                out.push_str(&format!("burst = {b:?}\n"));
            }
            out.push('\n');
        }
        out
    }

    /// One line for reports: `s6 from episode 50: loss 0.3, retries 0`.
    pub fn describe(&self, names: &[String]) -> String {
        self.changes
            .iter()
            .map(|c| {
                let mut s = format!(
                    "{} from episode {}: loss {}, retries {}",
                    names.get(c.sensor).map_or("?", String::as_str),
                    c.episode,
                    c.link.loss,
                    c.link.retries
                );
                if let Some(b) = c.link.burst {
                    s.push_str(&format!(", burst {b}"));
                }
                s
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// A TOML basic string.
fn toml_string(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names() -> Vec<String> {
        (0..3).map(|i| format!("s{i}")).collect()
    }

    fn radio() -> Radio {
        let mut r = Radio::ideal(3);
        r.links = vec![
            Link::IDEAL,
            Link {
                loss: 0.1,
                retries: 2,
                burst: None,
            },
            Link::IDEAL,
        ];
        r
    }

    #[test]
    fn a_change_holds_from_its_episode_and_keeps_what_it_leaves_out() {
        let text = "[[change]]\nsensor = \"s1\"\nepisode = 50\nloss = 0.3\n\n\
                    [[change]]\nsensor = \"s1\"\nepisode = 10\nretries = 0\n";
        let s = ChannelSchedule::parse(text, "f.toml", &radio(), &names()).expect("parses");
        let l = |e| s.link(&radio(), 1, e);
        assert_eq!(l(9), radio().link(1));
        assert_eq!(
            l(10),
            Link {
                loss: 0.1,
                retries: 0,
                burst: None
            }
        );
        // Episode 50's change came first in the file, but keeps episode 10's retries.
        assert_eq!(
            l(50),
            Link {
                loss: 0.3,
                retries: 0,
                burst: None
            }
        );
        assert_eq!(s.link(&radio(), 0, 99), Link::IDEAL);
        let again =
            ChannelSchedule::parse(&s.to_toml(&names()), "f", &radio(), &names()).expect("again");
        assert_eq!(again, s);
        assert_eq!(
            s.describe(&names()),
            "s1 from episode 10: loss 0.1, retries 0; s1 from episode 50: loss 0.3, retries 0"
        );
    }

    #[test]
    fn a_bad_change_is_refused_naming_its_key() {
        let bad = |text: &str| {
            ChannelSchedule::parse(text, "f.toml", &radio(), &names())
                .expect_err(text)
                .to_string()
        };
        let e = bad("[[change]]\nsensor = \"s9\"\nepisode = 1\nloss = 0.3\n");
        assert!(e.contains("change[0].sensor") && e.contains("s9"), "{e}");
        let e = bad("[[change]]\nsensor = \"s0\"\nepisode = -1\n");
        assert!(e.contains("change[0].episode"), "{e}");
        let e = bad("[[change]]\nsensor = \"s0\"\nepisode = 1\nloss = 1.5\n");
        assert!(e.contains("change[0].loss"), "{e}");
        let e = bad("[[change]]\nsensor = \"s0\"\nepisode = 1\nloss = 0.6\nburst = 1.0\n");
        assert!(e.contains("change[0].burst"), "{e}");
        let e = bad("[[change]]\nsensor = \"s0\"\nepisode = 1\nlos = 0.3\n");
        assert!(e.contains("f.toml") && e.contains("los"), "{e}");
    }
}
