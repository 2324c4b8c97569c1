//! The lossy, acknowledged radio of docs/MODEL.md §8.
//!
//! * [`Link`] — one sensor link's channel: attempt loss probability, retries
//!   within a step, optional Gilbert–Elliott burst length; its residual loss per
//!   trigger `q` and expected attempts per trigger.
//! * [`Radio`] — the scenario's radio: one resolved [`Link`] per sensor and the
//!   agent's [`Estimator`] (aware or naive silence update).
//! * [`beta_lossy`] — β_q(δ), the implicit information of "no packet received"
//!   when a trigger is lost with probability q.
//! * [`LinkChannel`] / [`EpisodeChannels`] — the channel state of every link
//!   during one episode, with its own random stream per (episode, link), and
//!   [`EpisodeChannels::transmit`], the fate of one trigger's attempts.
//! * [`schedule::ChannelSchedule`] — changes of links during a run, applied on
//!   the sensor side (experiments on a channel that drifts).
//!
//! An ideal link (`loss = 0`) draws nothing and delivers the first attempt, so
//! an ideal radio leaves every other random stream, and so every result, as it
//! was.

use crate::gaussian;
use crate::rng::{SimRng, link_rng, trigger_rng};
use rand::RngExt;
use serde::{Deserialize, Serialize};

pub mod schedule;

/// Most retries a link may be configured with (a link layer retrying more
/// often within one step is not a radio anyone builds).
pub const MAX_RETRIES: u32 = 1000;

/// The agent's reading of silence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// β_q(δ): silence may be a lost packet (docs/MODEL.md §8).
    #[default]
    Aware,
    /// β(δ): silence read as in §2, as if the radio were ideal.
    Naive,
}

impl Estimator {
    /// The name used in scenarios and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Aware => "aware",
            Self::Naive => "naive",
        }
    }

    /// Parse `aware` or `naive`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "aware" => Some(Self::Aware),
            "naive" => Some(Self::Naive),
            _ => None,
        }
    }
}

/// Why a channel setting was refused: the field (scenario path or option) and
/// the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("`{field}`: {reason}")]
pub struct RadioError {
    pub field: String,
    pub reason: String,
}

fn refuse(field: &str, reason: String) -> RadioError {
    RadioError {
        field: field.to_string(),
        reason,
    }
}

/// One sensor link's channel.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Link {
    /// Probability that one attempt is lost (in [0, 1)).
    pub loss: f64,
    /// Further attempts in the same step after a lost one.
    pub retries: u32,
    /// Gilbert–Elliott mean burst length in steps (≥ 1); `None`: independent losses.
    pub burst: Option<f64>,
}

/// Field names of a link's three settings, for errors.
#[derive(Debug, Clone, Copy)]
pub struct LinkFields<'a> {
    pub loss: &'a str,
    pub retries: &'a str,
    pub burst: &'a str,
}

impl Link {
    /// Every attempt arrives (docs/MODEL.md §2).
    pub const IDEAL: Self = Self {
        loss: 0.0,
        retries: 0,
        burst: None,
    };

    /// A checked link: `loss` in [0, 1), `retries` in 0..=[`MAX_RETRIES`],
    /// `burst` finite ≥ 1 with `loss ≤ B/(1 + B)` (else P(Good→Bad) > 1).
    /// Errors name the offending field from `fields`.
    pub fn checked(
        loss: f64,
        retries: i64,
        burst: Option<f64>,
        fields: LinkFields<'_>,
    ) -> Result<Self, RadioError> {
        if !(loss.is_finite() && (0.0..1.0).contains(&loss)) {
            return Err(refuse(
                fields.loss,
                format!("the probability that an attempt is lost must be in [0, 1), got {loss}"),
            ));
        }
        let retries = u32::try_from(retries)
            .ok()
            .filter(|&r| r <= MAX_RETRIES)
            .ok_or_else(|| {
                refuse(
                    fields.retries,
                    format!("must be a whole number between 0 and {MAX_RETRIES}, got {retries}"),
                )
            })?;
        if let Some(b) = burst {
            if !(b.is_finite() && b >= 1.0) {
                return Err(refuse(
                    fields.burst,
                    format!("the mean burst length must be a finite number of steps >= 1, got {b}"),
                ));
            }
            if loss > b / (1.0 + b) {
                return Err(refuse(
                    fields.burst,
                    format!(
                        "a burst of {b} steps allows loss <= B/(1+B) = {:.6} (else P(Good->Bad) > 1), \
                         but loss = {loss}",
                        b / (1.0 + b)
                    ),
                ));
            }
        }
        Ok(Self {
            loss,
            retries,
            burst,
        })
    }

    /// `loss = 0`: every attempt arrives, nothing is drawn.
    #[inline(always)]
    pub fn is_ideal(&self) -> bool {
        self.loss == 0.0
    }

    /// The residual loss per trigger q: independent losses `loss^(1 + retries)`;
    /// Gilbert–Elliott `loss` (in Bad every attempt of the step is lost).
    pub fn residual_loss(&self) -> f64 {
        match self.burst {
            Some(_) => self.loss,
            None => (0..=self.retries).fold(1.0, |q, _| q * self.loss),
        }
    }

    /// Expected attempts per trigger: independent losses `Σ_{j=0..r} loss^j`;
    /// Gilbert–Elliott (stationary) `1 + loss · r` (Good: one, Bad: all 1 + r).
    pub fn expected_attempts(&self) -> f64 {
        match self.burst {
            Some(_) => 1.0 + self.loss * f64::from(self.retries),
            None => {
                let (mut sum, mut term) = (0.0, 1.0);
                for _ in 0..=self.retries {
                    sum += term;
                    term *= self.loss;
                }
                sum
            }
        }
    }

    /// Gilbert–Elliott transition probabilities `(P(Bad→Good), P(Good→Bad))`
    /// = `(1/B, loss/(B(1 − loss)))`, so that P(Bad) = loss and bursts last B
    /// steps on average.
    pub fn transitions(&self) -> Option<(f64, f64)> {
        self.burst
            .map(|b| (1.0 / b, self.loss / (b * (1.0 - self.loss))))
    }
}

/// β_q(δ) = 1 − c with `c = [a v + q(1 − a v)] / [a + q(1 − a)]`,
/// `a = (2Φ(δ) − 1)^m`, `v = 1 − β(δ)`: the implicit information of "no packet
/// received" when a trigger's packet is lost with probability q (c is the
/// per-axis second moment of ε given no packet, docs/MODEL.md §8).
///
/// `q = 0` returns β(δ) itself (the quotient is not bit-exact), `q = 1` returns
/// exactly 0 (silence says nothing), and at δ = 0 with q > 0 it is 0 as well
/// (every step triggers, so silence is always a loss).
pub fn beta_lossy(delta: f64, m: usize, q: f64) -> f64 {
    if q == 0.0 {
        return gaussian::beta(delta);
    }
    if q >= 1.0 {
        return 0.0;
    }
    let a = gaussian::prob_within(delta).powi(m as i32);
    if a == 0.0 {
        return 0.0;
    }
    let av = a * (1.0 - gaussian::beta(delta));
    let c = (av + q * (1.0 - av)) / (a + q * (1.0 - a));
    (1.0 - c).max(0.0)
}

/// The scenario's radio: one link per sensor (index = sensor index) and the
/// agent's estimator.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Radio {
    pub estimator: Estimator,
    /// Per sensor; empty = every link ideal.
    pub links: Vec<Link>,
}

/// Command-line settings that replace the scenario's for every link
/// (`--loss`, `--retries`, `--burst`, `--estimator`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RadioOverride {
    pub loss: Option<f64>,
    pub retries: Option<i64>,
    pub burst: Option<f64>,
    pub estimator: Option<Estimator>,
}

impl RadioOverride {
    /// No setting given.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

impl Radio {
    /// Every link ideal, aware estimator (which then equals the naive one).
    pub fn ideal(num_sensors: usize) -> Self {
        Self {
            estimator: Estimator::Aware,
            links: vec![Link::IDEAL; num_sensors],
        }
    }

    /// Sensor `s`'s link (ideal if none is configured).
    #[inline(always)]
    pub fn link(&self, sensor: usize) -> Link {
        self.links.get(sensor).copied().unwrap_or(Link::IDEAL)
    }

    /// Every link ideal: the model of §2–§7 exactly.
    pub fn is_ideal(&self) -> bool {
        self.links.iter().all(Link::is_ideal)
    }

    /// The silence update's factor for sensor `s` at threshold δ (measurement
    /// dimension m): β_q(δ) for the aware estimator, β(δ) for the naive one
    /// (and for an ideal link, where the two agree bit for bit).
    pub fn silence_beta(&self, sensor: usize, delta: f64, m: usize) -> f64 {
        match self.estimator {
            Estimator::Naive => gaussian::beta(delta),
            Estimator::Aware => beta_lossy(delta, m, self.link(sensor).residual_loss()),
        }
    }

    /// THE channel of a use of a scenario (docs/MODEL.md §8.6), the one
    /// override rule of every command: `self` is the scenario text's own
    /// channel (`[radio]`, a sensor's own link fields winning); the channel
    /// a front or strategy file records (`recorded`: the one it was
    /// synthesized for, present only when radio options changed the text's
    /// own) replaces it whole; then each radio option given replaces that
    /// setting on every link ([`Self::overridden`]). A recorded channel
    /// without links is the ideal one; one with another number of links
    /// than `self` is refused.
    pub fn for_use(
        &self,
        recorded: Option<&Radio>,
        options: &RadioOverride,
    ) -> Result<Self, RadioError> {
        let base = match recorded {
            None => self.clone(),
            Some(r) if r.links.is_empty() => Self {
                estimator: r.estimator,
                links: vec![Link::IDEAL; self.links.len()],
            },
            Some(r) if r.links.len() != self.links.len() => {
                return Err(refuse(
                    "radio",
                    format!(
                        "the recorded channel has {} links for the scenario's {} sensors",
                        r.links.len(),
                        self.links.len()
                    ),
                ));
            }
            Some(r) => r.clone(),
        };
        if options.is_empty() {
            Ok(base)
        } else {
            base.overridden(options)
        }
    }

    /// Apply command-line settings to every link (each given value replaces
    /// the scenario's, including per-sensor ones); checked like the scenario,
    /// errors naming the option.
    pub fn overridden(&self, o: &RadioOverride) -> Result<Self, RadioError> {
        let fields = LinkFields {
            loss: "--loss",
            retries: "--retries",
            burst: "--burst",
        };
        let links = self
            .links
            .iter()
            .map(|l| {
                Link::checked(
                    o.loss.unwrap_or(l.loss),
                    o.retries.unwrap_or(i64::from(l.retries)),
                    o.burst.or(l.burst),
                    fields,
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        // Retries and bursts act on lost attempts only: on a channel that
        // loses none they would change nothing but the run's labels (and,
        // under `etp run`, where its prediction comes from).
        if links.iter().all(|l| l.loss == 0.0) {
            for (given, field) in [
                (o.retries.map(|r| r.to_string()), fields.retries),
                (o.burst.map(|b| b.to_string()), fields.burst),
            ] {
                if let Some(v) = given {
                    return Err(refuse(
                        field,
                        format!(
                            "{field} {v} does nothing: no link loses an attempt (loss 0); \
                             give --loss P (> 0) with it"
                        ),
                    ));
                }
            }
        }
        Ok(Self {
            estimator: o.estimator.unwrap_or(self.estimator),
            links,
        })
    }

    /// One line for reports: `ideal` or `loss 0.3, retries 1, burst 4, aware`
    /// (per sensor when links differ).
    pub fn describe(&self, sensor_names: &[String]) -> String {
        if self.is_ideal() {
            return "ideal".to_string();
        }
        let one = |l: &Link| {
            let mut s = format!("loss {}, retries {}", l.loss, l.retries);
            if let Some(b) = l.burst {
                s.push_str(&format!(", burst {b}"));
            }
            s
        };
        let first = self.link(0);
        let links = if self.links.iter().all(|l| *l == first) {
            one(&first)
        } else {
            self.links
                .iter()
                .zip(sensor_names)
                .map(|(l, n)| format!("{n}: {}", one(l)))
                .collect::<Vec<_>>()
                .join("; ")
        };
        format!("{links}; {} estimator", self.estimator.name())
    }
}

/// What one trigger's attempts achieved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Transmission {
    /// Attempts made (each costs c_m): `delivered as u32 + lost`.
    pub attempts: u32,
    /// Whether one attempt arrived (then it was the last one).
    pub delivered: bool,
}

impl Transmission {
    /// Attempts that were lost.
    pub fn lost(&self) -> u32 {
        self.attempts - u32::from(self.delivered)
    }
}

/// One link's channel during an episode: its state and its own random stream.
///
/// The Gilbert–Elliott state is advanced lazily: [`Self::advance_to`] catches
/// up the per-step transitions (one draw each, in step order) when the link is
/// next used, which gives exactly the states of advancing every link at the
/// start of every step, since no other draw shares the stream.
#[derive(Debug, Clone)]
pub struct LinkChannel {
    link: Link,
    /// `(P(Bad→Good), P(Good→Bad))` under bursts.
    transitions: Option<(f64, f64)>,
    bad: bool,
    /// Steps the state has been advanced through.
    step: u64,
    rng: SimRng,
}

impl LinkChannel {
    /// The channel at episode start; under bursts the state is drawn from
    /// the stationary law (P(Bad) = loss). An ideal link draws nothing.
    pub fn new(link: Link, mut rng: SimRng) -> Self {
        let transitions = if link.is_ideal() {
            None
        } else {
            link.transitions()
        };
        let bad = transitions.is_some() && rng.random::<f64>() < link.loss;
        Self {
            link,
            transitions,
            bad,
            step: 0,
            rng,
        }
    }

    /// Sensor `sensor`'s channel in episode `episode` of stream `stream`
    /// under `seed`: its link of `radio`, drawing from its own stream
    /// `link_rng(seed, stream, episode, sensor)` (docs/MODEL.md §8.2). THE
    /// seeding rule of a link: the in-process episodes
    /// ([`EpisodeChannels::new`]), the sensor process and `replay verify`
    /// (both with stream `AGENT`) all take their channel from here.
    pub fn of_episode(radio: &Radio, seed: u64, stream: u64, episode: u64, sensor: usize) -> Self {
        Self::of_link(radio.link(sensor), seed, stream, episode, sensor)
    }

    /// [`Self::of_episode`] on `link` instead of the radio's: a scheduled
    /// change ([`schedule::ChannelSchedule::link`]) draws from the same
    /// stream.
    pub fn of_link(link: Link, seed: u64, stream: u64, episode: u64, sensor: usize) -> Self {
        Self::new(link, link_rng(seed, stream, episode, sensor as u64))
    }

    /// Advance the Gilbert–Elliott state through step `step` (no-op for
    /// independent losses, or if already there).
    #[inline]
    pub fn advance_to(&mut self, step: u64) {
        let Some((to_good, to_bad)) = self.transitions else {
            self.step = step;
            return;
        };
        while self.step < step {
            let u: f64 = self.rng.random();
            self.bad = if self.bad { u >= to_good } else { u < to_bad };
            self.step += 1;
        }
    }

    /// In the Bad state (always false without bursts).
    pub fn is_bad(&self) -> bool {
        self.bad
    }

    /// The attempts of one trigger at the current state: independent losses
    /// draw each attempt's fate (lost with probability `loss`) until one
    /// arrives or `1 + retries` were made; under bursts Bad loses all
    /// `1 + retries`, Good delivers the first.
    #[inline]
    pub fn transmit(&mut self) -> Transmission {
        if self.link.is_ideal() {
            return Transmission {
                attempts: 1,
                delivered: true,
            };
        }
        let most = 1 + self.link.retries;
        if self.transitions.is_some() {
            return if self.bad {
                Transmission {
                    attempts: most,
                    delivered: false,
                }
            } else {
                Transmission {
                    attempts: 1,
                    delivered: true,
                }
            };
        }
        for attempts in 1..=most {
            if self.rng.random::<f64>() >= self.link.loss {
                return Transmission {
                    attempts,
                    delivered: true,
                };
            }
        }
        Transmission {
            attempts: most,
            delivered: false,
        }
    }
}

/// Every link's channel during one episode, and the episode's step count.
#[derive(Debug, Clone)]
pub struct EpisodeChannels {
    links: Vec<LinkChannel>,
    step: u64,
    ideal: bool,
    /// The stochastic trigger's draws, one generator per sensor
    /// ([`crate::rng::trigger_rng`]); empty for the families that draw nothing.
    trigger: Vec<SimRng>,
}

impl EpisodeChannels {
    /// The channels of episode `index` of stream `stream` under `seed`: link s
    /// is [`LinkChannel::of_episode`].
    pub fn new(radio: &Radio, seed: u64, stream: u64, index: u64) -> Self {
        Self {
            links: (0..radio.links.len())
                .map(|s| LinkChannel::of_episode(radio, seed, stream, index, s))
                .collect(),
            step: 0,
            ideal: radio.is_ideal(),
            trigger: Vec::new(),
        }
    }

    /// Ideal channels (every attempt arrives; nothing drawn).
    pub fn ideal() -> Self {
        Self {
            links: Vec::new(),
            step: 0,
            ideal: true,
            trigger: Vec::new(),
        }
    }

    /// These channels with the trigger draws of episode `index` of stream
    /// `stream` under `seed` for `sensors` sensors (docs/MODEL.md §9).
    pub fn with_trigger_draws(
        mut self,
        seed: u64,
        stream: u64,
        index: u64,
        sensors: usize,
    ) -> Self {
        self.trigger = (0..sensors as u64)
            .map(|s| trigger_rng(seed, stream, index, s))
            .collect();
        self
    }

    /// Sensor `sensor`'s next trigger draw, uniform on [0, 1); `None` when
    /// these channels carry no draws.
    #[inline]
    pub fn trigger_uniform(&mut self, sensor: usize) -> Option<f64> {
        self.trigger.get_mut(sensor).map(|r| r.random::<f64>())
    }

    /// Every link ideal.
    #[inline(always)]
    pub fn is_ideal(&self) -> bool {
        self.ideal
    }

    /// The start of a step (before its measurement): every link's channel
    /// state advances once.
    #[inline(always)]
    pub fn start_step(&mut self) {
        self.step += 1;
    }

    /// Sensor `s` triggered in the current step: its attempts' fate.
    #[inline]
    pub fn transmit(&mut self, sensor: usize) -> Transmission {
        match self.links.get_mut(sensor) {
            Some(l) => {
                l.advance_to(self.step);
                l.transmit()
            }
            None => Transmission {
                attempts: 1,
                delivered: true,
            },
        }
    }

    /// Sensor `s`'s channel, advanced to the current step.
    pub fn link_mut(&mut self, sensor: usize) -> Option<&mut LinkChannel> {
        let step = self.step;
        let link = self.links.get_mut(sensor)?;
        link.advance_to(step);
        Some(link)
    }
}

#[cfg(test)]
mod tests;
