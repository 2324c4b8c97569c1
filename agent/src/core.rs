//! What the agent decides in an episode, as pure functions of its state: no
//! ports, no clock, no waiting. [`crate::runtime`] is the thin iceoryx2
//! adapter around it (publish, wait, take), so every decision here is
//! unit-tested without processes.
//!
//! The step itself is `etp_shared::episode::AgentCore` (the one order of
//! docs/MODEL.md §3, the same code as the in-process simulator, `replay
//! --verify` and the sensor's replica); this core adds the episode around
//! it: the true state and its process noise (`streams::AGENT`), the legs in
//! turn, the check that the sensor's replica triggered on our prior, what a
//! dead link means (prediction only, the episode degraded), the counts the
//! coordinator is told and the outcome.

use crate::AgentError;
use etp_runtime::wire::agent_to_coordinator::Outcome;
use etp_runtime::wire::{OutcomeCode, WireVec};
use etp_shared::episode::{
    self, AgentCore, Begun, CompiledScenario, OpenSlot, Plant, SlotOutcome, belief_digest,
};
use etp_shared::etkf::{Belief, Vector};
use etp_shared::rng::{SimRng, stream_rng, streams};

/// What one slot brought.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlotResult {
    /// The slot closed: `Some(y)` if the sensor transmitted, `None` if silent
    /// (silence from a live sensor is information: implicit update), with
    /// the digest of the prior the sensor's replica triggered on.
    Closed(Option<WireVec>, u64),
    /// The sensor is dead (or, with `--slot-deadline`, late): no information
    /// from silence. A measurement that did arrive before the verdict is
    /// still returned.
    Dead(Option<WireVec>),
}

/// A dead link as the agent saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fault {
    pub sensor: u32,
    /// From the start of the wait on the slot to the verdict.
    pub detect_us: u64,
    pub wait_started_unix_ns: u64,
    pub detected_unix_ns: u64,
}

/// Counts of one leg, as the coordinator is told them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LegCounts {
    pub steps: u32,
    /// Measurements that reached the agent.
    pub received: u32,
    /// A slot of the leg was dead.
    pub degraded: bool,
}

/// A decision point: what the agent publishes as its `waypoint`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecisionPoint<const N: usize> {
    pub leg: u32,
    /// Episode step k reached.
    pub step: u32,
    /// The previous leg's counts (zero at leg 0).
    pub prev: LegCounts,
    /// The posterior here (what the coordinator classifies, and what the
    /// leg's sensor is handed).
    pub belief: Belief<N>,
}

/// A slot to be served: (leg, step k) at `sensor`; hand it back to
/// [`EpisodeCore::close_slot`] with what the sensor did.
#[derive(Debug)]
pub struct SlotRequest<const N: usize> {
    pub leg: u32,
    pub step: u32,
    pub sensor: usize,
    open: OpenSlot<N>,
}

impl<const N: usize> SlotRequest<N> {
    /// The prior of this slot (what the serving sensor's replica triggers on).
    pub fn prior(&self) -> &Belief<N> {
        self.open.prior()
    }
}

/// The episode's end: its outcome message (the header is the adapter's),
/// at (leg, step k).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeEnd {
    pub leg: u32,
    pub step: u32,
    pub outcome: Outcome,
}

/// After [`EpisodeCore::begin_step`].
#[derive(Debug)]
pub enum Step<const N: usize> {
    /// Serve this slot.
    Slot(SlotRequest<N>),
    /// The move collided: the episode is over.
    Ended(EpisodeEnd),
}

/// After [`EpisodeCore::close_slot`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AfterSlot {
    /// The leg goes on: begin the next step.
    Continue,
    /// The leg ended: the next decision point is due.
    LegEnded,
    /// The last leg ended.
    Ended(EpisodeEnd),
}

/// The leg in progress.
#[derive(Debug, Clone, Copy)]
struct OpenLeg<const N: usize> {
    core: AgentCore<N>,
    sensor: usize,
    counts: LegCounts,
}

/// One episode of the agent between messages.
#[derive(Debug)]
pub struct EpisodeCore<const N: usize> {
    episode: u64,
    /// Process noise of the simulated plant.
    rng: SimRng,
    /// The true state (the simulated world the sensors measure).
    x: Vector<N>,
    /// The posterior at the last decision point (or leg end).
    belief: Belief<N>,
    /// Episode step k.
    step: u32,
    /// The next decision point (= the leg to open).
    leg: usize,
    open: Option<OpenLeg<N>>,
    prev: LegCounts,
    totals: Outcome,
}

impl<const N: usize> EpisodeCore<N> {
    /// Episode `episode` of run seed `seed`: x₀ drawn from the agent's stream.
    pub fn start(c: &CompiledScenario<N>, episode: u64, seed: u64) -> Result<Self, AgentError> {
        if c.legs.is_empty() {
            return Err(AgentError::Protocol("scenario without legs".into()));
        }
        let mut rng = stream_rng(seed, streams::AGENT, episode);
        let state = c.initial_state(&mut rng);
        Ok(Self {
            episode,
            rng,
            x: state.x,
            belief: state.belief,
            step: 0,
            leg: 0,
            open: None,
            prev: LegCounts::default(),
            totals: Outcome {
                dead_sensor: u32::MAX,
                ..Outcome::default()
            },
        })
    }

    pub fn episode(&self) -> u64 {
        self.episode
    }

    /// The true state now (what the serving sensor measures).
    pub fn x(&self) -> &Vector<N> {
        &self.x
    }

    /// The decision point due (after [`Self::start`] or a leg's end).
    pub fn decision_point(&self) -> DecisionPoint<N> {
        DecisionPoint {
            leg: self.leg as u32,
            step: self.step,
            prev: self.prev,
            belief: self.belief,
        }
    }

    /// The coordinator opened the due leg at threshold δ = `delta` at
    /// `sensor`, which must be the leg's sensor in the scenario.
    pub fn open_leg(
        &mut self,
        c: &CompiledScenario<N>,
        delta: f64,
        sensor: usize,
    ) -> Result<(), AgentError> {
        let leg = self.leg;
        let serving = c.legs[leg].sensor;
        if sensor != serving {
            return Err(AgentError::Protocol(format!(
                "coordinator opened leg {leg} at sensor {sensor}, the scenario says {serving}"
            )));
        }
        self.open = Some(OpenLeg {
            core: AgentCore::for_delta(c, leg, delta, self.belief, self.step),
            sensor,
            counts: LegCounts::default(),
        });
        Ok(())
    }

    /// The threshold δ of the open leg's next slot (0 in its full-KF
    /// phase): what the serving sensor triggers at.
    pub fn slot_delta(&self) -> Option<f64> {
        self.open.as_ref().map(|l| l.core.threshold().delta)
    }

    fn open_mut(&mut self) -> Result<&mut OpenLeg<N>, AgentError> {
        let leg = self.leg;
        self.open
            .as_mut()
            .ok_or_else(|| AgentError::Protocol(format!("a step of leg {leg}, not opened")))
    }

    /// Begin a step of the open leg: input, the plant's move, collision,
    /// the prior (`AgentCore::begin`).
    pub fn begin_step(&mut self, c: &CompiledScenario<N>) -> Result<Step<N>, AgentError> {
        let Self { x, rng, open, .. } = self;
        let Some(open) = open.as_mut() else {
            return Err(AgentError::Protocol(format!(
                "a step of leg {}, not opened",
                self.leg
            )));
        };
        let begun = open.core.begin(c, &mut Plant { x, rng });
        let (leg, step, sensor) = (open.core.leg() as u32, open.core.step(), open.sensor);
        open.counts.steps += 1;
        self.step = step;
        self.totals.steps += 1;
        Ok(match begun {
            Begun::Slot(open) => Step::Slot(SlotRequest {
                leg,
                step,
                sensor,
                open,
            }),
            Begun::Collided(_obstacle) => {
                self.totals.outcome = OutcomeCode::Collision.code();
                Step::Ended(self.end())
            }
        })
    }

    /// Close the slot of `request` with what came of it (and the dead
    /// link's fault, if this wait found one): the replica's prior digest must
    /// be ours; a dead slot is prediction only and degrades the episode.
    pub fn close_slot(
        &mut self,
        c: &CompiledScenario<N>,
        request: SlotRequest<N>,
        result: SlotResult,
        fault: Option<Fault>,
    ) -> Result<AfterSlot, AgentError> {
        let episode = self.episode;
        if let Some(f) = fault {
            record_fault(&mut self.totals, &f);
        }
        self.totals.slots += 1;
        let SlotRequest {
            step, sensor, open, ..
        } = request;
        let (closed, y) = match result {
            SlotResult::Closed(y, digest) => {
                // The sensor triggered on its replica's prior: it must be
                // ours, bit for bit (docs/MODEL.md §3.2).
                let ours = belief_digest(open.prior());
                if digest != ours {
                    return Err(AgentError::Protocol(format!(
                        "sensor {sensor}'s replica diverged at episode {episode} step {step}: \
                         prior digest {digest:#018x}, the agent's {ours:#018x}"
                    )));
                }
                (true, y)
            }
            SlotResult::Dead(y) => {
                self.totals.degraded = 1;
                self.totals.dead_slots += 1;
                (false, y)
            }
        };
        let leg = self.open_mut()?;
        leg.counts.degraded |= !closed;
        leg.counts.received += u32::from(y.is_some());
        let outcome = match (&y, closed) {
            (Some(y), _) => SlotOutcome::Transmitted(&y[..]),
            (None, true) => SlotOutcome::Silent,
            (None, false) => SlotOutcome::Dead,
        };
        if !leg.core.close(c, open, outcome) {
            return Ok(AfterSlot::Continue);
        }
        let (posterior, counts) = (*leg.core.posterior(), leg.counts);
        self.belief = posterior;
        if self.leg + 1 == c.legs.len() {
            self.totals.outcome = match c.classify_end(&self.x) {
                episode::Outcome::Target => OutcomeCode::Target,
                _ => OutcomeCode::Free,
            }
            .code();
            return Ok(AfterSlot::Ended(self.end()));
        }
        self.totals.received += counts.received;
        self.prev = counts;
        self.open = None;
        self.leg += 1;
        Ok(AfterSlot::LegEnded)
    }

    /// The outcome at the end of the open leg.
    fn end(&mut self) -> EpisodeEnd {
        let last = self
            .open
            .take()
            .map_or_else(LegCounts::default, |l| l.counts);
        let mut o = self.totals;
        o.last_steps = last.steps;
        o.last_received = last.received;
        o.received += last.received;
        EpisodeEnd {
            leg: self.leg as u32,
            step: self.step,
            outcome: o,
        }
    }
}

/// The first dead link of the episode is the one reported.
fn record_fault(o: &mut Outcome, f: &Fault) {
    if o.dead_sensor == u32::MAX {
        o.dead_sensor = f.sensor;
        o.detect_us = f.detect_us;
        o.wait_started_unix_ns = f.wait_started_unix_ns;
        o.detected_unix_ns = f.detected_unix_ns;
    }
}

#[cfg(test)]
mod tests;
