//! Channel drift: sequential tests, per sensor, of what a run already carries
//! against the channel and trigger the strategy was synthesized for
//! (docs/MODEL.md §11).
//!
//! * [`Cusum`] — Page's CUSUM of a log-likelihood ratio: `S_n = max(0,
//!   S_{n−1} + ℓ_n)`, an alarm when `S_n ≥ h`.
//! * [`Budget`] — the threshold `h` from a false-alarm probability per run:
//!   `h = ln(N K / α)` for `K` tests of at most `N` observations each. Why it
//!   holds, whatever the model's conditional law: under the model, for every
//!   start `k` the product of the ratios `f₁/f₀` from `k` on is a
//!   non-negative martingale of mean 1 (`f₀` the model's law of the next
//!   observation given the past, `f₁` any law fixed before it is seen), so by
//!   Ville's inequality it ever reaches `e^h` with probability at most
//!   `e^{−h}`; `S_n ≥ h` means some start's sum reached `h`; a union over the
//!   `N` starts and `K` tests gives `N K e^{−h} = α`. The bound is
//!   conservative: the measured rate is far below it (tests below).
//! * [`DeliveryTest`] — each trigger's attempts (how many, whether one
//!   arrived) against the link's model: independent losses (`loss` per
//!   attempt, `1 + retries` at most) or Gilbert–Elliott bursts (a hidden
//!   Good/Bad state per step; a trigger in Bad loses every attempt, in Good
//!   its first arrives), against links with more loss.
//! * [`TriggerTest`] — whether each served slot triggered, against the
//!   trigger family's closed-form rate at the slot's δ (box, stochastic): more
//!   or fewer triggers than the model, e.g. a sensor whose noise grew. Exact
//!   for the stochastic family; for box the rate formula assumes an exact
//!   filter (box sends 0.1–1 pt above it, docs/performance.md), which the
//!   alternatives' spacing leaves room for.
//!
//! * [`Monitor`] — every sensor's tests of a run under one budget, each
//!   (sensor, [`Quantity`]) [`Flag`] raised at most once; what the agent
//!   runs on its slots and `replay verify` runs again.
//!
//! An observation the model cannot produce (a lost attempt on an ideal link,
//! more attempts than the link allows) is infinite evidence: an alarm at
//! once. Everything here is pure: the caller feeds what the run carried.

use crate::radio::{Link, Transmission};

mod monitor;
pub use monitor::{Flag, Monitor, MonitorConfig, MonitorObserver, Quantity};

/// The alternatives each test runs a CUSUM against, as fractions of the
/// distance to certainty: a probability `p₀` of the bad event (a loss, a
/// trigger) is tested against `p₀ + f (1 − p₀)` (and, for triggers, against
/// `p₀ (1 − f)`). Three spacings cover small and large drifts; each is one
/// of the `K` tests of the [`Budget`].
pub const ALTERNATIVES: [f64; 3] = [0.125, 0.25, 0.5];

/// The monitor's false-alarm probability per run unless asked otherwise.
pub const DEFAULT_FALSE_ALARM: f64 = 0.01;

/// What a run does with a flag (`--on-drift`, run-file key `on_drift`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnDrift {
    /// Reported; the run goes on.
    #[default]
    Warn,
    /// Reported; the run ends after the flag's episode.
    Stop,
}

impl OnDrift {
    pub const ALL: [OnDrift; 2] = [Self::Warn, Self::Stop];

    /// `warn`, `stop` (the command line's, the run file's and the
    /// coordinator's word).
    pub fn name(self) -> &'static str {
        match self {
            Self::Warn => "warn",
            Self::Stop => "stop",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|o| o.name() == s)
    }
}

/// Page's CUSUM of a log-likelihood ratio.
#[derive(Debug, Clone, PartialEq)]
pub struct Cusum {
    /// `S_n`.
    statistic: f64,
    /// Observations since `S` last was 0: the change point's estimate.
    since_reset: u64,
    observations: u64,
}

impl Default for Cusum {
    fn default() -> Self {
        Self::new()
    }
}

impl Cusum {
    pub fn new() -> Self {
        Self {
            statistic: 0.0,
            since_reset: 0,
            observations: 0,
        }
    }

    /// Add one observation's log-likelihood ratio `ℓ` (`+∞` for an
    /// observation the model cannot produce); returns `S_n`.
    pub fn push(&mut self, llr: f64) -> f64 {
        self.observations += 1;
        let s = self.statistic + llr;
        if s > 0.0 {
            self.statistic = s;
            self.since_reset += 1;
        } else {
            self.statistic = 0.0;
            self.since_reset = 0;
        }
        self.statistic
    }

    pub fn statistic(&self) -> f64 {
        self.statistic
    }

    /// Observations since the statistic last left 0 (the estimated onset:
    /// the start whose sum `S_n` is).
    pub fn since_onset(&self) -> u64 {
        self.since_reset
    }

    pub fn observations(&self) -> u64 {
        self.observations
    }
}

/// A false-alarm probability per run shared by `tests` CUSUMs of at most
/// `horizon` observations each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    /// α: the probability, under the synthesized channel, that any test of
    /// the run alarms.
    pub false_alarm: f64,
    /// `N`: most observations one test sees in the run.
    pub horizon: u64,
    /// `K`: how many CUSUMs share α.
    pub tests: u64,
}

impl Budget {
    /// `h = ln(N K / α)` (at least 0).
    pub fn threshold(&self) -> f64 {
        let n = self.horizon.max(1) as f64 * self.tests.max(1) as f64;
        (n / self.false_alarm).ln().max(0.0)
    }
}

/// `ln(p₁/p₀)` for the probability of what happened under the alternative
/// and under the model: `+∞` where the model gives it no chance.
fn llr(p1: f64, p0: f64) -> f64 {
    if p0 <= 0.0 {
        f64::INFINITY
    } else if p1 <= 0.0 {
        f64::NEG_INFINITY
    } else {
        (p1 / p0).ln()
    }
}

/// Kullback–Leibler divergence of Bernoulli(`p1`) from Bernoulli(`p0`), in
/// nats: the mean of `ℓ` per observation under the alternative.
pub fn bernoulli_kl(p1: f64, p0: f64) -> f64 {
    let term = |a: f64, b: f64| if a <= 0.0 { 0.0 } else { a * llr(a, b) };
    term(p1, p0) + term(1.0 - p1, 1.0 - p0)
}

/// A link as a per-trigger law: the probability a trigger loses every
/// attempt, and of `attempts` under it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LinkLaw {
    link: Link,
    /// Gilbert–Elliott: `(P(Bad) stationary, λ = 1 − P(B→G) − P(G→B))`.
    bursts: Option<(f64, f64)>,
}

impl LinkLaw {
    fn new(link: Link) -> Self {
        let bursts = if link.is_ideal() {
            None
        } else {
            link.transitions()
                .map(|(to_good, to_bad)| (link.loss, 1.0 - to_good - to_bad))
        };
        Self { link, bursts }
    }

    /// P(Bad at a step `d` steps after one in state `bad`; `None`: nothing
    /// seen this episode, the stationary law).
    fn bad_after(&self, last: Option<(bool, u64)>, step: u64) -> f64 {
        let Some((pi, lambda)) = self.bursts else {
            return 0.0;
        };
        match last {
            None => pi,
            Some((bad, at)) => {
                let decay = lambda.powf(step.saturating_sub(at) as f64);
                if bad {
                    pi + (1.0 - pi) * decay
                } else {
                    pi * (1.0 - decay)
                }
            }
        }
    }

    /// The probability of `t` at `step` given the last state seen.
    fn probability(&self, t: Transmission, last: Option<(bool, u64)>, step: u64) -> f64 {
        let most = 1 + self.link.retries;
        if t.attempts == 0 || t.attempts > most || (!t.delivered && t.attempts != most) {
            return 0.0;
        }
        if self.link.is_ideal() {
            return if t.delivered && t.attempts == 1 {
                1.0
            } else {
                0.0
            };
        }
        if self.bursts.is_some() {
            let bad = self.bad_after(last, step);
            return match (t.delivered, t.attempts) {
                (true, 1) => 1.0 - bad,
                (false, _) => bad,
                (true, _) => 0.0,
            };
        }
        let q = self.link.loss;
        if t.delivered {
            q.powi(t.attempts as i32 - 1) * (1.0 - q)
        } else {
            q.powi(t.attempts as i32)
        }
    }
}

/// One test's alarm: which alternative, the statistic, the threshold and the
/// estimated onset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alarm {
    /// The alternative's probability of the bad event (a loss per attempt,
    /// a trigger per slot) at the alarm.
    pub alternative: f64,
    pub statistic: f64,
    pub threshold: f64,
    /// Observations from the estimated onset to the alarm.
    pub since_onset: u64,
    /// Observations of this test so far.
    pub observations: u64,
}

/// Each trigger's attempts against the link it was synthesized for; one
/// CUSUM per link with more loss ([`ALTERNATIVES`]).
#[derive(Debug, Clone)]
pub struct DeliveryTest {
    model: LinkLaw,
    alternatives: Vec<(LinkLaw, Cusum)>,
    threshold: f64,
    /// The Gilbert–Elliott state the last trigger of this episode revealed
    /// (Bad ⇔ it lost every attempt), and its step.
    last: Option<(bool, u64)>,
    /// Attempts and lost attempts since each alternative's onset (the
    /// estimate of the channel now): `(attempts, lost)` per alternative.
    since: Vec<(u64, u64)>,
}

impl DeliveryTest {
    /// `link`: the synthesized channel; `threshold` from the run's
    /// [`Budget`] (the test counts as `ALTERNATIVES.len()` of its `K`).
    pub fn new(link: Link, threshold: f64) -> Self {
        let alternatives = ALTERNATIVES
            .iter()
            .map(|f| {
                let loss = link.loss + f * (1.0 - link.loss);
                // Bursts keep their mean length; the alternative's loss must
                // still be reachable (P(Good→Bad) ≤ 1).
                let burst = link.burst.map(|b| b.max(loss / (1.0 - loss)));
                let alt = Link {
                    loss,
                    burst,
                    ..link
                };
                (LinkLaw::new(alt), Cusum::new())
            })
            .collect();
        Self {
            model: LinkLaw::new(link),
            alternatives,
            threshold,
            last: None,
            since: vec![(0, 0); ALTERNATIVES.len()],
        }
    }

    /// A new episode: the burst state is drawn afresh from the stationary law.
    pub fn start_episode(&mut self) {
        self.last = None;
    }

    /// One trigger at `step` of the episode; the first alternative whose
    /// CUSUM reaches the threshold, if any.
    pub fn observe(&mut self, step: u64, t: Transmission) -> Option<Alarm> {
        let p0 = self.model.probability(t, self.last, step);
        let mut alarm = None;
        for (i, (law, cusum)) in self.alternatives.iter_mut().enumerate() {
            let p1 = law.probability(t, self.last, step);
            let s = cusum.push(llr(p1, p0));
            let since = &mut self.since[i];
            if cusum.since_onset() == 0 {
                *since = (0, 0);
            } else {
                since.0 += u64::from(t.attempts);
                since.1 += u64::from(t.lost());
            }
            if s >= self.threshold && alarm.is_none() {
                alarm = Some(Alarm {
                    alternative: law.link.loss,
                    statistic: s,
                    threshold: self.threshold,
                    since_onset: cusum.since_onset(),
                    observations: cusum.observations(),
                });
            }
        }
        if self.model.bursts.is_some() {
            self.last = Some((!t.delivered, step));
        }
        alarm
    }

    /// The loss per attempt measured since the onset of the alternative
    /// that alarmed, `alternative` as [`Alarm::alternative`] (the channel's
    /// estimate for a switch): lost / attempts.
    pub fn loss_since_onset(&self, alternative: f64) -> Option<f64> {
        let i = self
            .alternatives
            .iter()
            .position(|(l, _)| l.link.loss == alternative)?;
        let (attempts, lost) = self.since[i];
        (attempts > 0).then(|| lost as f64 / attempts as f64)
    }
}

/// Whether each served slot triggered, against the family's per-slot rate;
/// CUSUMs towards more and towards fewer triggers ([`ALTERNATIVES`] each
/// way: `2 × 3` of the [`Budget`]'s `K`).
#[derive(Debug, Clone)]
pub struct TriggerTest {
    more: Vec<(f64, Cusum)>,
    fewer: Vec<(f64, Cusum)>,
    threshold: f64,
}

impl TriggerTest {
    pub fn new(threshold: f64) -> Self {
        let cusums = || {
            ALTERNATIVES
                .iter()
                .map(|&f| (f, Cusum::new()))
                .collect::<Vec<_>>()
        };
        Self {
            more: cusums(),
            fewer: cusums(),
            threshold,
        }
    }

    /// A served slot whose model rate is `rate` (the family's closed form at
    /// the slot's δ) and whether it triggered.
    pub fn observe(&mut self, rate: f64, triggered: bool) -> Option<Alarm> {
        let p = |x: f64| if triggered { x } else { 1.0 - x };
        let threshold = self.threshold;
        let mut alarm = None;
        let mut push = |alt: f64, cusum: &mut Cusum| {
            let s = cusum.push(llr(p(alt), p(rate)));
            if s >= threshold && alarm.is_none() {
                alarm = Some(Alarm {
                    alternative: alt,
                    statistic: s,
                    threshold,
                    since_onset: cusum.since_onset(),
                    observations: cusum.observations(),
                });
            }
        };
        for (f, c) in &mut self.more {
            push(rate + *f * (1.0 - rate), c);
        }
        for (f, c) in &mut self.fewer {
            push(rate * (1.0 - *f), c);
        }
        alarm
    }
}

#[cfg(test)]
mod tests;
