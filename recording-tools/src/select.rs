//! Which messages of a recording `etp replay` works on (like `ros2 bag play
//! --topics` and `mcap cat --start/--end`): `--topics`, `--episodes A..B`,
//! `--start`/`--end` (seconds from the first message). The selection applies
//! to the summary, `--export`, `--cat`, `--info` and `--publish`.

use crate::error::{Context, Error, Result};
use etp_runtime::recording::{self, Contents};

/// `--episodes`: a range of `header.episode` (0-based): `A..B` (B excluded),
/// `A..=B`, `A..`, `..B`, or one episode `N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Episodes {
    pub first: u64,
    /// Excluded; `None` = no end.
    pub end: Option<u64>,
}

impl Episodes {
    pub fn contains(&self, e: u64) -> bool {
        e >= self.first && self.end.is_none_or(|end| e < end)
    }
}

/// Parse `--episodes`.
pub fn parse_episodes(s: &str) -> Result<Episodes, String> {
    let num = |t: &str| -> Result<u64, String> {
        t.trim().parse::<u64>().map_err(|_| {
            format!("`{t}` is not an episode number (expected A..B, A..=B, A.., ..B or N)")
        })
    };
    let r = if let Some((a, b)) = s.split_once("..=") {
        let first = if a.is_empty() { 0 } else { num(a)? };
        Episodes {
            first,
            end: Some(num(b)?.saturating_add(1)),
        }
    } else if let Some((a, b)) = s.split_once("..") {
        Episodes {
            first: if a.is_empty() { 0 } else { num(a)? },
            end: if b.is_empty() { None } else { Some(num(b)?) },
        }
    } else {
        let n = num(s)?;
        Episodes {
            first: n,
            end: Some(n.saturating_add(1)),
        }
    };
    if r.end.is_some_and(|e| e <= r.first) {
        return Err(format!("the episode range `{s}` is empty"));
    }
    Ok(r)
}

/// `--start` / `--end`: seconds (≥ 0) from the recording's first message.
pub fn parse_offset(s: &str) -> Result<f64, String> {
    let t = s.strip_suffix('s').unwrap_or(s);
    let x: f64 = t
        .parse()
        .map_err(|_| format!("`{s}` is not a number of seconds"))?;
    if !x.is_finite() || x < 0.0 {
        return Err(format!("an offset must be ≥ 0 seconds (got {s})"));
    }
    Ok(x)
}

/// The selection flags.
#[derive(Debug, Clone, Default)]
pub struct Selection {
    /// Topics (`outcome`, `sensor/0/truth`); `*` matches any text (`sensor/*/handover`).
    pub topics: Vec<String>,
    /// Topics (patterns as `topics`) left out, after `topics`.
    pub exclude_topics: Vec<String>,
    pub episodes: Option<Episodes>,
    pub start: Option<f64>,
    pub end: Option<f64>,
}

/// Does `topic` match `pattern` (`*` = any run of characters)?
pub fn glob(pattern: &str, topic: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == topic,
        Some((head, tail)) => {
            let Some(rest) = topic.strip_prefix(head) else {
                return false;
            };
            (0..=rest.len())
                .filter(|&i| rest.is_char_boundary(i))
                .any(|i| glob(tail, &rest[i..]))
        }
    }
}

impl Selection {
    /// True when nothing is filtered.
    pub fn is_all(&self) -> bool {
        self.topics.is_empty()
            && self.exclude_topics.is_empty()
            && self.episodes.is_none()
            && self.start.is_none()
            && self.end.is_none()
    }

    /// Keep only the selected messages (and channels) of `c`. A topic pattern
    /// that matches no channel is an error (a typo would otherwise select
    /// nothing silently).
    pub fn apply(&self, c: &mut Contents) -> Result<()> {
        self.prepare(c)?;
        let t0 = c.messages.iter().map(|m| m.log_time).min().unwrap_or(0);
        let mut kept = Vec::with_capacity(c.messages.len());
        for m in std::mem::take(&mut c.messages) {
            if self.keeps(c, t0, &m)? {
                kept.push(m);
            }
        }
        c.messages = kept;
        Ok(())
    }

    /// Check the selection against `c`'s channels and keep the selected
    /// channels only.
    pub fn prepare(&self, c: &mut Contents) -> Result<()> {
        if let (Some(s), Some(e)) = (self.start, self.end)
            && e <= s
        {
            return Err(Error::request(format!(
                "--end {e} s is not after --start {s} s"
            )));
        }
        for (option, patterns) in [
            ("--topics", &self.topics),
            ("--exclude-topics", &self.exclude_topics),
        ] {
            for p in patterns {
                if !c.channels.keys().any(|t| glob(p, t)) {
                    return Err(Error::request(format!(
                        "{option}: `{p}` matches no channel of the recording (channels: {})",
                        c.channels.keys().cloned().collect::<Vec<_>>().join(" ")
                    )));
                }
            }
        }
        if !self.topics.is_empty() {
            c.channels
                .retain(|t, _| self.topics.iter().any(|p| glob(p, t)));
        }
        c.channels
            .retain(|t, _| !self.exclude_topics.iter().any(|p| glob(p, t)));
        Ok(())
    }

    /// Is `m` selected (`c` prepared, `t0` the first message's log time)?
    pub fn keeps(&self, c: &Contents, t0: u64, m: &recording::RawMessage) -> Result<bool> {
        let ns = |s: f64| t0.saturating_add((s * 1e9).round() as u64);
        if !c.channels.contains_key(&m.topic)
            || self.start.is_some_and(|s| m.log_time < ns(s))
            || self.end.is_some_and(|e| m.log_time > ns(e))
        {
            return Ok(false);
        }
        match &self.episodes {
            Some(r) => {
                let rec = m
                    .decode()
                    .at_message(|| format!("message at log time {}", m.log_time))?;
                Ok(r.contains(rec.header().episode))
            }
            None => Ok(true),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn episode_ranges_parse_like_rust_ranges() {
        let r = parse_episodes("1..3").expect("range");
        assert!(!r.contains(0) && r.contains(1) && r.contains(2) && !r.contains(3));
        let r = parse_episodes("1..=3").expect("inclusive");
        assert!(r.contains(3) && !r.contains(4));
        let r = parse_episodes("2..").expect("open");
        assert!(!r.contains(1) && r.contains(1_000_000));
        let r = parse_episodes("..2").expect("to");
        assert!(r.contains(0) && !r.contains(2));
        let r = parse_episodes("5").expect("one");
        assert!(r.contains(5) && !r.contains(4) && !r.contains(6));
        assert!(parse_episodes("3..3").is_err());
        assert!(parse_episodes("a..b").expect_err("bad").contains("`a`"));
    }

    #[test]
    fn topic_patterns() {
        assert!(glob("outcome", "outcome"));
        assert!(!glob("outcome", "outcomes"));
        assert!(glob("sensor/*/prior", "sensor/12/prior"));
        assert!(!glob("sensor/*/prior", "sensor/1/truth"));
        assert!(glob("*", "anything"));
        assert_eq!(parse_offset("1.5s"), Ok(1.5));
        assert!(parse_offset("-1").is_err());
    }
}
