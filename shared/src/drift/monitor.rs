//! The run's monitor: every sensor's tests ([`DeliveryTest`], and
//! [`TriggerTest`] for a family with a model rate) under one false-alarm
//! budget, fed one served slot at a time, raising each (sensor, quantity)
//! flag at most once. The agent runs it on the slots it receives; `replay
//! verify` runs it again on the re-run's slots and must find the same flags;
//! the in-process simulation runs it through [`MonitorObserver`].

use super::{ALTERNATIVES, Budget, DeliveryTest, TriggerTest};
use crate::episode::{EpisodeObserver, StepEvent};
use crate::radio::{Estimator, Transmission};
use crate::scenario::Scenario;
use crate::trigger::TriggerFamily;

/// What a flag says drifted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Quantity {
    /// More attempts lost than the link allows for.
    Loss,
    /// More triggers than the family's rate at the slot's δ.
    MoreTriggers,
    /// Fewer triggers than that rate.
    FewerTriggers,
}

impl Quantity {
    pub const ALL: [Quantity; 3] = [Self::Loss, Self::MoreTriggers, Self::FewerTriggers];

    /// `loss`, `more_triggers`, `fewer_triggers` (report, JSON, recordings).
    pub fn name(self) -> &'static str {
        match self {
            Self::Loss => "loss",
            Self::MoreTriggers => "more_triggers",
            Self::FewerTriggers => "fewer_triggers",
        }
    }

    /// 1, 2, 3 on the wire (0 is no quantity).
    pub fn code(self) -> u32 {
        match self {
            Self::Loss => 1,
            Self::MoreTriggers => 2,
            Self::FewerTriggers => 3,
        }
    }

    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|q| q.code() == code)
    }

    fn index(self) -> usize {
        self.code() as usize - 1
    }
}

/// The monitor's parameters: a false-alarm probability for the whole run and
/// how many episodes the run has (the horizon of each test is at most every
/// step of them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonitorConfig {
    /// α: the probability, under the synthesized channel and trigger, that
    /// any flag of the run is raised.
    pub false_alarm: f64,
    pub episodes: u64,
}

/// One raised flag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Flag {
    pub sensor: usize,
    pub quantity: Quantity,
    pub episode: u64,
    /// Episode step k of the slot that raised it.
    pub step: u32,
    /// The alternative whose CUSUM reached the threshold: a loss per attempt,
    /// or a trigger probability per slot.
    pub alternative: f64,
    pub statistic: f64,
    pub threshold: f64,
    /// Observations from the estimated onset to the flag.
    pub since_onset: u64,
    /// Observations of this test so far.
    pub observations: u64,
    /// For a loss flag: lost / attempts since the estimated onset, the
    /// channel's estimate now.
    pub estimate: Option<f64>,
}

/// One sensor's tests.
#[derive(Debug, Clone)]
struct SensorTests {
    delivery: DeliveryTest,
    /// `None` where the family's closed-form rate is not the slot's law:
    /// a family without a model rate (send-on-delta, variance and periodic
    /// decide otherwise), and a lossy link whose silence the filter does
    /// not model exactly (bursts, or the naive estimator): there the
    /// prior's innovations are wider than the filter says after a lost
    /// packet, so triggers come more often than the formula (measured: a
    /// stochastic trigger on loss 0.3, burst 3, flagged "more triggers" in
    /// 19 of 300 runs at α = 0.1 with no drift).
    triggers: Option<TriggerTest>,
    /// The measurement's dimension m (the family's rate depends on it).
    m: usize,
    raised: [bool; 3],
}

/// Every sensor's tests for one run.
#[derive(Debug, Clone)]
pub struct Monitor {
    sensors: Vec<SensorTests>,
    family: TriggerFamily,
    budget: Budget,
    episode: u64,
}

impl Monitor {
    /// The tests of a run of `config.episodes` episodes of `scenario` (its
    /// radio is the channel the strategy was synthesized for).
    pub fn new(scenario: &Scenario, config: MonitorConfig) -> Self {
        let family = scenario.trigger;
        let radio = &scenario.radio;
        let tests_triggers = |s: usize| {
            let link = radio.link(s);
            family.has_model_rate()
                && (link.is_ideal()
                    || (link.burst.is_none() && radio.estimator == Estimator::Aware))
        };
        let tests: usize = (0..scenario.sensors.len())
            .map(|s| ALTERNATIVES.len() * if tests_triggers(s) { 3 } else { 1 })
            .sum();
        let steps_per_episode =
            scenario.legs.len() as u64 * u64::from(scenario.controller.k_max.max(1));
        let budget = Budget {
            false_alarm: config.false_alarm,
            horizon: config.episodes.max(1).saturating_mul(steps_per_episode),
            tests: tests as u64,
        };
        let h = budget.threshold();
        let sensors = scenario
            .sensors
            .iter()
            .enumerate()
            .map(|(s, sensor)| SensorTests {
                delivery: DeliveryTest::new(radio.link(s), h),
                triggers: tests_triggers(s).then(|| TriggerTest::new(h)),
                m: sensor.dim(),
                raised: [false; 3],
            })
            .collect();
        Self {
            sensors,
            family,
            budget,
            episode: 0,
        }
    }

    /// The budget the threshold comes from (`h = budget.threshold()`).
    pub fn budget(&self) -> Budget {
        self.budget
    }

    /// A new episode (the burst state is drawn afresh).
    pub fn start_episode(&mut self, episode: u64) {
        self.episode = episode;
        for s in &mut self.sensors {
            s.delivery.start_episode();
        }
    }

    /// One served slot of `sensor` at episode step `step`, threshold δ =
    /// `delta` (the slot's own: 0 in a leg's full-KF phase), with what its
    /// radio did; the flags it raises (at most one per quantity per run).
    /// A sensor the scenario does not have is ignored.
    pub fn observe(&mut self, sensor: usize, step: u32, delta: f64, t: Transmission) -> Vec<Flag> {
        let episode = self.episode;
        let family = self.family;
        let Some(s) = self.sensors.get_mut(sensor) else {
            return Vec::new();
        };
        let mut flags = Vec::new();
        let mut raise = |s: &mut SensorTests, quantity: Quantity, a: super::Alarm, estimate| {
            if !std::mem::replace(&mut s.raised[quantity.index()], true) {
                flags.push(Flag {
                    sensor,
                    quantity,
                    episode,
                    step,
                    alternative: a.alternative,
                    statistic: a.statistic,
                    threshold: a.threshold,
                    since_onset: a.since_onset,
                    observations: a.observations,
                    estimate,
                });
            }
        };
        if let (Some(tests), Some(rate)) = (s.triggers.as_mut(), family.expected_rate(delta, s.m))
            && let Some(a) = tests.observe(rate, t.attempts > 0)
        {
            let q = if a.alternative > rate {
                Quantity::MoreTriggers
            } else {
                Quantity::FewerTriggers
            };
            raise(s, q, a, None);
        }
        if t.attempts > 0
            && let Some(a) = s.delivery.observe(u64::from(step), t)
        {
            let estimate = s.delivery.loss_since_onset(a.alternative);
            raise(s, Quantity::Loss, a, estimate);
        }
        flags
    }
}

/// The monitor fed by the in-process simulation's steps (the same slots the
/// agent would receive): the flags of every episode, in order.
#[derive(Debug)]
pub struct MonitorObserver<'a> {
    pub monitor: Monitor,
    pub flags: Vec<Flag>,
    /// Sensor of each leg.
    legs: &'a [crate::scenario::Leg],
    /// Episode step k of the next step.
    step: u32,
}

impl<'a> MonitorObserver<'a> {
    pub fn new(scenario: &'a Scenario, config: MonitorConfig) -> Self {
        Self {
            monitor: Monitor::new(scenario, config),
            flags: Vec::new(),
            legs: &scenario.legs,
            step: 0,
        }
    }

    /// Call before each episode.
    pub fn start_episode(&mut self, episode: u64) {
        self.monitor.start_episode(episode);
        self.step = 0;
    }
}

impl<const N: usize> EpisodeObserver<N> for MonitorObserver<'_> {
    fn on_step(&mut self, e: &StepEvent<'_, N>) {
        // Steps are counted from 1, as the agent's episode step k.
        self.step += 1;
        if e.collided {
            return;
        }
        let Some(leg) = self.legs.get(e.leg) else {
            return;
        };
        let t = Transmission {
            attempts: e.attempts,
            delivered: e.delivered,
        };
        let flags = self.monitor.observe(leg.sensor, self.step, e.delta, t);
        self.flags.extend(flags);
    }
}
